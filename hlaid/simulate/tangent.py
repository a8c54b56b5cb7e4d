"""The floors' response to a small change of the ground motion, along a nonlinear replay.

A yielding building carries a perturbation of its ground acceleration (a sensor's noise) to
its floors by a transfer that changes in time: stiff before yield, soft and hysteretic after.
:func:`ground_tangent` measures that time-varying transfer, the tangent-linear operator of the
replay: for every sample ``tau`` the change of the absolute floor accelerations over the next
``lags`` samples per unit change of the ground acceleration at ``tau``.

It is the replay's tangent-linear model. The Jacobians of one sample's step, ``y[k+1]`` with
respect to ``y[k]``, ``g[k]`` and ``g[k+1]``, are central differences of single steps of the
compiled simulator from the trajectory's own states (every sample at once, one batch); a
perturbation of the ground is then carried through them for ``lags`` samples (:func:`_propagate`,
compiled, parallel over the perturbed samples). The absolute floor accelerations are linear in
the state, so their map is exact.

It agrees to 1e-9-1e-5 with finite differences of replays restarted before each perturbed
sample (the reference in tests/test_tangent.py, 2 x lags x substeps times dearer). The linear
initial-stiffness transfer misses the floors' response to a 10 % ground noise by 108-164 % on
the Table 1 building; this operator by 2-4 % (tests/test_tangent.py, docs/identification.md).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba as nb
import numpy as np
import torch

from .. import _progress
from ..errors import InputError, TangentTooLargeError, UnstableTangentError
from ..limits import check_count
from ..model import BoucWenBuilding, Building, BuildingTensors
from ..motions import GroundMotion
from ..signal import lowpass
from .batch import _run_numba, simulate_response

__all__ = ["GroundTangent", "ground_tangent", "step_jacobians"]

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
                   substeps: int = 4, stride: int = 1, lowpass_hz: float | None = None,
                   max_mb: float | None = None, y0: np.ndarray | None = None) -> GroundTangent:
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
    stride : keep every ``stride``-th sample, of the perturbed samples and of the response: the
        tangent on a coarser grid (``dt * stride``), for a response band-limited well below
        its Nyquist frequency (see ``lowpass_hz``); ``shape`` then perturbs every ``stride``-th
        sample, so white noise of std ``s`` per sample is ``sqrt(stride) * s`` per perturbation
    lowpass_hz : the floors' response low-passed (zero phase, along the lags) at this corner
        before it is sampled, as the residuals it describes; None: as simulated
    max_mb : raise :class:`~hlaid.errors.TangentTooLargeError` before anything is simulated when
        the tangent and its step Jacobians would take more than this many MiB (a budget, below
        the hard limit ``HLAID_MAX_TANGENT_MB`` on four copies)
    y0 : ``(4*story,)`` the state the replay starts from (a building an earlier event left;
        :class:`~hlaid.model.state.BuildingState`); None: at rest

    Returns
    -------
    GroundTangent with ``lead = h`` and ``lags + h`` lags (in samples of ``dt * stride``: the
    shape is padded to make ``h`` a multiple of ``stride``).
    """
    if building.collapse is not None:
        raise InputError("ground_tangent: a building with a collapse model is not supported")
    g = np.asarray(motion.acc, dtype=float)
    T, n = g.size, building.n_stories
    k = np.ones(1) if shape is None else np.asarray(shape, dtype=float)
    if k.ndim != 1 or k.size % 2 == 0:
        raise InputError(f"ground_tangent: shape of {k.shape}; expected an odd-length vector")
    if int(lags) < 1 or int(stride) < 1:
        raise InputError(f"ground_tangent: lags = {lags}, stride = {stride}; expected integers >= 1")
    stride = int(stride)
    pad = -(k.size // 2) % stride
    k = np.pad(k, pad)
    half = k.size // 2
    width = int(lags) * stride + half
    S = 4 * n
    taus = np.arange(0, T, stride)
    one, jacobians = taus.size * width * n * 8.0 / 2**20, T * S * (S + 2) * 8.0 / 2**20  # MiB
    if max_mb is not None and one + jacobians > max_mb:
        raise TangentTooLargeError(f"ground_tangent: the tangent ({taus.size} samples x {width} lags x {n} floors) "
                                   f"and its step Jacobians would take {one + jacobians:.0f} MiB, more than the "
                                   f"{max_mb:g} MiB allowed")
    check_count(4 * one + jacobians, "TANGENT_MB",
                f"memory of the ground tangent ({taus.size} samples x {width} lags x {n} floors, 4 copies, "
                f"and {T} step Jacobians) [MiB]")
    base = simulate_response(building, motion, substeps=substeps, y0=y0)
    if base.status[0] != 0:
        raise InputError("ground_tangent: the replay did not complete")
    assert base.disp is not None and base.vel is not None and base.z is not None and base.energy is not None
    work = base.energy[0] / ((1.0 - np.asarray(building.alpha)) * np.asarray(building.k0))  # e = integral(z dx)
    states = np.concatenate([base.disp[0], base.vel[0], base.z[0], work], axis=1)  # states[0] is y0
    out = np.zeros((taus.size, width, n))
    A, b0, b1 = step_jacobians(building, states, g, float(motion.dt), substeps=substeps)
    cmap = _acceleration_map(building)
    per = max(int(4e8 // (width * S * S)), 1)  # about a second per call: Ctrl-C and progress between calls
    for c0 in range(0, taus.size, per):
        _propagate(A, b0, b1, cmap, k, half, taus[c0:c0 + per], out[c0:c0 + per])
        _progress.debug(f"[tangent] {min(taus.size, c0 + per)}/{taus.size} samples")
    if not np.all(np.isfinite(out)):
        raise UnstableTangentError("ground_tangent: the tangent of the replay grows without bound (not finite): "
                                   "the building is far from the data or its linearisation is unstable")
    if lowpass_hz is not None:
        out = _lowpass_lags(out, float(motion.dt), lowpass_hz, stride)
    else:
        out = out[:, ::stride]
    return GroundTangent(response=out, lead=half // stride, dt=float(motion.dt) * stride)


def _lowpass_lags(out: np.ndarray, dt: float, hi_hz: float, stride: int, rows: int = 32) -> np.ndarray:
    """``out`` low-passed along axis 1 and sampled every ``stride`` lags, in blocks of ``rows``
    rows (a few MB: filtering the whole array at once spent as long allocating as filtering)
    shared among the cores (scipy's filter releases the GIL)."""
    res = np.empty((out.shape[0], len(range(0, out.shape[1], stride)), out.shape[2]))

    def one(r0):
        res[r0:r0 + rows] = lowpass(out[r0:r0 + rows], dt, hi_hz, axis=1)[:, ::stride]

    with ThreadPoolExecutor(max(min(os.cpu_count() or 1, out.shape[0]), 1)) as ex:
        list(ex.map(one, range(0, out.shape[0], rows)))
    return res


def step_jacobians(building: Building, states: np.ndarray, ground: np.ndarray, dt: float, *, substeps: int = 4,
                   rel_step: float = 1e-6, chunk: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jacobians of the compiled simulator's step over every sample of a trajectory.

    The step ``y[k+1] = step(y[k], g[k], g[k+1])`` is one record sample of ``substeps`` RK4
    steps with the ground linear between ``g[k]`` and ``g[k+1]``. Its derivatives are central
    differences of single steps of the same kernel from ``states[k]`` (every sample at once), with
    steps ``rel_step`` times each state component's and the ground's largest magnitude (they agree
    with the torch module's forward-mode derivatives to 1e-6, tests/test_tangent.py).

    Parameters
    ----------
    building : one building without a collapse model
    states : ``(time, 4*story)`` the trajectory ``[u, v, z, e]``
    ground : ``(time,)`` its ground acceleration [mm/s^2]
    dt : sample interval [s]
    chunk : samples per batch of the kernel; None: about 32 MB of initial states per batch

    Returns
    -------
    ``A`` ``(time-1, 4*story, 4*story)`` with ``A[k, i, j] = d y[k+1, i] / d y[k, j]``, and
    ``b0``, ``b1`` ``(time-1, 4*story)``: ``d y[k+1] / d g[k]`` and ``d y[k+1] / d g[k+1]``.
    """
    states = np.asarray(states, dtype=float)
    g = np.asarray(ground, dtype=float)
    T, S = states.shape
    P = BuildingTensors.stack([building]).numpy()
    hy = rel_step * np.maximum(np.max(np.abs(states), axis=0), 1e-9)
    hg = rel_step * max(float(np.max(np.abs(g))), 1e-9)
    A, b0, b1 = np.empty((T - 1, S, S)), np.empty((T - 1, S)), np.empty((T - 1, S))
    chunk = max(2**22 // ((2 * S + 4) * S), 1) if chunk is None else int(chunk)
    for c0 in range(0, T - 1, chunk):
        ks = np.arange(c0, min(T - 1, c0 + chunk))
        m = ks.size
        rows = np.stack([g[ks], g[ks + 1]], axis=1)
        ag = np.concatenate([rows, rows + [hg, 0.0], rows - [hg, 0.0], rows + [0.0, hg], rows - [0.0, hg]])
        y0 = np.repeat(states[ks][None], 2 * S + 4, axis=0)  # (2 S + 4, m, S): +- each state, then +- g0, g1
        for j in range(S):
            y0[2 * j, :, j] += hy[j]
            y0[2 * j + 1, :, j] -= hy[j]
        rep = np.arange(m)
        mi = np.concatenate([np.tile(rep, 2 * S)] + [(q + 1) * m + rep for q in range(4)]).astype(np.int64)
        B = mi.size
        fin = _run_numba(P, ag, np.full(5 * m, dt), np.full(5 * m, 2, dtype=np.int64), mi, np.zeros(B, np.int64),
                         np.ones(B), int(substeps), y0.reshape(B, S), np.full((B, building.n_stories), np.inf),
                         "peaks")[4]
        fs = fin[:2 * S * m].reshape(S, 2, m, S)
        A[ks] = ((fs[:, 0] - fs[:, 1]) / (2.0 * hy[:, None, None])).transpose(1, 2, 0)
        fg = fin[2 * S * m:].reshape(4, m, S)
        b0[ks] = (fg[0] - fg[1]) / (2.0 * hg)
        b1[ks] = (fg[2] - fg[3]) / (2.0 * hg)
    return A, b0, b1


def _acceleration_map(building: Building) -> np.ndarray:
    """``(story, 4*story)``: the absolute floor accelerations are linear in the state ``[u, v, z, e]``."""
    S = 4 * building.n_stories
    unit = torch.as_tensor(np.vstack([np.zeros(S), np.eye(S)]))[None]
    with torch.no_grad():
        acc = BoucWenBuilding(BuildingTensors.stack([building])).responses(unit)["acc"][0].numpy()
    return np.ascontiguousarray((acc[1:] - acc[0]).T)


@nb.njit(parallel=True, cache=True)
def _propagate(A, b0, b1, cmap, shape, half, taus, out):  # pragma: no cover (compiled)
    """``out[i, j] = cmap dy[taus[i] - half + j]``, where ``dy`` is the state's tangent response
    to the ground perturbation ``shape`` starting at sample ``taus[i] - half``:
    ``dy[s+1] = A[s] dy[s] + b0[s] dg[s] + b1[s] dg[s+1]``, zero before (and at) that sample's
    previous one."""
    T = A.shape[0] + 1
    S = A.shape[1]
    n = cmap.shape[0]
    K = shape.size
    width = out.shape[1]
    for row in nb.prange(taus.size):
        s0 = taus[row] - half
        dy = np.zeros(S)
        nxt = np.empty(S)
        s = max(s0 - 1, 0)  # the ground at s0 already acts on the step into s0 (linear between samples)
        stop = min(T, s0 + width)
        while s < stop:
            j = s - s0
            if j >= 0:
                for i in range(n):
                    a = 0.0
                    for q in range(S):
                        a += cmap[i, q] * dy[q]
                    out[row, j, i] = a
            if s + 1 >= T:
                break
            ga = shape[j] if 0 <= j < K else 0.0
            gb = shape[j + 1] if j + 1 < K else 0.0
            for i in range(S):
                a = ga * b0[s, i] + gb * b1[s, i]
                for q in range(S):
                    a += A[s, i, q] * dy[q]
                nxt[i] = a
            for i in range(S):
                dy[i] = nxt[i]
            s += 1
