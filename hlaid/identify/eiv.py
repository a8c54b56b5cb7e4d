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
from scipy import signal as _scipy_signal

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
