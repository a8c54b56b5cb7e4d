"""Errors in the input of the replay refinement: the ground noise weighted out of its residuals.

The replay is driven by the *measured* ground acceleration, so its floor residuals carry the
ground sensor's noise propagated through the building, besides the floor sensors' own noise.
Least squares of those residuals is an output-error criterion: the propagated part depends on
the parameters, so its optimum sits off the truth even without floor noise. With the building
linearised (initial stiffness, its damping) and both noises white, the residual at frequency
``w`` has the covariance

    Sigma(w) = diag(s_f^2) + s_g^2 |L(w)|^2 h(w) h(w)^H

(``s_f`` floor and ``s_g`` ground noise std, ``h`` the floors' absolute acceleration per unit
ground acceleration, ``L`` the low-pass the replay's ground goes through). Least squares of the
residuals whitened by ``Sigma(w)^(-1/2)`` at every frequency, with ``h`` of the building being
evaluated, is the frequency-domain errors-in-variables criterion (Pintelon and Schoukens,
*System Identification*, ch. 10): the same as minimising over the parameters *and* the true
ground acceleration, the latter with the sensor noise as its prior.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy import signal as _scipy_signal

from ..errors import InputError, UnstableTangentError
from ..model import Building
from ..signal import butter_sos


def ground_transfer(building: Building, freq_hz: np.ndarray) -> np.ndarray:
    """Absolute floor acceleration per unit ground acceleration of the linear building.

    Initial stiffness ``K0`` less the P-Delta stiffness, the building's damping matrix and
    masses: ``h(w) = 1 + w^2 (K - w^2 M + i w C)^-1 M 1``.

    Parameters
    ----------
    building : the building (its k0, masses, damping and P-Delta)
    freq_hz : frequencies [Hz], shape ``(n_freq,)``

    Returns
    -------
    complex array, shape ``(n_freq, n_floors)``
    """
    K = building.stiffness_matrix(pdelta=True)
    M = np.diag(np.asarray(building.mass, dtype=float))
    C = building.damping_matrix()
    w = 2.0 * np.pi * np.asarray(freq_hz, dtype=float)[:, None, None]
    Z = K[None] - w**2 * M[None] + 1j * w * C[None]
    u = np.linalg.solve(Z, np.broadcast_to(M @ np.ones(len(M)), (len(w), len(M)))[..., None])[..., 0]
    return 1.0 + w[:, 0]**2 * u


def lowpass_gain(n_time: int, dt: float, hi_hz: float) -> np.ndarray:
    """Magnitude response of :func:`hlaid.signal.lowpass` (forward and backward, so the
    design's squared) at the ``rfft`` frequencies of ``n_time`` samples, shape ``(n_time // 2 + 1,)``."""
    _, g = _scipy_signal.sosfreqz(butter_sos((0.0, hi_hz), dt), worN=np.fft.rfftfreq(n_time, dt), fs=1.0 / dt)
    return np.abs(g) ** 2


def whiten(res: np.ndarray, v: np.ndarray, floor_std: np.ndarray) -> np.ndarray:
    """Residuals whitened by ``Sigma(w)^(-1/2)`` with ``Sigma = diag(floor_std^2) + a a^H``.

    Parameters
    ----------
    res : residuals, shape ``(n_time, n_floors)`` (or ``(batch, n_time, n_floors)``)
    v : the ground noise's spectrum relative to the floor noise, ``a / floor_std`` per floor,
        shape ``(n_time // 2 + 1, n_floors)``: ``s_g L(w) h(w) / s_f``
    floor_std : the floor noise std in the units of ``res``, shape ``(n_floors,)`` or, when it
        varies with frequency, ``(n_time // 2 + 1, n_floors)``; the result
        is multiplied by their mean, so that with ``v = 0`` and equal stds it is ``res`` itself

    Returns
    -------
    array of ``res``'s shape: ``irfft((I + v v^H)^(-1/2) diag(floor_std)^-1 rfft(res)) * mean(floor_std)``
    (the circular approximation: every DFT bin treated as independent)
    """
    n = res.shape[-2]
    R = np.fft.rfft(res, axis=-2) * (np.mean(floor_std) / floor_std)
    nv2 = np.sum(np.abs(v) ** 2, axis=-1)  # |v|^2 per frequency
    c = np.where(nv2 > 0, (1.0 - 1.0 / np.sqrt(1.0 + nv2)) / np.where(nv2 > 0, nv2, 1.0), 0.0)
    proj = np.sum(np.conj(v) * R, axis=-1)  # v^H R
    R -= (c * proj)[..., None] * v
    return np.fft.irfft(R, n=n, axis=-2)


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
        for c in range(0, T, W):
            k = min(W, T - c)
            Y = np.zeros((k, W + k, n))
            for i in range(k):
                tau = c + i  # only the lags that land inside the record count
                j0, j1 = max(self.lead - tau, 0), min(W, T + self.lead - tau)
                Y[i, i + j0:i + j1] = G[tau, j0:j1] * w
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
        self._chol = scipy.linalg.cholesky_banded(ab, lower=False)

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
