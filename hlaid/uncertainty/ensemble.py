"""Ensembles of buildings from a clone's uncertainty, and the parametric bootstrap that checks it."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import _progress
from ..errors import InputError
from ..model import Building
from .config import MAX_ENSEMBLE


def _check_clone(clone) -> None:
    from ..clone import Clone

    if not isinstance(clone, Clone):
        raise InputError(f"expected an hlaid Clone (hlaid.load_clone(path)), got {type(clone).__name__}")
    if clone.uncertainty is None:
        raise InputError("this clone has no uncertainty (a version 1 file, or identified without the replay "
                         "refinement): identify it again with refine.method 'replay' to get one")


def _check_n(n, what: str = "n") -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_ENSEMBLE:
        raise InputError(f"{what} = {n!r}; expected a whole number of ensemble members in 1..{MAX_ENSEMBLE}")
    return int(n)


def clone_ensemble(clone, n: int, *, seed: int = 0) -> list[Building]:
    """``n`` buildings drawn from ``clone.uncertainty`` (reproducible for a given ``seed``).

    Each member is the clone's building with its uncertain parameters replaced by one draw of
    the Gaussian in log-parameter space (clipped to the parameters' bounds); parameters
    without uncertainty keep their identified value. Members are named ``<name>#<j>``.

    Raises
    ------
    InputError : a clone without uncertainty, or ``n`` outside 1..100000
    """
    _check_clone(clone)
    n = _check_n(n)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed = {seed!r}; expected a whole number >= 0")
    u = clone.uncertainty
    X = u.sample(n, np.random.default_rng(int(seed)))
    b = clone.building
    base = b.name or "clone"
    return [u.apply(b, x).replace(name=f"{base}#{j}") for j, x in enumerate(X)]


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
    from ..identify import IdentifyConfig, identify
    from ..identify.pipeline import estimate_noise_rms
    from ..motions import GroundMotion
    from ..synthetic import simulate_measurement

    _check_clone(clone)
    n = _check_n(n)
    cfg = config or IdentifyConfig()
    if noise_rms is None:
        noise_rms = clone.provenance.get("noise_rms_used") or estimate_noise_rms(measurement)
    gm = GroundMotion(dt=measurement.dt, acc=np.asarray(measurement.ground_acc), name="measured")
    b = clone.building
    if measurement.height is not None and b.height is None:
        b = b.replace(height=measurement.height)
    u = clone.uncertainty
    rows, failed = [], 0
    for j in _progress.progress(range(n), desc="bootstrap"):
        m = simulate_measurement(b, gm, rate_hz=None, noise_rms=float(noise_rms), seed=int(seed) * 100_003 + j)
        m = dataclasses.replace(m, mass=np.asarray(measurement.mass) if measurement.mass is not None else m.mass)
        try:
            res = identify(m, cfg, cache_dir=cache_dir)
        except ValueError:
            failed += 1
            continue
        rb = res.clone.building
        rows.append([getattr(rb, k)[i] if k != "damping" else rb.damping.ratio for k, i in u.slots])
    return BootstrapResult(names=tuple(u.names), values=np.array(rows).reshape(-1, len(u.slots)),
                           noise_rms=float(noise_rms), failed=failed)
