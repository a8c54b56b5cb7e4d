"""hlaid: digital clones of buildings from earthquake records.

Pipeline: measurement -> :func:`hla` (hysteresis loop analysis) -> :func:`identify`
(degrading Bouc-Wen clone: regressions + RBF kernel SVMs) -> :func:`replay` / :func:`simulate`
-> :func:`ida` (incremental dynamic analysis, collapse fragility). See README.md.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("hlaid")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+unknown"

from .clone import Clone, load_clone
from .errors import ConfigError, InputError, NotIdentifiableError
from .hla import HLAConfig, HLAResult, hla
from .ida import IDAConfig, IDAResult, ida
from .identify import (BaseIdentifier, GradientIdentifier, HLASVMIdentifier, IdentificationResult, IdentifyConfig,
                       NotFittedError, UKFIdentifier, identify, refine_replay)
from .io import read
from .measurement import Measurement, Truth
from .model import BoucWenBuilding, Building, BuildingTensors, Damping
from .motions import GroundMotion, builtin_records
from .runner import RunConfig, run_pipeline
from .simulate import SimulationResult, replay, simulate
from .svm import KernelSVC
from .synthetic import simulate_measurement

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
