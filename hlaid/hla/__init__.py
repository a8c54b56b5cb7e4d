"""Hysteresis loop analysis (HLA): story force-drift loops, half cycles, k0, ke(t), k(t)."""

from .analysis import floor_motion, run_hla
from .config import ForceConfig, HalfCycleConfig, HLAConfig, PreprocessConfig, StiffnessConfig
from .result import HalfCycleTable, HLAResult, StoryHLA

__all__ = ["run_hla", "floor_motion", "HLAConfig", "PreprocessConfig", "ForceConfig", "HalfCycleConfig",
           "StiffnessConfig", "HLAResult", "StoryHLA", "HalfCycleTable"]
