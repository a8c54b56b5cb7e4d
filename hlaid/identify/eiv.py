"""Errors in the input of the refinement: the ground noise weighted out of its residuals.

The replay is driven by the *measured* ground acceleration, so its floor residuals carry the
ground sensor's noise propagated through the building, besides the floor sensors' own noise.
Least squares of those residuals is an output-error criterion: the propagated part depends on
the parameters, so its optimum sits off the truth even without floor noise. A yielding
building carries the ground noise to its floors by a transfer that changes in time: the
tangent of its replay (:func:`hlaid.simulate.tangent.ground_tangent`). :class:`TangentWhitener`
whitens the residuals against floor noise plus the ground noise carried by that tangent:
least squares of the whitened residuals is maximum likelihood with the true ground as a
nuisance (errors in variables), linearised about the trajectory the tangent was taken along.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ..errors import InputError, UnstableTangentError, one_line
from ..measurement import Measurement
from ..model import Building
from ..motions import GroundMotion
from ..signal import lowpass
from ..simulate.tangent import GroundTangent, ground_tangent


def ground_memory(building: Building, decays: float = 4.0, limits_s=(2.0, 10.0)) -> float:
    """Seconds of the floors' response to a ground sample that the tangent keeps by default:
    ``decays`` first-mode decay times ``T1 / (2 pi zeta)`` of the linear building (initial
    stiffness, its damping ratio), within ``limits_s``. Table 1 (T1 0.38 s, 5 %): 4.9 s, after
    which 0.2-0.6 % of the tangent's energy is left on its five records (yielding lengthens the
    tail); the tangent only weights the residuals, so a shorter memory costs efficiency, not
    consistency."""
    zeta = building.damping.ratio if building.damping.kind != "none" else 0.0
    t1 = float(building.periods()[0])
    tau = t1 / (2.0 * np.pi * zeta) if zeta > 0 else np.inf
    return float(np.clip(decays * tau, *limits_s))


def tangent_whitener(building: Building, meas: Measurement, ground: GroundMotion, hi_hz: float, scale: np.ndarray,
                      memory_s: float, substeps: int, stride: int, max_mb: float | None = None,
                      y0: np.ndarray | None = None) -> TangentWhitener:
    """:class:`~hlaid.identify.eiv.TangentWhitener` of the refinement's residuals, low-passed at
    ``hi_hz`` and sampled every ``stride`` samples.

    The replay's ground is the measured one low-passed at ``hi_hz``, so a ground sensor's white
    noise reaches it through that low-pass: the tangent is taken for the low-pass's impulse
    response at every ``stride``-th sample (white noise of std ``s`` per sample is then
    ``sqrt(stride) s`` per perturbation), its floor responses low-passed, sampled and divided by
    ``scale`` like the residuals (the 0.1 Hz high-pass is left out: white noise has next to no
    power below it). The floor noise, white of std ``s`` per sample and low-passed, is white of
    std ``s / sqrt(stride)`` on the coarse grid within the band. Every channel's noise a common
    fraction of its RMS (the fraction cancels). ``y0``: the state the replay starts from (None:
    at rest).
    """
    dt = meas.dt
    half = int(np.ceil(4.0 / (hi_hz * dt)))
    imp = np.zeros(8 * half + 1)
    imp[4 * half] = 1.0
    shape = lowpass(imp, dt, hi_hz)[2 * half:6 * half + 1]  # room before lag 0 for the output's low-pass
    lags = max(int(round(memory_s / (dt * stride))), 1)
    gt = ground_tangent(building, ground, lags=lags, shape=shape, substeps=substeps, stride=stride, lowpass_hz=hi_hz,
                        max_mb=max_mb, y0=y0)
    floor = np.asarray(meas.floor_acc)
    rms_f = np.sqrt(np.mean(floor**2, axis=0))
    rms_g = float(np.sqrt(np.mean(np.asarray(meas.ground_acc) ** 2)))
    resp = GroundTangent(response=gt.response / scale[None, None, :], lead=gt.lead, dt=gt.dt)
    return TangentWhitener(resp, rms_f / scale / np.sqrt(stride), rms_g * np.sqrt(stride))


class TangentWhitener:
    """Residuals whitened against floor noise plus the ground noise carried by a time-varying
    tangent (:func:`hlaid.simulate.tangent.ground_tangent`), the errors-in-variables criterion.

    The residual model is ``r = e_f + G e_g``: ``e_f`` white floor noise of std ``s_f`` per
    floor, ``e_g`` white ground noise of std ``s_g`` per sample, ``G`` the tangent (in the
    residuals' units per unit ground noise). Minimising ``|(r + G d) / s_f|^2 + |d / s_g|^2`` over
    the ground correction ``d`` gives ``d = -M^-1 G^T D r`` with ``M = I / s_g^2 + G^T D G``
    (``D = diag(1 / s_f^2)``, ``M`` banded: ``G`` only reaches ``lags`` samples), and the whitened
    residuals ``rho = c [(r + G d) / s_f ; d / s_g]`` whose squared norm is
    ``c^2 r^T (diag(s_f^2) + s_g^2 G G^T)^-1 r``: least squares of ``rho`` over the building's
    parameters is maximum likelihood with the true ground as a nuisance, linearised about the
    trajectory the tangent was taken along. ``c = mean(s_f)`` keeps the residuals' units.

    Parameters
    ----------
    tangent : :class:`~hlaid.simulate.tangent.GroundTangent` in residual units
    floor_std : ``(floor,)`` floor noise std in residual units (before any band-pass)
    ground_std : ground noise std per sample in the tangent's input units
    """

    def __init__(self, tangent, floor_std, ground_std: float):
        G = np.asarray(tangent.response, dtype=float)
        T, W, n = G.shape
        self.n_time, self.n_floors, self.lead, self.width = T, n, int(tangent.lead), W
        self.floor_std = np.asarray(floor_std, dtype=float).reshape(n)
        self.ground_std = float(ground_std)
        if not (np.all(self.floor_std > 0) and self.ground_std > 0):
            raise InputError("TangentWhitener: noise stds must be positive")
        w = 1.0 / self.floor_std
        # column blocks of W samples as dense (block, W + block rows, floor) arrays scaled by D^(1/2):
        # block b's rows start at sample c_b - lead; blocks b and b + 1 share W rows, b and b + 2 none
        self._blocks = []
        lags = np.arange(W)[None, :]
        for c in range(0, T, W):
            k = min(W, T - c)
            Y = np.zeros((k, W + k, n))
            rows = np.arange(k)[:, None]
            tau = c + rows  # only the lags that land inside the record count
            keep = (lags >= self.lead - tau) & (lags < T + self.lead - tau)
            i, j = np.nonzero(keep)
            Y[i, i + j] = G[c + i, j] * w
            self._blocks.append((c, Y))
        u = W - 1
        ab = np.zeros((W, T))  # upper band: ab[u + i - j, j] = M[i, j]
        ab[u] = 1.0 / self.ground_std**2
        for b, (c, Y) in enumerate(self._blocks):
            k = Y.shape[0]
            Yf = Y.reshape(k, -1)
            Mbb = Yf @ Yf.T
            for d in range(min(k, W)):
                ab[u - d, c + d:c + k] += np.diagonal(Mbb, d)
            if b + 1 < len(self._blocks):
                c2, Y2 = self._blocks[b + 1]
                k2 = Y2.shape[0]
                Mo = Y[:, k:k + W].reshape(k, -1) @ Y2[:, :W].reshape(k2, -1).T  # M[c + i, c2 + j]
                for d in range(1, W):  # global j - i = d: c2 + j - (c + i) = d
                    off = d - (c2 - c)
                    diag = np.diagonal(Mo, off)
                    if diag.size == 0:
                        continue
                    j0 = max(off, 0)
                    ab[u - d, c2 + j0:c2 + j0 + diag.size] += diag
        if not np.all(np.isfinite(ab)):  # finite but huge tangents overflow G^T D G
            raise UnstableTangentError("TangentWhitener: the tangent's Gram matrix overflows (a tangent that grows "
                                       "without bound along the replay)")
        try:
            self._chol = scipy.linalg.cholesky_banded(ab, lower=False)
        except np.linalg.LinAlgError as err:  # rounding in a near-singular Gram matrix (a very soft story)
            raise UnstableTangentError(f"TangentWhitener: the whitening matrix is not positive definite "
                                       f"({one_line(err, 80)}): the tangent of this replay is too "
                                       "ill-conditioned to weigh the ground's noise") from None

    def _apply(self, d: np.ndarray) -> np.ndarray:
        """``D^(1/2) G d``: ``(time, k)`` -> ``(time, floor, k)``."""
        T, W, n = self.n_time, self.width, self.n_floors
        out = np.zeros((T + 2 * W + self.lead, n, d.shape[1]))
        for c, Y in self._blocks:
            k = Y.shape[0]
            out[c:c + W + k] += (Y.reshape(k, -1).T @ d[c:c + k]).reshape(W + k, n, -1)
        return out[self.lead:self.lead + T]

    def _adjoint(self, x: np.ndarray) -> np.ndarray:
        """``G^T D^(1/2) x``: ``(time, floor, k)`` -> ``(time, k)``."""
        T, W, n = self.n_time, self.width, self.n_floors
        pad = np.zeros((T + 2 * W + self.lead, n, x.shape[2]))
        pad[self.lead:self.lead + T] = x
        out = np.empty((T, x.shape[2]))
        for c, Y in self._blocks:
            k = Y.shape[0]
            out[c:c + k] = Y.reshape(k, -1) @ pad[c:c + W + k].reshape((W + k) * n, -1)
        return out

    def __call__(self, res: np.ndarray) -> np.ndarray:
        """Whitened residuals: ``(time, floor)`` -> ``(time, floor + 1)``, or
        ``(batch, time, floor)`` -> ``(batch, time, floor + 1)`` (the last column the ground's)."""
        r = np.asarray(res, dtype=float)
        one = r.ndim == 2
        r3 = (r[None] if one else r).transpose(1, 2, 0)  # (time, floor, batch)
        x = r3 / self.floor_std[None, :, None]
        d = -scipy.linalg.cho_solve_banded((self._chol, False), self._adjoint(x))
        c = float(np.mean(self.floor_std))
        out = np.concatenate([x + self._apply(d), (d / self.ground_std)[:, None, :]], axis=1) * c
        out = out.transpose(2, 0, 1)
        return out[0] if one else out
