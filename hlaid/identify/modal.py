"""The records' own modes: a linear output-error fit to the lowest-amplitude record.

At small amplitude a building is linear: its floor accelerations are the ground's filtered by
its modes. The records' modes are those of the linear model whose replay of the record best
matches the measured floor accelerations in the records' band: story springs ``k`` (a shear
chain), a flexural coupling term per level pair (:mod:`hlaid.model.coupling`) and one damping
ratio per mode (``modal`` damping), the masses the record's (equal where unknown). Each mode's
absolute-acceleration response is the exact first-order-hold discretisation of ``Gamma_j (2
zeta_j w_j s + w_j^2) / (s^2 + 2 zeta_j w_j s + w_j^2)`` (the ground acceleration linear between
samples, as the simulator takes it: a matrix exponential per mode), run as a digital filter.

mdof's OKID-ERA and SRIM (the project's linear peer, ``pip install hlaid[peer]``) identify the
same modes; this fit needs nothing beyond scipy, and its model is the clone's own linear part, so
its modes, the clone's start and the prior of its coupling are one model's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model.coupling import curvature_operator
from ..model.modes import Mode, unit_roof

MAX_MODE_HZ = 25.0
"""No mode above this is sought (the top of the compared band is kept below it)."""

MAX_EVALUATIONS = 40
"""At most this many evaluations of the residuals (each with its finite-difference Jacobian) per
start of the fit: from the starts below, the modes of the steel frame's record settle within 20."""

FLEXURAL_STARTS = (0.01, 0.3)
"""Starts of the flexural terms, as fractions of the mean story spring."""


@dataclass(frozen=True)
class LinearFit:
    """The linear model of one record (see the module's doc).

    Attributes
    ----------
    k : (story,) story stiffness [N/mm] (per unit mass where the masses are unknown)
    flexural : (story - 1,) flexural coupling terms [N/mm]
    ratios : (story,) damping ratio of each mode, lowest first
    mass : (story,) the masses used [t]
    modes : the model's modes, lowest first (:class:`~hlaid.model.modes.Mode`)
    r : correlation of the replayed and measured floor accelerations in the band, per floor
    band_hz : the band compared [Hz]
    record : the record's name
    """

    k: tuple[float, ...]
    flexural: tuple[float, ...]
    ratios: tuple[float, ...]
    mass: tuple[float, ...]
    modes: tuple[Mode, ...]
    r: tuple[float, ...]
    band_hz: tuple[float, float]
    record: str = ""

    def to_dict(self) -> dict:
        return {"k": list(self.k), "flexural": list(self.flexural), "ratios": list(self.ratios),
                "mass": list(self.mass), "modes": [m.to_dict() for m in self.modes], "r": list(self.r),
                "band_hz": list(self.band_hz), "record": self.record}


def _modal(k, kf, mass):
    import scipy.linalg

    n = len(k)
    kk = np.asarray(k, dtype=float)
    K = np.diag(kk + np.append(kk[1:], 0.0)) - np.diag(kk[1:], 1) - np.diag(kk[1:], -1)
    B = curvature_operator(n)
    K = K + B.T @ (np.asarray(kf, dtype=float)[:, None] * B)
    lam, phi = scipy.linalg.eigh(K, np.diag(mass))
    gamma = phi.T @ np.asarray(mass)  # participation of each mass-normalised mode
    return np.sqrt(np.maximum(lam, 1e-12)), phi, gamma


def linear_response(k, kf, ratios, mass, ag: np.ndarray, dt: float) -> np.ndarray:
    """Absolute floor accelerations ``(time, floor)`` [mm/s^2] of the linear model under ground
    acceleration ``ag`` ``(time,)`` [mm/s^2], from rest."""
    import scipy.signal

    w, phi, gamma = _modal(k, kf, mass)
    out = np.zeros((ag.size, len(k)))
    impulse = np.zeros(ag.size)
    impulse[0] = 1.0
    for j in range(w.size):
        b, a, b_rest = _mode_filter(float(w[j]), float(ratios[j]), float(gamma[j]), dt)
        y = scipy.signal.lfilter(b, a, ag) + ag[0] * scipy.signal.lfilter(b_rest, a, impulse)
        out += y[:, None] * phi[:, j][None, :]
    return out


