"""The paper's method: a degrading Bouc-Wen clone from one record.

HLA, the regressions of delta_eta and dy, RBF SVMs on half-cycle features coarse to fine with an
outer loop (:mod:`.stages`, :mod:`.passes`), then a refinement against the measured accelerations
named in :data:`REFINERS` (:mod:`.refiners`): :func:`identify_event` on one analysed record.
:func:`hlaid.identify_clone` is the entry point (one record or a building's records in time
order, :mod:`hlaid.events`); other identifiers for comparison are in :mod:`hlaid.baselines`.
Names are imported on first use: :mod:`hlaid.identify.config` (the schema) loads without torch,
numba or scipy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .config import BinsConfig, IdentifyConfig, OuterConfig, RefineConfig, SVMConfig, TrainingConfig
    from .pipeline import identify_event, open_cache
    from .refine import RefineResult, refine_replay
    from .refiners import REFINERS
    from .result import IdentificationResult

_WHERE = {
    ".config": ("BinsConfig", "IdentifyConfig", "OuterConfig", "RefineConfig", "SVMConfig", "TrainingConfig"),
    ".pipeline": ("identify_event", "open_cache"),
    ".refine": ("RefineResult", "refine_replay"),
    ".refiners": ("REFINERS",),
    ".result": ("IdentificationResult",),
}

__all__ = ["BinsConfig", "IdentifyConfig", "OuterConfig", "RefineConfig", "SVMConfig", "TrainingConfig",
           "identify_event", "open_cache", "RefineResult", "refine_replay", "REFINERS", "IdentificationResult"]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
