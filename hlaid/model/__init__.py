"""The degrading Bouc-Wen shear building: parameters and the torch module."""

from . import _equations as equations
from . import _structure as structure
from ._structure import DAMPING_KINDS
from .building import BoucWenBuilding
from .collapse import COLLAPSE_MODELS, CollapseModel, get_collapse_model
from .params import STORY_FIELDS, Building, BuildingTensors, Damping

__all__ = ["Building", "BuildingTensors", "Damping", "BoucWenBuilding", "STORY_FIELDS", "DAMPING_KINDS",
           "equations", "structure", "CollapseModel", "COLLAPSE_MODELS", "get_collapse_model"]
