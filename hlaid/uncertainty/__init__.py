"""Identification uncertainty of a clone: its posterior, ensembles drawn from it, their calibration.

``clone.uncertainty`` (set by :func:`hlaid.identify_clone`) is a Gaussian over the refined parameters
in transformed space, from the Gauss-Newton (Laplace) covariance of the replay refinement with a
sandwich (HAC) correction for the correlated residuals (:mod:`.laplace`) or the joint fit's
posterior. :func:`clone_ensemble` draws buildings from it (:func:`hlaid.ida.assess` runs an IDA
of such an ensemble); :mod:`.calibration` scores intervals against known truths. Method and
measured coverage: ``docs/uncertainty.md``. Names are imported on first use:
:mod:`hlaid.uncertainty.config` (the ``assess:`` schema) loads without torch.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from ..model.uncertainty import ParameterUncertainty
    from .calibration import calibration_factor, coverage, zscores
    from .config import AssessConfig
    from .ensemble import clone_ensemble
    from .laplace import covariance, from_refinement, uncertainty_of_refinement

__all__ = ["AssessConfig", "ParameterUncertainty", "calibration_factor", "clone_ensemble", "coverage", "covariance",
           "from_refinement",
           "uncertainty_of_refinement", "zscores"]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in {
    "..model.uncertainty": ("ParameterUncertainty",),
    ".config": ("AssessConfig",),
    ".calibration": ("calibration_factor", "coverage", "zscores"),
    ".ensemble": ("clone_ensemble",),
    ".laplace": ("covariance", "from_refinement", "uncertainty_of_refinement"),
}.items() for name in names})
