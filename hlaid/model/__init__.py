"""The degrading Bouc-Wen shear building: parameters and the torch module.

The names below are imported on first use (PEP 562): :mod:`hlaid.model.schema` and
:mod:`hlaid.model.params` (what a building may be, and the building itself) load without torch,
so configs and clone files are checked before torch is imported.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from . import _equations as equations
    from . import _structure as structure
    from ._structure import DAMPING_KINDS
    from .building import BoucWenBuilding
    from .collapse import COLLAPSE_MODELS, CollapseModel, get_collapse_model
    from .params import STORY_FIELDS, Building, BuildingTensors, Damping

__getattr__, __dir__ = lazy_exports(__name__, {
    "equations": "._equations:module", "structure": "._structure:module", "DAMPING_KINDS": "._structure",
    "BoucWenBuilding": ".building", "COLLAPSE_MODELS": ".collapse", "CollapseModel": ".collapse",
    "get_collapse_model": ".collapse", "STORY_FIELDS": ".params", "Building": ".params", "BuildingTensors": ".params",
    "Damping": ".schema"})

__all__ = ["Building", "BuildingTensors", "Damping", "BoucWenBuilding", "STORY_FIELDS", "DAMPING_KINDS",
           "equations", "structure", "CollapseModel", "COLLAPSE_MODELS", "get_collapse_model"]
