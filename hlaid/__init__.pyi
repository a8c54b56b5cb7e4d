# What type checkers and IDEs see of ``hlaid`` (at run time the names load lazily, hlaid/__init__.py).
# The same names as ``_LAZY`` there (tests/test_cli_startup.py checks it).
from typing import Any

from ._progress import verbose as verbose
from .clone import Clone as Clone
from .clone import load_clone as load_clone
from .errors import ConfigError as ConfigError
from .errors import InputError as InputError
from .errors import NotIdentifiableError as NotIdentifiableError
from .estimators import BaseIdentifier as BaseIdentifier
from .estimators import HLASVMIdentifier as HLASVMIdentifier
from .estimators import NotFittedError as NotFittedError
from .events import Prediction as Prediction
from .events import identify_clone as identify_clone
from .events import predict_event as predict_event
from .events import update_clone as update_clone
from .hla import HLAConfig as HLAConfig
from .hla import HLAResult as HLAResult
from .hla import run_hla as run_hla
from .ida import IDAConfig as IDAConfig
from .ida import IDAResult as IDAResult
from .ida import run_ida as run_ida
from .identify import IdentificationResult as IdentificationResult
from .identify import IdentifyConfig as IdentifyConfig
from .identify import refine_replay as refine_replay
from .io import read as read
from .measurement import Measurement as Measurement
from .measurement import Truth as Truth
from .model import BoucWenBuilding as BoucWenBuilding
from .model import Building as Building
from .model import BuildingTensors as BuildingTensors
from .model import Damping as Damping
from .model.state import BuildingState as BuildingState
from .motions import GroundMotion as GroundMotion
from .motions import builtin_records as builtin_records
from .run import RunConfig as RunConfig
from .run import run_pipeline as run_pipeline
from .simulate import SimulationResult as SimulationResult
from .simulate import replay as replay
from .simulate import simulate_response as simulate_response
from .svm import KernelSVC as KernelSVC
from .synthetic import simulate_events as simulate_events
from .synthetic import simulate_measurement as simulate_measurement

__version__: str
__all__: list[str]
_LAZY: dict[str, tuple[str, ...]]

def __getattr__(name: str) -> Any: ...
def __dir__() -> list[str]: ...
