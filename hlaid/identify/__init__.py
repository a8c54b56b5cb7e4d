"""Identification of a degrading Bouc-Wen clone from a measurement.

The paper's method (:func:`identify`: HLA, regressions, RBF SVMs, replay refinement) and two
baselines, all behind one scikit-learn estimator interface and named in :data:`IDENTIFIERS`
(:func:`get_identifier`). Studies that compare them live in :mod:`hlaid.studies`.
"""

from .config import BinsConfig, IdentifyConfig, OuterConfig, RefineConfig, SVMConfig, TrainingConfig
from .drift import reconstruct_drift
from .estimators import BaseIdentifier, HLASVMIdentifier, NotFittedError
from .gradient import GradientIdentifier
from .loopfit import LoopFit, fit_story_loop
from .pathtrain import StoryPath, path_training_set, segment_operator, story_features
from .pipeline import IdentificationResult, estimate_noise_rms, identify_clone
from .refine import RefineResult, refine_replay
from .registry import IDENTIFIERS, get_identifier
from .regression import RegressionFit, fit_delta_eta, fit_yield_displacement
from .replaycheck import ReplayCheck, replay_check
from .ukf import UKFIdentifier

__all__ = ["reconstruct_drift", "fit_story_loop", "LoopFit", "StoryPath", "path_training_set", "segment_operator",
           "story_features", "BaseIdentifier", "HLASVMIdentifier", "GradientIdentifier", "UKFIdentifier",
           "NotFittedError", "identify_clone", "IdentificationResult", "IdentifyConfig", "BinsConfig", "TrainingConfig",
           "SVMConfig",
           "OuterConfig", "RefineConfig", "refine_replay", "RefineResult", "fit_delta_eta", "fit_yield_displacement",
           "RegressionFit", "replay_check", "ReplayCheck", "estimate_noise_rms", "IDENTIFIERS", "get_identifier"]
