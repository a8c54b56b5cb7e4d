"""Parametric bootstrap of an identification: the spread of re-identified parameters, the
check of a clone's Laplace uncertainty (``scripts/study_uncertainty.py``)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import _progress
from ..events.identify import identify_clone
from ..identify import IdentifyConfig
from ..identify.auto import resolve_like
from ..identify.stages import estimate_noise_rms
from ..synthetic import simulate_measurement
from ..uncertainty.ensemble import check_ensemble_size, check_uncertain_clone


@dataclass(frozen=True)
class BootstrapResult:
    """Parametric bootstrap of an identification.

    Attributes
    ----------
    names : (P,) the clone's uncertain parameters (``"k0[1]"`` ...)
    values : (n_ok, P) the re-identified values of those parameters
    noise_rms : noise fraction used for re-noising
    failed : replicates whose identification failed
    """

    names: tuple
    values: np.ndarray
    noise_rms: float
    failed: int


def parametric_bootstrap(clone, measurement, n: int, *, config=None, cache_dir=None, seed: int = 0,
                         noise_rms: float | None = None) -> BootstrapResult:
    """Re-identify ``n`` simulated measurements of ``clone`` under ``measurement``'s ground motion.

    Each replicate simulates the clone's building on the measured ground acceleration, adds
    white noise of ``noise_rms`` x channel RMS to every channel (default: the noise level
    identification used, ``clone.provenance["noise_rms_used"]``, else estimated from the
    measurement's spectral floor) and identifies it again. The spread of the re-identified
    parameters checks the Laplace covariance. Costs ``n`` identifications.
    """
    check_uncertain_clone(clone)
    n = check_ensemble_size(n)
    cfg = resolve_like(clone.provenance, measurement, config or IdentifyConfig()).config  # the clone's choices
    if noise_rms is None:
        noise_rms = clone.provenance.get("noise_rms_used") or estimate_noise_rms(measurement)
    gm = measurement.ground_motion(name="measured")
    b = clone.building
    if measurement.height is not None and b.height is None:
        b = b.replace(height=measurement.height)
    u = clone.uncertainty
    rows, failed = [], 0
    for j in _progress.progress(range(n), desc="bootstrap"):
        m = simulate_measurement(b, gm, rate_hz=None, noise_rms=float(noise_rms), seed=int(seed) * 100_003 + j)
        m = dataclasses.replace(m, mass=np.asarray(measurement.mass) if measurement.mass is not None else m.mass)
        try:
            res = identify_clone(m, cfg, cache_dir=cache_dir)
        except ValueError:
            failed += 1
            continue
        rb = res.clone.building
        rows.append([getattr(rb, k)[i] if k != "damping" else rb.damping.ratio for k, i in u.slots])
    return BootstrapResult(names=tuple(u.names), values=np.array(rows).reshape(-1, len(u.slots)),
                           noise_rms=float(noise_rms), failed=failed)
