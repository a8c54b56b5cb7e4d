"""Hysteresis loop analysis (HLA): story force-drift loops, half cycles, k0, ke(t), k(t).

Names are imported on first use: :mod:`hlaid.hla.config` (the schema) loads without scipy or torch.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .analysis import floor_motion
    from .auto import Choice, resolve_hla, run_hla
    from .config import ForceConfig, HalfCycleConfig, HLAConfig, PreprocessConfig, StiffnessConfig
    from .result import HalfCycleTable, HLAResult, StoryHLA

__all__ = ["run_hla", "resolve_hla", "Choice", "floor_motion", "HLAConfig", "PreprocessConfig", "ForceConfig",
           "HalfCycleConfig", "StiffnessConfig", "HLAResult", "StoryHLA", "HalfCycleTable"]

__getattr__, __dir__ = lazy_exports(__name__, {
    **dict.fromkeys(("floor_motion",), ".analysis"),
    **dict.fromkeys(("run_hla", "resolve_hla", "Choice"), ".auto"),
    **dict.fromkeys(("HLAConfig", "PreprocessConfig", "ForceConfig", "HalfCycleConfig", "StiffnessConfig"), ".config"),
    **dict.fromkeys(("HLAResult", "StoryHLA", "HalfCycleTable"), ".result")})
