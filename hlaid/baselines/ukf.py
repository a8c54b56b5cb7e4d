"""Unscented Kalman filter on the augmented state (a baseline identifier).

Joint state and parameter estimation, the standard nonlinear-filtering baseline of
structural identification (Wu & Smyth 2007, "Application of the unscented Kalman filter
for real-time nonlinear structural system identification", Struct. Control Health Monit.
14:971-990; Chatzi & Smyth 2009, "The unscented Kalman filter and particle filter methods
for nonlinear structural system identification with non-collocated heterogeneous sensing",
Struct. Control Health Monit. 16:99-123).

Augmented state, ``L = 9 x story``::

    x = [u, v, z, e (the response of every story, as hlaid.model.BoucWenBuilding),
         theta (the 5 x story parameters in the unconstrained coordinates of _space)]

so every sigma point is a valid building (log k0 and dy, logit alpha, softplus for p - 1 and
delta_eta). Sigma points are the scaled unscented transform (``ut_alpha``, ``ut_beta``,
``ut_kappa``; van der Merwe). The process model is one RK4 step per sample (``substeps``)
of ``BoucWenBuilding.rates`` with the sigma points as the batch (one model definition);
parameters follow a random walk. The measurement is the absolute floor acceleration
``-(R + C v)/m`` (``BoucWenBuilding.responses``) of every floor.

Noise settings
--------------
* measurement noise: std ``measurement_noise`` x each channel's RMS (None: the measurement's
  noise level when known, else :func:`hlaid.identify.stages.estimate_noise_rms`), at least
  ``min_noise`` x RMS so that noise-free data keep the filter well conditioned;
* input noise: the ground record carries the same relative noise, low-passed at
  ``band_hz[1]`` like the input; it enters the velocities as process noise
  ``(std x dt)^2`` per step;
* parameter random walk: std ``param_noise`` per sqrt(s) in the unconstrained coordinates;
  the response states (u, z, e) get ``state_noise`` relative std per step.

Several passes over the record (``n_passes``): each restarts the response at rest with the
previous pass's parameter mean and covariance (inflated by ``pass_inflation``), the usual
way to let a filter's parameters converge on a record of finite length.
"""

from __future__ import annotations

import time

import numpy as np
import torch

from .. import _progress
from .._threads import one_thread
from ..clone import Clone
from ..errors import InputError, NotIdentifiableError
from ..estimators import BaseIdentifier
from ..identify.stages import estimate_noise_rms
from ..identify.tb import TBLogger
from ..measurement import Measurement, measured_ground
from ..model import BoucWenBuilding
from ..signal import arias_window, cap_corner
from . import _space as sp

INITS = ("hla", "ranges")
"""Prior parameter mean: ``"hla"`` (k0 from hysteresis loop analysis, dy a fraction of its
peak drift, the others mid-range) or ``"ranges"`` (k0 the geometric mean of ``k0_range``)."""


def sigma_weights(L: int, alpha: float, beta: float, kappa: float):
    """Scaled unscented transform: ``(gamma, Wm, Wc)`` with ``2L+1`` weights each."""
    lam = alpha**2 * (L + kappa) - L
    wm = np.full(2 * L + 1, 0.5 / (L + lam))
    wc = wm.copy()
    wm[0] = lam / (L + lam)
    wc[0] = wm[0] + (1.0 - alpha**2 + beta)
    return float(np.sqrt(L + lam)), torch.as_tensor(wm), torch.as_tensor(wc)


def _sqrt_psd(P: torch.Tensor) -> torch.Tensor:
    """A square root of a (nearly) positive semi-definite matrix: Cholesky, else clipped eigen."""
    P = 0.5 * (P + P.T)
    Lc, info = torch.linalg.cholesky_ex(P)
    if int(info) == 0:
        return Lc
    w, V = torch.linalg.eigh(P)
    return V * w.clamp_min(1e-12 * float(w.abs().max())).sqrt()


