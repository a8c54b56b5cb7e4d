"""Identification of a degrading Bouc-Wen clone from a measurement.

The paper's method (:func:`identify_clone`: HLA, regressions, RBF SVMs coarse to fine, then a
refinement against the measured accelerations named in :data:`REFINERS`) and two baselines,
all behind one scikit-learn estimator interface and named in :data:`IDENTIFIERS`
(:func:`get_identifier`). The stages themselves are in :mod:`hlaid.identify.stages`,
:mod:`hlaid.identify.passes` and :mod:`hlaid.identify.refiners`; studies that compare the
identifiers live in :mod:`hlaid.studies`.
"""

from .config import BinsConfig, IdentifyConfig, OuterConfig, RefineConfig, SVMConfig, TrainingConfig
from .estimators import BaseIdentifier, HLASVMIdentifier, NotFittedError
from .gradient import GradientIdentifier
from .pipeline import IdentificationResult, identify_clone
from .refine import RefineResult, refine_replay
from .refiners import REFINERS
from .registry import IDENTIFIERS, get_identifier
from .ukf import UKFIdentifier

__all__ = ["identify_clone", "IdentificationResult", "IdentifyConfig", "BinsConfig", "TrainingConfig", "SVMConfig",
           "OuterConfig", "RefineConfig", "REFINERS", "refine_replay", "RefineResult", "IDENTIFIERS",
           "get_identifier", "BaseIdentifier", "HLASVMIdentifier", "GradientIdentifier", "UKFIdentifier",
           "NotFittedError"]
