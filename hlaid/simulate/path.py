"""The story law driven along a given drift history (no building, no dynamics).

For a story whose drift ``x(t)`` is known (measured, or reconstructed), the hysteretic
displacement ``z`` and the work ``e = integral(z dx)`` follow from eq 3-10 alone: the same
compiled functions of :mod:`hlaid.model._equations` that the batch simulator uses, integrated
by RK4 along the path. This is how the identification generates its training half cycles:
every simulated half cycle has the measured half cycle's own path and differs only in the
story parameters.

Between two samples the path is the cubic Hermite interpolant of the drift and the drift
velocity when the velocity is given (what the batch simulator integrates, to RK4 accuracy),
else the straight line between the samples (for measured paths, whose velocity is noisier
than their drift increments).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..model import equations as eq
from ..model.collapse import N_COLLAPSE
from ._kernel import _FASTMATH, _degradation, _spring_force

_LANES = 16
"""Parameter sets integrated in lockstep by one thread of :func:`_drive`: each RK4 stage is
evaluated for all lanes before the next, so its arithmetic, the power included
(:func:`_pow_lanes`), runs as vector instructions across them. Measured on 800 sets along Table 1's
paths, one thread: 33-42 ns per set and sample (58-80 ns with libm's ``pow`` per lane, which was
itself 2.2x faster than one set at a time); 32 lanes were no faster."""


# pow(w, p) = exp(p log w) in arithmetic LLVM vectorises (libm's pow is a call per lane): log from
# the exponent bits and the atanh series of the mantissa, exp as in hlaid.svm._solver
_LN2_HI = 0.6931471803691238
_LN2_LO = 1.9082149292705877e-10
_MAGIC = 6755399441055744.0  # 1.5 * 2^52: x + _MAGIC rounds x to an integer held in the low bits
_LOG2E = 1.4426950408889634
_SQRT2 = 1.4142135623730951
_TINY = 1e-300

# rows of a block's lane scratch ``W`` (row, lane): every array a block needs is one of three
# (``W``, its bits ``Wb``, the parameters ``PAR``): numba passes each array to a function with two
# atomic reference-count updates, which cost as much as the arithmetic of 16 lanes
_KZ, _KE = 0, 4  # the four stages' rates of z (rows 0-3) and of e (rows 4-7)
_W, _Q, _T, _U = 8, 9, 10, 11  # a stage's |z/dy| (loading), its power, scratch, eta
_R = 12  # rows 12-14: the drift rate at the start, middle and end of a step
_Z, _E, _Z1, _E1 = 15, 16, 17, 18  # the lanes' state and the trial of a sample
_ROWS = 19
_K0, _AL, _P, _DY, _DE = 0, 1, 2, 3, 4  # rows of the parameters PAR (5, batch)


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _pow_lanes(j0, j1, lo, W, Wb, PAR):
    """``W[_Q, j] = W[_W, j] ** PAR[_P, lo + j]`` for lanes ``j0 <= j < j1``, ``W[_W] >= 0`` (0
    below 1e-300). Within 4.5e-16 (absolute, two ulps of 1) of libm's ``pow`` for ``w <= 1`` and ``p`` in [1, 10]
    (the law's ``|z/dy|^p``), in loops that vectorise: the lanes in AVX-512 registers instead of
    one ``pow`` call each."""
    for j in range(j0, j1):  # frexp: the mantissa in [1, 2) into _T, the exponent into _Q
        b = Wb[_W, j]
        W[_Q, j] = float(((b >> 52) & 0x7FF) - 1023)
        Wb[_T, j] = (b & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000
    for j in range(j0, j1):
        m = W[_T, j]
        big = m > _SQRT2
        m = m * 0.5 if big else m  # in [sqrt(1/2), sqrt(2)): |s| <= 0.172
        e = W[_Q, j] + 1.0 if big else W[_Q, j]
        s = (m - 1.0) / (m + 1.0)
        s2 = s * s
        half_log = 1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0 + s2 * (
            1.0 / 11.0 + s2 * (1.0 / 13.0 + s2 * (1.0 / 15.0 + s2 * (1.0 / 17.0 + s2 * (1.0 / 19.0 + s2 * (
                1.0 / 21.0 + s2 * (1.0 / 23.0)))))))))))
        x = max(PAR[_P, lo + j] * ((e * _LN2_HI + 2.0 * s * half_log) + e * _LN2_LO), -708.0)
        tt = x * _LOG2E + _MAGIC
        W[_T, j] = tt
        k = tt - _MAGIC
        r = (x - k * _LN2_HI) - k * _LN2_LO
        W[_Q, j] = 1.0 + r * (1.0 + r * (0.5 + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (
            1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0 + r * (1.0 / 40320.0 + r * (
                1.0 / 362880.0 + r * (1.0 / 3628800.0 + r * (1.0 / 39916800.0 + r * (
                    1.0 / 479001600.0))))))))))))
    for j in range(j0, j1):  # 2^k from its bits
        Wb[_T, j] = (Wb[_T, j] + 1023) << 52
    for j in range(j0, j1):
        W[_Q, j] = W[_Q, j] * W[_T, j] if W[_W, j] > _TINY else 0.0


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _stage(j0, j1, W, Wb, PAR, lo, m, c, zk, ek, out, rate):
    """One RK4 stage of lanes ``j0 <= j < j1``: the rates ``W[_KZ + out], W[_KE + out]`` at
    ``(z + c W[zk], e + c W[ek])`` (``z, e`` the rows ``_Z1, _E1``) with the drift rate in row
    ``rate``: eq 7-10 with the arithmetic of :func:`hlaid.model._equations.hysteretic_rate` and
    ``degradation``, the power from :func:`_pow_lanes`."""
    for j in range(j0, j1):
        b = lo + j
        zs = W[_Z1, j] + c * W[zk, j]
        es = W[_E1, j] + c * W[ek, j]
        W[_U, j] = _degradation(es, PAR[_AL, b], PAR[_K0, b], m, PAR[_DE, b])
        d = W[rate, j]
        s = d * zs
        loading = 0.5 * ((s > 0.0) * 1.0 - (s < 0.0) * 1.0 + 1.0)
        W[_W, j] = loading * abs(zs / PAR[_DY, b])
        W[_KE + out, j] = zs * d
    _pow_lanes(j0, j1, lo, W, Wb, PAR)
    for j in range(j0, j1):
        W[_KZ + out, j] = W[rate, j] * (1.0 - W[_Q, j]) / W[_U, j]


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _rk4_lanes(j0, j1, W, Wb, PAR, lo, m, h):
    """One RK4 step of ``(z, e)`` (rows ``_Z1, _E1``) for lanes ``j0 <= j < j1`` (parameter set
    ``lo + j``), the drift rates at the start, middle and end of the step in rows ``_R.._R+2``."""
    _stage(j0, j1, W, Wb, PAR, lo, m, 0.0, _Z1, _E1, 0, _R)
    _stage(j0, j1, W, Wb, PAR, lo, m, 0.5 * h, _KZ, _KE, 1, _R + 1)
    _stage(j0, j1, W, Wb, PAR, lo, m, 0.5 * h, _KZ + 1, _KE + 1, 2, _R + 1)
    _stage(j0, j1, W, Wb, PAR, lo, m, h, _KZ + 2, _KE + 2, 3, _R + 2)
    for j in range(j0, j1):
        W[_Z1, j] = W[_Z1, j] + h / 6.0 * (W[_KZ, j] + 2.0 * W[_KZ + 1, j] + 2.0 * W[_KZ + 2, j] + W[_KZ + 3, j])
        W[_E1, j] = W[_E1, j] + h / 6.0 * (W[_KE, j] + 2.0 * W[_KE + 1, j] + 2.0 * W[_KE + 2, j] + W[_KE + 3, j])


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _hermite_rate(tau, x0, x1, v0, v1, dt):
    """Derivative of the cubic Hermite interpolant at ``tau`` in [0, 1] of a sample interval."""
    t2 = tau * tau
    return ((6.0 * t2 - 6.0 * tau) * (x0 - x1) / dt + (3.0 * t2 - 4.0 * tau + 1.0) * v0
            + (3.0 * t2 - 2.0 * tau) * v1)


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _advance(j0, j1, W, Wb, PAR, lo, m, x, v, k, dt, hermite, ns):
    """``(z, e)`` (rows ``_Z1, _E1``) of lanes ``j0 <= j < j1`` over sample interval ``k`` in
    ``ns`` RK4 sub-steps, lane ``j`` along path ``x[(lo + j) % n_paths]``."""
    P = x.shape[0]
    h = dt / ns
    for s in range(ns):
        if hermite:
            for j in range(j0, j1):
                q = (lo + j) % P
                for c in range(3):
                    W[_R + c, j] = _hermite_rate((s + 0.5 * c) / ns, x[q, k], x[q, k + 1], v[q, k], v[q, k + 1], dt)
        elif P == 1:  # one path for every lane (the training samples): no modulo per lane
            d = (x[0, k + 1] - x[0, k]) / dt
            for j in range(j0, j1):
                W[_R, j] = d
                W[_R + 1, j] = d
                W[_R + 2, j] = d
        else:
            for j in range(j0, j1):
                q = (lo + j) % P
                d = (x[q, k + 1] - x[q, k]) / dt
                W[_R, j] = d
                W[_R + 1, j] = d
                W[_R + 2, j] = d
        _rk4_lanes(j0, j1, W, Wb, PAR, lo, m, h)


@nb.njit(cache=True, parallel=True, fastmath=_FASTMATH, error_model="numpy")
def _drive(x, v, dt, hermite, PAR, m, nsub, state, force, z_out, e_out):
    """Integrate every parameter set ``b`` (column of ``PAR``, rows k0, alpha, p, dy, delta_eta)
    along path ``x[b % n_paths]``; see :func:`drive_story`. Each thread takes blocks of
    :data:`_LANES` parameter sets and steps them in lockstep. A set whose step lets ``|z|``
    overshoot ``dy`` is redone alone with up to 16x the sub-steps (as the batch simulator does);
    beyond that it takes the law's limit (elastic to ``|z| = dy``). ``z_out`` and ``e_out`` are
    written only with ``state`` (the force alone halves the memory traffic of a large batch)."""
    B = PAR.shape[1]
    P, T = x.shape
    for c in nb.prange((B + _LANES - 1) // _LANES):
        lo = c * _LANES
        n = min(_LANES, B - lo)
        W = np.zeros((_ROWS, _LANES))
        Wb = W.view(np.int64)
        path = np.empty(_LANES, dtype=np.int64)  # each lane's path (a modulo per lane and step cost 10 %)
        for j in range(n):
            b = lo + j
            path[j] = b % P
            force[b, 0] = _spring_force(x[path[j], 0], 0.0, PAR[_AL, b], PAR[_K0, b])
            if state:
                z_out[b, 0] = 0.0
                e_out[b, 0] = 0.0
        for k in range(T - 1):
            for j in range(n):
                W[_Z1, j] = W[_Z, j]
                W[_E1, j] = W[_E, j]
            _advance(0, n, W, Wb, PAR, lo, m, x, v, k, dt, hermite, nsub)
            for j in range(n):
                b = lo + j
                dyb = PAR[_DY, b]
                top = dyb * (1.0 + 1e-5)
                ns = nsub
                while not abs(W[_Z1, j]) <= top and ns < 16 * nsub:  # overshoot: redo with 2x, 4x ... 16x
                    ns *= 2
                    W[_Z1, j] = W[_Z, j]
                    W[_E1, j] = W[_E, j]
                    _advance(j, j + 1, W, Wb, PAR, lo, m, x, v, k, dt, hermite, ns)
                x0 = x[path[j], k]
                x1 = x[path[j], k + 1]
                z0, e0 = W[_Z, j], W[_E, j]
                if not abs(W[_Z1, j]) <= top:
                    # still over (a drift increment of many dy in one sample): the law's limit for such a
                    # step, elastic to the yield surface and no further (|z| <= dy holds for the exact law)
                    eta = _degradation(e0, PAR[_AL, b], PAR[_K0, b], m, PAR[_DE, b])
                    W[_Z1, j] = min(max(z0 + (x1 - x0) / eta, -dyb), dyb)
                    W[_E1, j] = e0 + 0.5 * (z0 + W[_Z1, j]) * (x1 - x0)
                W[_Z, j] = W[_Z1, j]
                W[_E, j] = W[_E1, j]
                force[b, k + 1] = _spring_force(x1, W[_Z, j], PAR[_AL, b], PAR[_K0, b])
                if state:
                    z_out[b, k + 1] = W[_Z, j]
                    e_out[b, k + 1] = W[_E, j]


@dataclass(frozen=True, eq=False)
class PathResponse:
    """Response of the story law along a drift path; every field is ``(batch, time)``.

    Attributes
    ----------
    force : spring force ``alpha k0 x + (1-alpha) k0 z`` [N]
    z : hysteretic displacement [mm] (None when driven with ``state=False``)
    energy : ``e = integral(z dx)`` [mm^2] (None when driven with ``state=False``)
    """

    force: np.ndarray
    z: np.ndarray | None
    energy: np.ndarray | None

    def elastic_stiffness(self, k0, alpha, delta_eta, mass) -> np.ndarray:
        """``ke(t) = alpha k0 + (1-alpha) k0 / eta(t)`` (eq 11), ``(batch, time)`` [N/mm]."""
        if self.energy is None:
            raise ValueError("this response was driven with state=False; drive it with state=True for ke(t)")
        k0, alpha, delta_eta = (np.asarray(a, float).reshape(-1, 1) for a in (k0, alpha, delta_eta))
        eta = _degradation(self.energy, alpha, k0, mass, delta_eta)
        return alpha * k0 + (1.0 - alpha) * k0 / eta


def drive_story(drift: np.ndarray, *, k0, alpha, p, dy, delta_eta, mass: float, dt: float,
                velocity: np.ndarray | None = None, substeps: int = 4, state: bool = True,
                collapse=None) -> PathResponse:
    """Drive the degrading Bouc-Wen story law along drift paths, batched over parameters.

    Parameters
    ----------
    drift : ``(time,)`` or ``(path, time)`` drift [mm]; parameter set ``b`` follows path
        ``b % path`` (one path for all, one per parameter set, or any number that divides the
        parameter sets)
    k0, alpha, p, dy, delta_eta : scalars or ``(batch,)`` story parameters
    mass : floor mass above the story [t] (enters the degradation energy, eq 8)
    dt : sample interval [s]
    velocity : drift velocity [mm/s], the shape of ``drift``: cubic Hermite path between
        samples; None: straight lines between samples
    substeps : RK4 sub-steps per sample
    state : also return the ``z`` and ``energy`` histories (False: the force only)
    collapse : None (the paper's law), or ``(8,)`` / ``(batch, 8)`` collapse gap springs
        (:meth:`hlaid.model.Building.collapse_values`): the force is then the collapse law
        (:func:`hlaid.model._equations.collapse_spring_force`) with the largest drift of each
        direction taken over the path's samples (``z`` does not depend on it)

    Returns
    -------
    PathResponse with ``(batch, time)`` arrays; starts from rest (``z = e = 0``).
    """
    x = np.atleast_2d(np.ascontiguousarray(drift, dtype=np.float64))
    hermite = velocity is not None
    v = np.atleast_2d(np.ascontiguousarray(velocity, dtype=np.float64)) if hermite else np.zeros((1, 1))
    if hermite and v.shape != x.shape:
        raise ValueError(f"velocity has shape {v.shape}; expected the drift's {x.shape}")
    pars = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (k0, alpha, p, dy,
                                                                                          delta_eta)))
    B = max(pars[0].shape[0], x.shape[0])
    k0_, al_, p_, dy_, de_ = (np.ascontiguousarray(np.broadcast_to(a, (B,))) for a in pars)
    if B % x.shape[0]:
        raise ValueError(f"{x.shape[0]} paths for {B} parameter sets; expected a number that divides {B}")
    if substeps < 1:
        raise ValueError(f"substeps = {substeps}; expected >= 1")
    T = x.shape[1]
    force = np.empty((B, T))
    z, e = (np.empty((B, T) if state else (1, 1)) for _ in range(2))
    if collapse is not None and not state:
        z, e = (np.empty((B, T)) for _ in range(2))
    _drive(x, v if hermite else np.zeros_like(x), float(dt), hermite, np.stack([k0_, al_, p_, dy_, de_]), float(mass),
           int(substeps), bool(state or collapse is not None), force, z, e)
    if collapse is not None:
        c = np.broadcast_to(np.asarray(collapse, dtype=np.float64), (B, N_COLLAPSE))[:, :, None]
        xb = x[np.arange(B) % x.shape[0]]
        xp = np.maximum.accumulate(np.maximum(xb, 0.0), axis=1)
        xn = np.maximum.accumulate(np.maximum(-xb, 0.0), axis=1)
        force = eq.collapse_spring_force(xb, z, xp, xn, al_[:, None], k0_[:, None], *(c[:, j] for j in
                                                                                      range(N_COLLAPSE)))
    return PathResponse(force=force, z=z if state else None, energy=e if state else None)
