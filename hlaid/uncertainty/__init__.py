"""Identification uncertainty of a clone and collapse fragility with epistemic uncertainty.

``clone.uncertainty`` (set by :func:`hlaid.identify_clone`) is a Gaussian over the refined parameters
in log space, from the Gauss-Newton (Laplace) covariance of the replay refinement with a
sandwich (HAC) correction for the correlated residuals (:mod:`.laplace`).
:func:`clone_ensemble` draws buildings from it; :func:`assess` runs IDA over such an ensemble
and returns the fragility band, the probabilities at the building's own record intensity and a
re-occupancy indicator. Method and measured coverage: ``docs/uncertainty.md``.
"""

from ..model.uncertainty import ParameterUncertainty
from .assess import AssessConfig, Assessment, ReoccupancyThresholds, assess
from .coverage import calibration_factor, coverage, zscores
from .ensemble import clone_ensemble
from .laplace import covariance, from_refinement, uncertainty_of_refinement

__all__ = ["AssessConfig", "Assessment", "ParameterUncertainty", "ReoccupancyThresholds", "assess",
           "calibration_factor", "clone_ensemble", "coverage", "covariance", "from_refinement",
           "uncertainty_of_refinement", "zscores"]
