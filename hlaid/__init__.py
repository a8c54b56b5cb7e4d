"""hlaid: digital clones of buildings from earthquake records.

Pipeline: measurement -> :func:`hla` (hysteresis loop analysis) -> :func:`identify`
(degrading Bouc-Wen clone: regressions + RBF kernel SVMs) -> :func:`replay` / :func:`simulate`
-> :func:`ida` (incremental dynamic analysis, collapse fragility). See README.md.

The names below are imported on first use (PEP 562), so ``import hlaid`` and the command line's
``--help`` do not load torch, numba, scipy or matplotlib.
"""

from __future__ import annotations

import importlib
import sys
import types
from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING, Any

try:
    __version__ = version("hlaid")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+unknown"

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from .clone import Clone, load_clone
    from .errors import ConfigError, InputError, NotIdentifiableError
    from .hla import HLAConfig, HLAResult, hla
    from .ida import IDAConfig, IDAResult, ida
    from .identify import (
        BaseIdentifier,
        GradientIdentifier,
        HLASVMIdentifier,
        IdentificationResult,
        IdentifyConfig,
        NotFittedError,
        UKFIdentifier,
        identify,
        refine_replay,
    )
    from .io import read
    from .measurement import Measurement, Truth
    from .model import BoucWenBuilding, Building, BuildingTensors, Damping
    from .motions import GroundMotion, builtin_records
    from .runner import RunConfig, run_pipeline
    from .simulate import SimulationResult, replay, simulate  # type: ignore[no-redef]  # replay: also a submodule
    from .svm import KernelSVC
    from .synthetic import simulate_measurement

_LAZY = {
    ".clone": ("Clone", "load_clone"),
    ".errors": ("ConfigError", "InputError", "NotIdentifiableError"),
    ".hla": ("HLAConfig", "HLAResult", "hla"),
    ".ida": ("IDAConfig", "IDAResult", "ida"),
    ".identify": ("BaseIdentifier", "GradientIdentifier", "HLASVMIdentifier", "IdentificationResult",
                  "IdentifyConfig", "NotFittedError", "UKFIdentifier", "identify", "refine_replay"),
    ".io": ("read",),
    ".measurement": ("Measurement", "Truth"),
    ".model": ("BoucWenBuilding", "Building", "BuildingTensors", "Damping"),
    ".motions": ("GroundMotion", "builtin_records"),
    ".runner": ("RunConfig", "run_pipeline"),
    ".simulate": ("SimulationResult", "replay", "simulate"),
    ".svm": ("KernelSVC",),
    ".synthetic": ("simulate_measurement",),
}
_WHERE = {name: module for module, names in _LAZY.items() for name in names}
"""Public name -> the module that defines it."""

__all__ = [
    "__version__",
    # model and simulation
    "Building", "Damping", "BoucWenBuilding", "BuildingTensors", "simulate", "replay", "SimulationResult",
    # data
    "read", "GroundMotion", "builtin_records", "Measurement", "Truth",
    "simulate_measurement",
    # analysis and identification
    "hla", "HLAConfig", "HLAResult", "identify", "IdentifyConfig", "IdentificationResult", "refine_replay",
    "BaseIdentifier", "HLASVMIdentifier", "GradientIdentifier", "UKFIdentifier", "NotFittedError", "KernelSVC",
    "Clone", "load_clone",
    # risk
    "ida", "IDAConfig", "IDAResult",
    # pipeline and errors
    "run_pipeline", "RunConfig", "InputError", "ConfigError", "NotIdentifiableError",
]


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


class _Package(types.ModuleType):
    """``hlaid.hla``, ``hlaid.identify``, ``hlaid.ida`` and ``hlaid.simulate`` are the functions,
    as with eager imports: importing the subpackage of the same name does not replace them."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _WHERE and isinstance(value, types.ModuleType) and value.__name__ == f"{__name__}.{name}":
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
