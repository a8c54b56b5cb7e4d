"""The floors' response to a small change of the ground motion, along a nonlinear replay.

A yielding building carries a perturbation of its ground acceleration (a sensor's noise) to
its floors by a transfer that changes in time: stiff before yield, soft and hysteretic after.
:func:`ground_tangent` measures that time-varying transfer, the tangent-linear operator of the
replay: for every sample ``tau`` the change of the absolute floor accelerations over the next
``lags`` samples per unit change of the ground acceleration at ``tau``. Each column is a
central finite difference of two replays restarted from the trajectory's own state just before
``tau`` (the same simulator and the same story law as every replay; batched). The linear
initial-stiffness transfer misses the floors' response to a 10 % ground noise by 108-164 % on
the Table 1 building; this operator by 2-4 % (tests/test_tangent.py, docs/identification.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _progress
from ..errors import InputError
from ..limits import check_count
from ..model import Building
from ..motions import GroundMotion
from .batch import simulate

__all__ = ["GroundTangent", "ground_tangent"]

@dataclass(frozen=True)
class GroundTangent:
    """Tangent of the absolute floor accelerations with respect to the ground acceleration.

    Attributes
    ----------
    response : ``(time, lags, floor)``: ``response[tau, j, s]`` is the change of floor ``s``'s
        absolute acceleration at sample ``tau - lead + j`` per unit change of the ground
        acceleration's perturbation shape placed at sample ``tau`` (zero past the record)
    lead : samples before ``tau`` held in lag 0 (where a centred shape already acts)
    dt : sample interval [s]
    """

    response: np.ndarray
    lead: int
    dt: float

    @property
    def n_time(self) -> int:
        return self.response.shape[0]

    def apply(self, u: np.ndarray) -> np.ndarray:
        """The floors' response to ground perturbations ``u``: ``(time,)`` or ``(time, k)``
        weights of the shape at every sample -> ``(time, floor)`` or ``(time, floor, k)``."""
        T, L, n = self.response.shape
        u2 = np.asarray(u, dtype=float).reshape(T, -1)
        out = np.zeros((T + L, n, u2.shape[1]))
        for j in range(L):  # sample tau + j - lead receives response[tau, j] u[tau]
            out[j:j + T] += self.response[:, j, :, None] * u2[:, None, :]
        res = out[self.lead:self.lead + T]
        return res[..., 0] if np.ndim(u) == 1 else res

    def adjoint(self, r: np.ndarray) -> np.ndarray:
        """The transpose of :meth:`apply`: ``(time, floor)`` or ``(time, floor, k)`` -> ``(time,)``
        or ``(time, k)``."""
        T, L, n = self.response.shape
        r3 = np.asarray(r, dtype=float).reshape(T, n, -1)
        pad = np.zeros((T + L, n, r3.shape[2]))
        pad[self.lead:self.lead + T] = r3
        out = np.zeros((T, r3.shape[2]))
        for j in range(L):
            out += np.einsum("ts,tsk->tk", self.response[:, j, :], pad[j:j + T])
        return out[:, 0] if np.ndim(r) == 2 else out


def ground_tangent(building: Building, motion: GroundMotion, *, lags: int, shape: np.ndarray | None = None,
                   substeps: int = 4, rel_step: float = 1e-4, chunk: int = 512) -> GroundTangent:
    """Tangent of the floors' absolute accelerations along ``building``'s replay of ``motion``.

    Parameters
    ----------
    building : one building (its collapse model, if any, is not supported)
    motion : the ground motion of the replay
    lags : samples of response kept after each perturbation (the rest is dropped: choose it
        longer than the building's memory, a few of its periods over its damping ratio)
    shape : ``(2 h + 1,)`` perturbation of the ground centred on its sample (e.g. the impulse
        response of the low-pass the replay's ground went through); None: a unit impulse
    substeps : RK4 sub-steps per sample, as the replay
    rel_step : finite-difference step as a fraction of the ground's RMS
    chunk : perturbation samples simulated per batch

    Returns
    -------
    GroundTangent with ``lead = h`` and ``lags + h`` lags.
    """
    if building.collapse is not None:
        raise InputError("ground_tangent: a building with a collapse model is not supported")
    g = np.asarray(motion.acc, dtype=float)
    T, n = g.size, building.n_stories
    k = np.ones(1) if shape is None else np.asarray(shape, dtype=float)
    if k.ndim != 1 or k.size % 2 == 0:
        raise InputError(f"ground_tangent: shape of {k.shape}; expected an odd-length vector")
    if int(lags) < 1:
        raise InputError(f"ground_tangent: lags = {lags}; expected >= 1")
    half = k.size // 2
    width = int(lags) + half
    check_count(4 * T * width * n * 8.0 / 2**20, "TANGENT_MB",
                f"memory of the ground tangent ({T} samples x {width} lags x {n} floors, 4 copies) [MiB]")
    base = simulate(building, motion, substeps=substeps)
    if base.status[0] != 0:
        raise InputError("ground_tangent: the replay did not complete")
    assert base.disp is not None and base.vel is not None and base.z is not None and base.energy is not None
    work = base.energy[0] / ((1.0 - np.asarray(building.alpha)) * np.asarray(building.k0))  # e = integral(z dx)
    states = np.concatenate([base.disp[0], base.vel[0], base.z[0], work], axis=1)  # states[0] is rest
    eps = rel_step * float(np.sqrt(np.mean(g**2)) or 1.0)
    seg_len = width + half + 2
    padded = np.concatenate([g, np.zeros(seg_len + 1)])
    out = np.zeros((T, width, n))
    for c0 in range(0, T, chunk):
        taus = np.arange(c0, min(T, c0 + chunk))
        motions, y0, offs = [], np.empty((2 * taus.size, 4 * n)), []
        for i, tau in enumerate(taus):
            s0 = max(tau - half - 1, 0)  # restart from the state at sample s0 (rest at 0)
            seg = padded[s0:s0 + seg_len]
            lo = max(tau - half, 0)  # the shape's first sample inside the record
            for sign, row in ((1.0, 2 * i), (-1.0, 2 * i + 1)):
                s = seg.copy()
                s[lo - s0:tau + half + 1 - s0] += sign * eps * k[lo - (tau - half):]
                motions.append(GroundMotion(dt=motion.dt, acc=s))
                y0[row] = states[s0]
            offs.append(tau - half - s0)  # segment index of lag 0 (1, or <= 0 at the record's start)
        acc = simulate([building], motions, substeps=substeps, outputs="acc", y0=y0).acc
        assert acc is not None
        diff = (acc[0::2] - acc[1::2]) / (2.0 * eps)
        for i, (tau, off) in enumerate(zip(taus, offs)):
            j0 = max(-off, 0)
            stop = min(width, T - (tau - half))  # lags past the record's end stay zero
            if stop > j0:
                out[tau, j0:stop] = diff[i, off + j0:off + stop]
        _progress.debug(f"[tangent] {taus[-1] + 1}/{T} samples")
    return GroundTangent(response=out, lead=half, dt=float(motion.dt))