def _mode_filter(w: float, zeta: float, gamma: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(b, a, b_rest)`` of the digital filter from ground acceleration to one mode's share of the
    absolute floor acceleration: the exact step of ``q'' + 2 zeta w q' + w^2 q = -gamma ag`` with
    ``ag`` linear between samples, read out as ``-(w^2 q + 2 zeta w q')``. The filter alone starts
    as if the ground ramped from zero to its first sample over the sample before; ``b_rest``'s
    impulse response times that first sample removes that ramp's response (the record starts from
    rest, as the simulator's)."""
    import scipy.linalg

    A = np.array([[0.0, 1.0], [-w * w, -2.0 * zeta * w]])
    E = np.zeros((4, 4))
    E[:2, :2], E[:2, 2], E[2, 3] = A, (0.0, -gamma), 1.0 / dt
    E = scipy.linalg.expm(E * dt)
    Phi, ga, gb = E[:2, :2], E[:2, 2], E[:2, 3]  # x1 = Phi x0 + ga u0 + gb (u1 - u0)
    C = np.array([-w * w, -2.0 * zeta * w])
    adj = [np.array([1.0, -Phi[1, 1]]), np.array([0.0, Phi[0, 1]]), np.array([0.0, Phi[1, 0]]),
           np.array([1.0, -Phi[0, 0]])]  # adj(zI - Phi) entries as polynomials in z
    g0 = ga - gb
    num = np.zeros(3)
    for r in range(2):
        for c in range(2):
            num += C[r] * np.convolve(adj[2 * r + c], [gb[c], g0[c]])
    den = np.array([1.0, -np.trace(Phi), np.linalg.det(Phi)])
    w0 = -gb  # x[k] - gb u[k] runs from -gb u[0] where the record starts at rest
    rest = np.zeros(3)
    for r in range(2):
        for c in range(2):
            rest += C[r] * np.convolve(adj[2 * r + c], [w0[c], 0.0])
    return num, den, rest


def _band(x, dt, band):
    import scipy.signal

    sos = scipy.signal.butter(4, band, btype="bandpass", fs=1.0 / dt, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=0)


def fit_linear(ground_acc: np.ndarray, floor_acc: np.ndarray, dt: float, *, k_start: Sequence[float] | np.ndarray,
               mass: Sequence[float] | np.ndarray | None = None, band_hz: tuple[float, float] = (0.5, 20.0),
               record: str = "", coupling: bool = True) -> LinearFit:
    """The linear model of one record (see the module's doc).

    Parameters
    ----------
    ground_acc : (time,) [mm/s^2]; floor_acc : (time, floor) absolute [mm/s^2]
    k_start : (story,) a start of the story stiffnesses (e.g. HLA's)
    mass : (story,) [t], or None (equal unit masses: stiffness per unit mass)
    band_hz : the band compared (its top kept below :data:`MAX_MODE_HZ` and Nyquist)
    coupling : fit the flexural terms (False: held at zero, the shear chain's modes)
    """
    import scipy.optimize

    n = floor_acc.shape[1]
    m = np.ones(n) if mass is None else np.asarray(mass, dtype=float)
    hi = min(band_hz[1], MAX_MODE_HZ, 0.45 / dt)
    band = (band_hz[0], hi)
    meas = _band(floor_acc, dt, band)
    scale = np.sqrt(np.mean(meas**2, axis=0))
    k0 = np.log(np.asarray(k_start, dtype=float))

    nf = n - 1 if coupling else 0

    def unpack(x):
        e = np.exp(x)
        return e[:n], (e[n:n + nf] if coupling else np.zeros(n - 1)), np.minimum(e[n + nf:], 0.9)

    def residuals(x):
        k, kf, zeta = unpack(x)
        sim = _band(linear_response(k, kf, zeta, m, ground_acc, dt), dt, band)
        return ((sim - meas) / scale).ravel() / np.sqrt(meas.shape[0])

    best = None
    kbar = float(np.mean(np.exp(k0)))
    for c in FLEXURAL_STARTS if coupling else (0.0,):
        x0 = np.concatenate([k0, np.full(nf, np.log(max(c, 1e-9) * kbar)), np.full(n, np.log(0.03))])
        lo = np.concatenate([k0 - 3.0, np.full(nf, np.log(1e-6 * kbar)), np.full(n, np.log(1e-3))])
        up = np.concatenate([k0 + 3.0, np.full(nf, np.log(10 * kbar)), np.full(n, np.log(0.9))])
        sol = scipy.optimize.least_squares(residuals, np.clip(x0, lo + 1e-9, up - 1e-9), bounds=(lo, up),
                                           x_scale=1.0, max_nfev=MAX_EVALUATIONS)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    k, kf, zeta = unpack(best.x)
    w, phi, _ = _modal(k, kf, m)
    modes = tuple(Mode(float(w[j] / (2 * np.pi)), float(zeta[j]), tuple(float(v) for v in unit_roof(phi[:, j])))
                  for j in range(n))
    sim = _band(linear_response(k, kf, zeta, m, ground_acc, dt), dt, band)
    r = tuple(float(np.corrcoef(sim[:, i], meas[:, i])[0, 1]) for i in range(n))
    return LinearFit(tuple(map(float, k)), tuple(map(float, kf)), tuple(map(float, zeta)), tuple(map(float, m)),
                     modes, r, (float(band[0]), float(band[1])), record)


def lowest_amplitude(measurements) -> int:
    """Index of the record of smallest peak ground acceleration."""
    return int(np.argmin([np.max(np.abs(m.ground_acc)) for m in measurements]))


__all__ = ["LinearFit", "MAX_MODE_HZ", "fit_linear", "linear_response", "lowest_amplitude"]
