"""Gauss-Newton (Laplace) covariance of the replay refinement at its solution.

The refinement (:func:`hlaid.identify.refine_replay`) minimises ``0.5 |r(x)|^2`` with ``r`` the
normalised floor-acceleration residuals, ``(n_time, n_floors)`` flattened time-major. Near
the solution ``r(theta) ~ r0 + J (theta - theta0)``, so the estimate moves with the noise
``e`` as ``d theta = -(J^T J)^-1 J^T e``. Three estimates of its covariance:

``naive``
    ``s^2 (J^T J)^-1`` with ``s^2 = |r|^2 / (n - P)``: right only for white, independent
    residuals. The refinement's residuals are band-passed (0.1-20 Hz of a 100 Hz Nyquist)
    and contain the structure's response to the ground sensor's noise: strongly correlated
    in time, so this is too narrow.
``neff``
    the naive one scaled by ``n / n_eff``, ``n_eff`` the effective number of independent
    samples from the residuals' integrated autocorrelation time (per floor, Parzen-windowed).
``sandwich`` (default)
    ``A^-1 B A^-1`` with ``A = J^T J`` and ``B = J^T Sigma J``, ``Sigma`` the residuals'
    covariance taken as stationary per floor with the Parzen-windowed sample autocovariance
    (Newey-West / HAC estimator): the right answer for coloured noise of any spectrum,
    evaluated with FFTs.

Parameters are transformed first (log of positive values, see :mod:`hlaid.model.uncertainty`):
``J_theta = J_x * dx/dtheta``.

The sandwich alone holds about two thirds of the true values in its nominal 90 % intervals on
simulated random buildings (bias the linearisation cannot see: the ground sensor's noise enters
as an input error, and stories that did not yield keep borrowed parameters). Identified clones
therefore carry it widened by factors fitted on that study (:data:`CALIBRATION`,
:data:`CALIBRATION_TANGENT` for the default errors-in-variables fit, and
:data:`CALIBRATION_MISFIT` for a fit the misfit check rejects); docs/uncertainty.md has the
coverage, scored leave-one-case-out.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model.uncertainty import BOUNDS, MAX_THETA_STD, ParameterUncertainty
from ..signal import cap_corner

METHODS = ("sandwich", "neff", "naive")


def _parzen(u: np.ndarray) -> np.ndarray:
    u = np.abs(u)
    return np.where(u <= 0.5, 1 - 6 * u**2 + 6 * u**3, np.where(u <= 1.0, 2 * (1 - u) ** 3, 0.0))


def _autocov(e: np.ndarray, max_lag: int) -> np.ndarray:
    """Biased sample autocovariance of each column of ``e`` ``(n, c)`` for lags 0..max_lag, ``(max_lag+1, c)``."""
    n = e.shape[0]
    m = 1 << int(np.ceil(np.log2(2 * n)))
    F = np.fft.rfft(e, m, axis=0)
    return np.fft.irfft(np.abs(F) ** 2, m, axis=0)[: max_lag + 1] / n


def _meat(G: np.ndarray, gamma_w: np.ndarray) -> np.ndarray:
    """``sum_{t,s} g(t) gamma(t-s) g(s)^T`` for one floor: ``G`` ``(n, P)`` the Jacobian rows of that
    floor, ``gamma_w`` ``(L+1,)`` the windowed autocovariance (zero beyond lag L)."""
    n, _ = G.shape
    L = len(gamma_w) - 1
    m = 1 << int(np.ceil(np.log2(n + L + 1)))
    kernel = np.zeros(m)
    kernel[: L + 1] = gamma_w
    kernel[m - L:] = gamma_w[1:][::-1]
    W = np.fft.rfft(kernel).real  # the symmetric kernel's spectrum
    F = np.fft.rfft(G, m, axis=0)
    w = np.full(F.shape[0], 2.0)
    w[0] = 1.0
    if m % 2 == 0:
        w[-1] = 1.0
    return ((F.conj().T * (w * W)) @ F).real / m


def covariance(jacobian, residuals, n_floors: int, *, method: str = "sandwich", max_lag: int | None = None):
    """Covariance of the least-squares estimate, ``(P, P)``, and details.

    Parameters
    ----------
    jacobian : (n_time * n_floors, P) d residuals / d parameters at the solution, rows time-major
    residuals : (n_time * n_floors,) residuals at the solution
    n_floors : number of residual channels (columns after ``reshape(n_time, n_floors)``)
    method : ``"sandwich"``, ``"neff"`` or ``"naive"`` (module docstring)
    max_lag : samples of autocorrelation kept (default ``n_time // 8``)

    Returns
    -------
    (cov, info) : info holds ``sigma`` (residual RMS), ``n``, ``n_eff`` and ``max_lag``
    """
    if method not in METHODS:
        raise InputError(f"uncertainty method {method!r} is unknown; expected one of {', '.join(METHODS)}")
    J = np.asarray(jacobian, dtype=float)
    r = np.asarray(residuals, dtype=float).reshape(-1)
    if J.ndim != 2 or J.shape[0] != r.size or r.size % n_floors:
        raise InputError(f"jacobian {J.shape} and residuals ({r.size},) do not match {n_floors} floors")
    n, P = J.shape
    T = n // n_floors
    E = r.reshape(T, n_floors)
    L = int(max_lag if max_lag is not None else max(T // 8, 1))
    L = min(max(L, 1), T - 1)
    gam = _autocov(E, L) * _parzen(np.arange(L + 1) / (L + 1))[:, None]
    A = J.T @ J
    Ainv = np.linalg.pinv(A, rcond=1e-12, hermitian=True)
    s2 = float(r @ r) / max(n - P, 1)
    tau = 1.0 + 2.0 * np.sum(gam[1:], axis=0) / np.maximum(gam[0], 1e-300)  # integrated autocorrelation time
    n_eff = float(np.sum(T / np.maximum(tau, 1.0)))
    info = {"method": method, "sigma": float(np.sqrt(s2)), "n": int(n), "n_eff": n_eff, "max_lag": L}
    if method == "naive":
        return s2 * Ainv, info
    if method == "neff":
        return s2 * Ainv * (n / max(n_eff, P + 1.0)), info
    B = np.zeros((P, P))
    Jf = J.reshape(T, n_floors, P)
    for c in range(n_floors):
        B += _meat(Jf[:, c, :], gam[:, c])
    B = 0.5 * (B + B.T).real
    C = Ainv @ B @ Ainv
    return 0.5 * (C + C.T), info


def transforms_for(slots, x) -> tuple:
    """``"log"`` for a slot whose value is clearly above a zero lower bound, else ``"linear"``."""
    out = []
    for (n, _), v in zip(slots, x):
        lo = BOUNDS[n][0]
        out.append("log" if lo >= 0 and v > max(lo, 0.0) + 1e-9 * max(abs(v), 1.0) and v > 0 else "linear")
    return tuple(out)


def from_refinement(refinement, n_floors: int, *, method: str = "sandwich", scale: float = 1.0,
                    max_lag: int | None = None) -> ParameterUncertainty:
    """The :class:`ParameterUncertainty` of a :class:`~hlaid.identify.RefineResult`.

    ``scale`` multiplies the standard deviations (a calibration factor; 1 = none).
    """
    if refinement.jacobian is None or refinement.residuals is None:
        raise InputError("this refinement result holds no Jacobian and residuals (an hlaid older than v2 clones?)")
    slots = refinement.slots
    x = np.asarray(refinement.x, dtype=float)
    tr = transforms_for(slots, x)
    dxdtheta = np.where(np.array([t == "log" for t in tr]), x, 1.0)
    cov, info = covariance(np.asarray(refinement.jacobian) * dxdtheta[None, :], refinement.residuals, n_floors,
                           method=method, max_lag=max_lag)
    info["scale"] = float(scale)
    centre = np.where(np.array([t == "log" for t in tr]), np.log(np.maximum(x, 1e-300)), x)
    u = ParameterUncertainty(slots=tuple(slots), transform=tr, centre=centre, covariance=cov * scale**2,
                             method=f"laplace-{method}", info=info).capped()
    if u.unidentified:  # what a clone file holds, and what every command reads back
        from .. import _progress
        _progress.warn(f"flag: the record did not identify {', '.join(u.unidentified[:6])}"
                       + (f" and {len(u.unidentified) - 6} more" if len(u.unidentified) > 6 else "")
                       + f": its spread is capped at a standard deviation of {MAX_THETA_STD:g} in its scale")
    return u


CALIBRATION = 2.06
"""Factor on the sandwich standard deviations of a fit consistent with the noise (misfit ratio <=
:data:`MISFIT_LIMIT`), fitted so that 90 % intervals hold 90 % of the true values on the
random-building study; coverage was scored leave-one-case-out (docs/uncertainty.md)."""

CALIBRATION_TANGENT = 1.52
"""The same for the errors-in-variables fit (``refine.method: eiv``, the default): its
residuals are whitened against the ground noise, so its sandwich needs less widening (alone it
held 75.5 % of the true values in its 90 % intervals, least squares' 66 %); fitted on the 55
consistent fits of a 60-building study (scripts/study_uncertainty.py), 1.48-1.53
leave-one-case-out, which then held 89.9 % (docs/uncertainty.md)."""

CALIBRATION_MISFIT = 13.1
"""The same for a fit *not* consistent with the noise (a wrong local minimum): the local
curvature says nothing there, and intervals this wide say "not identified"."""

MISFIT_LIMIT = 2.0
"""Residual RMS over the noise-only expectation above which the fit is flagged as inconsistent
with the measurement noise (a wrong local minimum or a model that does not fit): its Laplace
intervals describe the local curvature only and are not to be trusted."""


def noise_residual_rms(noise_rms: float, band_hz, dt: float) -> float:
    """Expected RMS of the normalised residuals if the model were exact: white sensor noise of
    ``noise_rms`` x channel RMS, band-passed to ``band_hz`` (the ground sensor's noise, seen
    through the structure, adds to it)."""
    lo, hi = band_hz
    hi = cap_corner(hi, dt)
    return float(noise_rms * np.sqrt(max(2.0 * (hi - lo) * dt, 0.0)))


def uncertainty_of_refinement(refinement, n_floors: int, *, noise_rms: float | None = None, band_hz=None,
                              dt: float | None = None) -> ParameterUncertainty | None:
    """The default uncertainty attached to an identified clone: the sandwich covariance widened by
    :data:`CALIBRATION` (:data:`CALIBRATION_TANGENT` for an errors-in-variables fit); given the
    noise level, band and dt also the misfit ratio
    ``info["misfit_ratio"]`` and ``info["fit_consistent"]`` (ratio <= :data:`MISFIT_LIMIT`), and a
    fit that is not consistent is widened by :data:`CALIBRATION_MISFIT` instead. None when the
    refinement has no Jacobian."""
    if refinement is None or refinement.jacobian is None or len(refinement.slots) == 0:
        return None
    factor = CALIBRATION_TANGENT if getattr(refinement, "criterion", "ignore") == "tangent" else CALIBRATION
    u = from_refinement(refinement, n_floors, method="sandwich", scale=factor)
    if noise_rms and band_hz is not None and dt:
        s0 = noise_residual_rms(noise_rms, band_hz, dt)
        if s0 > 0:
            assert u.info is not None  # from_refinement fills info
            ratio = u.info["sigma"] / s0
            if ratio > MISFIT_LIMIT:
                u = from_refinement(refinement, n_floors, method="sandwich", scale=CALIBRATION_MISFIT)
            assert u.info is not None
            u.info.update(misfit_ratio=float(ratio), fit_consistent=bool(ratio <= MISFIT_LIMIT),
                          noise_rms=float(noise_rms))
    return u
