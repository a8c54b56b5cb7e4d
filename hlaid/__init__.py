"""hlaid: digital clones of buildings from earthquake records.

Pipeline: measurement -> :func:`run_hla` (hysteresis loop analysis) -> :func:`identify_clone`
(degrading Bouc-Wen clone: regressions + RBF kernel SVMs) -> :func:`replay` /
:func:`simulate_response` -> :func:`run_ida` (incremental dynamic analysis, collapse fragility).
See README.md.

The subpackages (``hlaid.hla``, ``hlaid.identify``, ``hlaid.simulate``, ``hlaid.ida``, ...) are
modules; the functions users call have names of their own. The names below are imported on
first use (PEP 562), so ``import hlaid`` and the command line's ``--help`` do not load torch,
numba, scipy or matplotlib. :data:`_LAZY` is the one list of the public API: ``__all__`` is
made from it, and a test checks that the type stub ``__init__.pyi`` declares the same names.
"""

from __future__ import annotations

import importlib
from typing import Any

from ._jitcache import configure as _configure_kernel_cache
from ._version import __version__

_configure_kernel_cache()  # before numba is imported: a writable cache for the kernels, or none

_LAZY: dict[str, tuple[str, ...]] = {
    # model and simulation
    ".model": ("Building", "Damping", "BoucWenBuilding", "BuildingTensors"),
    ".simulate": ("simulate_response", "replay", "SimulationResult"),
    # data
    ".io": ("read",),
    ".motions": ("GroundMotion", "builtin_records"),
    ".measurement": ("Measurement", "Truth"),
    ".synthetic": ("simulate_measurement", "simulate_events"),
    # analysis and identification
    ".hla": ("run_hla", "HLAConfig", "HLAResult"),
    ".identify": ("IdentifyConfig", "IdentificationResult", "refine_replay"),
    ".estimators": ("BaseIdentifier", "HLASVMIdentifier", "NotFittedError"),
    ".svm": ("KernelSVC",),
    ".clone": ("Clone", "load_clone"),
    # a building's events
    ".events": ("identify_clone", "update_clone", "predict_event", "Prediction"),
    ".model.state": ("BuildingState",),
    # risk
    ".ida": ("run_ida", "IDAConfig", "IDAResult"),
    # pipeline and errors
    ".run": ("run_pipeline", "RunConfig"),
    ".errors": ("InputError", "ConfigError", "NotIdentifiableError"),
    # messages: progress on stderr from Python
    "._progress": ("verbose",),
}
"""The public API: module (relative to hlaid) -> the names it gives ``hlaid``."""

_WHERE = {name: module for module, names in _LAZY.items() for name in names}
"""Public name -> the module that defines it."""

__all__ = ["__version__", *_WHERE]


def __getattr__(name: str) -> Any:
    """Import a public name on first use and keep it in the module's namespace."""
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'hlaid' has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
