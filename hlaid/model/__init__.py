"""The degrading Bouc-Wen shear building: parameters and the torch module."""

from . import _equations as equations
from ._structure import DAMPING_KINDS
from .building import BoucWenBuilding
from .params import STORY_FIELDS, Building, BuildingTensors, Damping

__all__ = ["Building", "BuildingTensors", "Damping", "BoucWenBuilding", "STORY_FIELDS", "DAMPING_KINDS",
           "equations"]
