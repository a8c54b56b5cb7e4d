"""Identification of a degrading Bouc-Wen clone from a measurement.

The paper's method (:func:`identify_clone`: HLA, regressions, RBF SVMs coarse to fine, then a
refinement against the measured accelerations named in :data:`REFINERS`) and two baselines,
all behind one scikit-learn estimator interface and named in :data:`IDENTIFIERS`
(:func:`get_identifier`). The stages themselves are in :mod:`hlaid.identify.stages`,
:mod:`hlaid.identify.passes` and :mod:`hlaid.identify.refiners`; studies that compare the
identifiers live in :mod:`hlaid.studies`. Names are imported on first use:
:mod:`hlaid.identify.config` (the schema) loads without torch, numba or scipy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .config import BinsConfig, IdentifyConfig, OuterConfig, RefineConfig, SVMConfig, TrainingConfig
    from .estimators import BaseIdentifier, HLASVMIdentifier, NotFittedError
    from .gradient import GradientIdentifier
    from .pipeline import IdentificationResult, identify_clone
    from .refine import RefineResult, refine_replay
    from .refiners import REFINERS
    from .registry import IDENTIFIERS, get_identifier
    from .ukf import UKFIdentifier
    from .update import update_clone

_WHERE = {
    ".config": ("BinsConfig", "IdentifyConfig", "OuterConfig", "RefineConfig", "SVMConfig", "TrainingConfig"),
    ".estimators": ("BaseIdentifier", "HLASVMIdentifier", "NotFittedError"),
    ".gradient": ("GradientIdentifier",),
    ".pipeline": ("IdentificationResult", "identify_clone"),
    ".refine": ("RefineResult", "refine_replay"),
    ".refiners": ("REFINERS",),
    ".registry": ("IDENTIFIERS", "get_identifier"),
    ".ukf": ("UKFIdentifier",),
    ".update": ("update_clone",),
}

__all__ = ["identify_clone", "IdentificationResult", "IdentifyConfig", "BinsConfig", "TrainingConfig", "SVMConfig",
           "OuterConfig", "RefineConfig", "REFINERS", "refine_replay", "RefineResult", "IDENTIFIERS",
           "get_identifier", "BaseIdentifier", "HLASVMIdentifier", "GradientIdentifier", "UKFIdentifier",
           "NotFittedError", "update_clone"]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
