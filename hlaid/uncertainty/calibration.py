"""Coverage of uncertainty intervals against known truths (simulated cases).

The z-score of a parameter is ``(theta_hat - theta_true) / std`` in the uncertainty's own
transformed space (log for positive parameters), so the central ``level`` interval holds the
truth exactly when ``|z| <= Phi^-1((1 + level) / 2)``.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from ..errors import InputError
from ..model.uncertainty import ParameterUncertainty


def zscores(uncertainty: ParameterUncertainty, true_values) -> np.ndarray:
    """(P,) standardised errors of the slots against ``true_values`` ``(P,)`` (parameter units)."""
    t = np.asarray(true_values, dtype=float).reshape(-1)
    if t.shape != uncertainty.centre.shape:
        raise InputError(f"true_values: {t.size} values for {uncertainty.centre.size} uncertain parameters")
    log = np.array([k == "log" for k in uncertainty.transform])
    if np.any(log & ~(t > 0)):
        raise InputError("true_values: a log-transformed parameter's true value must be > 0")
    theta = np.where(log, np.log(np.where(log, t, 1.0)), t)
    return (uncertainty.centre - theta) / np.maximum(uncertainty.std, 1e-300)


def coverage(z, level: float = 0.9, scale: float = 1.0) -> float:
    """Fraction of z-scores inside the central ``level`` interval widened by ``scale``."""
    z = np.asarray(z, dtype=float).reshape(-1)
    if z.size == 0:
        raise InputError("coverage of no intervals")
    if not 0 < level < 1:
        raise InputError(f"level = {level!r}; expected a probability in (0, 1)")
    return float(np.mean(np.abs(z) <= scale * norm.ppf(0.5 + 0.5 * level)))


def calibration_factor(z, level: float = 0.9) -> float:
    """The factor on the standard deviations that makes ``level`` intervals hold exactly that
    fraction of the (calibration) z-scores: their ``level`` quantile of ``|z|`` over the nominal one."""
    z = np.abs(np.asarray(z, dtype=float).reshape(-1))
    if z.size == 0:
        raise InputError("calibration of no intervals")
    return float(np.quantile(z, level) / norm.ppf(0.5 + 0.5 * level))