class UKFIdentifier(BaseIdentifier):
    """Unscented Kalman filter on response and parameters (see the module docstring).

    Parameters
    ----------
    n_passes : passes over the record
    init : ``"hla"`` or ``"ranges"`` (see :data:`INITS`)
    substeps : RK4 steps per sample in the process model
    arias_end : the record is filtered from its start (the response starts at rest) up to 2 s
        after this fraction of its Arias intensity has arrived
    band_hz : ``band_hz[1]`` low-passes the ground input [Hz]
    damping_ratio : Rayleigh damping assumed (modes 1 and 2)
    prior_std : ``(5,)`` prior std of the unconstrained coordinates of k0, alpha, p, dy,
        delta_eta
    measurement_noise, min_noise, param_noise, state_noise : noise settings (module docstring)
    pass_inflation : factor on the parameter covariance carried to the next pass
    ut_alpha, ut_beta, ut_kappa : scaled unscented transform
    alpha_range, p_range, delta_eta_range, dy_range, k0_range : the prior mean is the middle
        of these (dy: fraction of HLA's peak drift with init "hla", else mm)
    tensorboard : folder for TensorBoard logs (parameter estimates per second) or None

    Attributes
    ----------
    clone_ : the identified clone; fit_seconds_ : wall time
    param_std_ : (5, story) final std of the unconstrained coordinates
    history_ : (pass, 5, story) parameter means at the end of each pass
    """

    def __init__(self, *, n_passes: int = 3, init: str = "hla", substeps: int = 1, arias_end: float = 0.95,
                 band_hz=(0.1, 20.0), damping_ratio: float = 0.05, prior_std=(0.2, 1.0, 1.0, 0.7, 1.0),
                 measurement_noise: float | None = None, min_noise: float = 0.01, param_noise: float = 1e-3,
                 state_noise: float = 1e-6, pass_inflation: float = 4.0, ut_alpha: float = 0.5,
                 ut_beta: float = 2.0, ut_kappa: float = 0.0, alpha_range=(0.02, 0.5), p_range=(1.0, 3.0),
                 dy_range=(0.1, 0.6), delta_eta_range=(0.0, 2.0), k0_range=(1e3, 1e5),
                 tensorboard: str | None = None):
        self.n_passes = n_passes
        self.init = init
        self.substeps = substeps
        self.arias_end = arias_end
        self.band_hz = band_hz
        self.damping_ratio = damping_ratio
        self.prior_std = prior_std
        self.measurement_noise = measurement_noise
        self.min_noise = min_noise
        self.param_noise = param_noise
        self.state_noise = state_noise
        self.pass_inflation = pass_inflation
        self.ut_alpha = ut_alpha
        self.ut_beta = ut_beta
        self.ut_kappa = ut_kappa
        self.alpha_range = alpha_range
        self.p_range = p_range
        self.dy_range = dy_range
        self.delta_eta_range = delta_eta_range
        self.k0_range = k0_range
        self.tensorboard = tensorboard

    def _check(self) -> None:
        if self.init not in INITS:
            raise InputError(f"init = {self.init!r}; expected one of {list(INITS)}")
        if int(self.n_passes) < 1 or int(self.substeps) < 1:
            raise InputError("n_passes and substeps must be >= 1")
        if len(self.prior_std) != len(sp.FIELDS) or min(self.prior_std) <= 0:
            raise InputError(f"prior_std = {list(self.prior_std)}; expected {len(sp.FIELDS)} positive numbers")
        if not self.ut_alpha > 0:
            raise InputError(f"ut_alpha = {self.ut_alpha}; expected > 0")

    def _prior(self, meas: Measurement, known: sp.KnownPart) -> dict[str, np.ndarray]:
        n = known.n_stories

        def mid(r):
            return np.full(n, 0.5 * (r[0] + r[1]))

        if self.init == "hla":
            k0, drift = sp.hla_scales(meas)
            dy = mid(self.dy_range) * drift
        else:
            k0 = np.full(n, np.sqrt(self.k0_range[0] * self.k0_range[1]))
            dy = mid(self.dy_range)
        return {"k0": k0, "alpha": mid(self.alpha_range), "p": np.maximum(mid(self.p_range), 1.05), "dy": dy,
                "delta_eta": np.maximum(mid(self.delta_eta_range), 1e-3)}

    def fit(self, measurement: Measurement) -> UKFIdentifier:
        """Filter ``measurement`` (ground and floor accelerations) and keep the final
        parameter mean as the clone."""
        self._check()
        meas = measurement
        t0 = time.perf_counter()
        with one_thread():  # tiny tensors: intra-op threads only add contention
            known = sp.known_part(meas, self.damping_ratio)
            prior = self._prior(meas, known)
            k0_ref, dy_ref = prior["k0"], prior["dy"]
            theta = torch.as_tensor(sp.to_unconstrained(prior, k0_ref, dy_ref))  # (5, n)
            std = torch.as_tensor(np.asarray(self.prior_std, dtype=float))[:, None].expand_as(theta)
            Ptheta = torch.diag(std.reshape(-1) ** 2)
            ground = measured_ground(meas, cap_corner(self.band_hz[1], meas.dt))
            _, i1 = arias_window(ground.acc, meas.dt, (0.0, self.arias_end))
            tb = TBLogger(self.tensorboard)
            history = []
            for k in range(int(self.n_passes)):
                theta, Ptheta = self._pass(meas, known, ground.acc[:i1], theta, Ptheta, k0_ref, dy_ref, tb, k)
                history.append(theta.numpy().copy())
                _progress.info(f"[ukf] pass {k + 1}/{self.n_passes}: " + ", ".join(
                    f"{f} {np.array2string(v, precision=3)}" for f, v in sp.values_numpy(
                        sp.from_unconstrained(theta, k0_ref, dy_ref)).items()))
                if k + 1 < int(self.n_passes):
                    Ptheta = Ptheta * float(self.pass_inflation)
            tb.close()
        values = sp.values_numpy(sp.from_unconstrained(theta, k0_ref, dy_ref))
        building = known.building(values)
        self.param_std_ = torch.diagonal(Ptheta).sqrt().reshape(theta.shape).numpy()
        self.history_ = np.stack(history)
        self.fit_seconds_ = time.perf_counter() - t0
        diagnostics = {"method": "unscented Kalman filter (augmented state)", "passes": int(self.n_passes),
                       "param_std": self.param_std_.tolist(), "window_s": [0.0, i1 * meas.dt]}
        provenance = {"identifier": repr(self), "source": meas.source, "seconds": self.fit_seconds_}
        self.clone_ = Clone(building=building, mass_normalised=known.mass_normalised, diagnostics=diagnostics,
                            provenance=provenance)
        return self

    def _noise(self, meas: Measurement, i1: int):
        """Measurement noise variance ``(story,)`` and input-noise std [mm/s^2]."""
        level = self.measurement_noise
        if level is None:
            level = meas.noise_rms if meas.noise_rms is not None else estimate_noise_rms(meas)
        level = max(float(level), float(self.min_noise))
        floor = np.asarray(meas.floor_acc[:i1])
        rms = np.sqrt(np.mean(floor**2, axis=0))
        hi = cap_corner(self.band_hz[1], meas.dt)
        g_std = level * np.sqrt(np.mean(np.asarray(meas.ground_acc[:i1]) ** 2)) * np.sqrt(hi * 2 * meas.dt)
        return torch.as_tensor((level * rms) ** 2), g_std

    def _pass(self, meas, known, ag, theta, Ptheta, k0_ref, dy_ref, tb, k_pass):
        """One filter pass from rest; returns the parameter mean ``(5, n)`` and covariance."""
        n = known.n_stories
        ns, npar = 4 * n, theta.numel()
        L = ns + npar
        dt, m = meas.dt, int(self.substeps)
        gamma, Wm, Wc = sigma_weights(L, self.ut_alpha, self.ut_beta, self.ut_kappa)
        i1 = ag.shape[0]
        R, g_std = self._noise(meas, i1)
        y_meas = torch.as_tensor(np.array(meas.floor_acc[:i1]))
        g = torch.as_tensor(np.array(ag))
        x = torch.cat([torch.zeros(ns, dtype=theta.dtype), theta.reshape(-1)])
        P = torch.zeros(L, L, dtype=theta.dtype)
        P[ns:, ns:] = Ptheta
        scale = torch.as_tensor(np.concatenate([np.full(n, 1.0), np.full(n, 10.0), np.asarray(dy_ref, dtype=float),
                                                np.full(n, 100.0)]))  # typical u, v, z, e [mm, mm/s, mm, mm^2]
        Q = torch.zeros(L, dtype=theta.dtype)
        Q[:ns] = (float(self.state_noise) * scale) ** 2
        Q[n:2 * n] += (g_std * dt) ** 2
        Q[ns:] = float(self.param_noise) ** 2 * dt
        Q = torch.diag(Q)
        P[:ns, :ns] = Q[:ns, :ns]
        for k in range(i1):
            if k > 0:  # predict: sample k-1 -> k
                S_ = _sqrt_psd(P).T
                X = x[None] + gamma * torch.cat([torch.zeros(1, L, dtype=x.dtype), S_, -S_])
                model = self._model(known, X[:, ns:], k0_ref, dy_ref)
                y = X[:, :ns]
                y = model.rk4_sample(y, g[k - 1].expand(X.shape[0]), g[k].expand(X.shape[0]), dt, m)
                X = torch.cat([y, X[:, ns:]], dim=1)
                if not torch.isfinite(X).all():
                    raise NotIdentifiableError(f"the unscented Kalman filter diverged at t = {k * dt:.2f} s "
                                               f"(pass {k_pass + 1})", source=meas.source or None)
                x = Wm @ X
                D = X - x
                P = (D.T * Wc) @ D + Q
            # update with the floor accelerations of sample k
            S_ = _sqrt_psd(P).T
            X = x[None] + gamma * torch.cat([torch.zeros(1, L, dtype=x.dtype), S_, -S_])
            model = self._model(known, X[:, ns:], k0_ref, dy_ref)
            Y = model.responses(X[:, None, :ns])["acc"][:, 0]  # (2L+1, n)
            yb = Wm @ Y
            DY, DX = Y - yb, X - x
            Pyy = (DY.T * Wc) @ DY + torch.diag(R)
            Pxy = (DX.T * Wc) @ DY
            K = torch.linalg.solve(Pyy, Pxy.T).T
            x = x + K @ (y_meas[k] - yb)
            P = P - K @ Pyy @ K.T
            P = 0.5 * (P + P.T)
            if k % round(1.0 / dt) == 0:
                for f, v in sp.values_numpy(sp.from_unconstrained(x[ns:].reshape(theta.shape), k0_ref,
                                                                  dy_ref)).items():
                    for i in range(n):
                        tb.scalar(f"ukf/pass{k_pass + 1}/story{i + 1}/{f}", float(v[i]), k)
        return x[ns:].reshape(theta.shape).clone(), P[ns:, ns:].clone()

    @staticmethod
    def _model(known: sp.KnownPart, coords: torch.Tensor, k0_ref, dy_ref) -> BoucWenBuilding:
        values = sp.from_unconstrained(coords.reshape(coords.shape[0], len(sp.FIELDS), -1), k0_ref, dy_ref)
        return BoucWenBuilding(known.tensors(values))
