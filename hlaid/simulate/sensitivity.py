"""Forward-mode sensitivities of a replay: the response of many nearby buildings as one replay
and its tangent.

A finite-difference Jacobian of the replay fit replays ``P + 1`` buildings that differ from the
first in one parameter each: ``P + 1`` full nonlinear replays, each spending most of its time
in the power ``|z/dy|^p`` of the hysteretic law. Within :func:`linearised`, a batch of
buildings under one motion (:func:`hlaid.simulate.simulate_response` with ``outputs="acc"``)
is instead integrated as the first building's replay plus the tangent-linear model of that
replay in the direction of every other element's difference from it (its parameters, its
damping matrix and its initial state): element ``j`` gets ``acc[0] + D acc[delta_j]``, the
first-order response, with the final state likewise. The tangent shares the replay's power,
degradation and step choices (the RK4 stages and the sub-step refinement are differentiated
as they are taken), so it costs a fraction of a replay per direction: the derivative of the
discrete replay, exact up to rounding, where the difference quotient was accurate to ``O(h)``.

Differences in the residuals built from such a batch, ``(r_j - r_0) / h``, are then the exact
directional derivatives of the residuals (any linear post-processing: band-pass, whitening,
event-to-event carried states) and :func:`hlaid.identify.refine.fit_residuals` takes its
Jacobians this way. The degrading Bouc-Wen law is smooth except where the loading switch flips
(``dx z`` changes sign) and at ``z = 0`` with ``p`` near 1, where the tangent is the one-sided
derivative of the branch the base replay is on.

Only the paper's law (no collapse model), equal masses, one motion and one scale: any other
batch is replayed in full.
"""

from __future__ import annotations

import contextlib
import contextvars

import numba as nb
import numpy as np

from ..model import equations as eq
from ._kernel import (
    _FASTMATH,
    STATUS_DIVERGED,
    STATUS_OK,
    _absolute_acc,
    _all_finite,
    coupling_bandwidth,
    damping_bandwidth,
)

ENERGY_SCALE = eq.ENERGY_SCALE

__all__ = ["linearised", "is_linearised", "integrate_tangent"]

_ACTIVE: contextvars.ContextVar[bool] = contextvars.ContextVar("hlaid_linearised_batches", default=False)

GROUP_DIRECTIONS = 12
"""At least this many directions per thread: each thread integrates its own copy of the replay
(sequential in time) beside its directions' tangents, so a second thread pays a second replay.
Measured on the Table 1 building, one thread: a replay 6 ms, with 4 / 8 / 16 / 32 tangent
directions 13 / 15 / 19 / 28 ms."""

STATUS_REFINED = 3
"""Status of a linearised batch whose replay needed a refined sample (see :func:`run_linearised`)."""


N_PAR = 6
"""Parameters with a tangent, per story: k0, alpha, p, dy, delta_eta and the P-Delta stiffness kg."""


@contextlib.contextmanager
def linearised():
    """Within: a :func:`~hlaid.simulate.simulate_response` batch of ``outputs="acc"`` under one
    motion is the first element's replay and, for every other element, the first's plus its
    tangent-linear response to the element's difference (see the module's doc). A batch the
    tangent does not cover (a collapse model, other masses, several motions or scales, a drift
    limit, the torch backend) is replayed in full as outside."""
    token = _ACTIVE.set(True)
    try:
        yield
    finally:
        _ACTIVE.reset(token)


def is_linearised() -> bool:
    """Whether :func:`linearised` is active in this context."""
    return _ACTIVE.get()


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _rhs_tangent(y, Y, ag, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, f, F, out, OUT):
    """``out = dy/dt`` at ``y`` (the arithmetic of :func:`hlaid.simulate._kernel._rhs`) and
    ``OUT[:, d]`` its derivative in direction ``d``: state ``Y[:, d]``, story parameters
    ``P[:, :, d]`` (``N_PAR``, story), damping matrix ``dC[:, :, d]`` and coupling ``dKc[:, :, d]``
    (``Kc`` zero beyond its band ``bwc``, -1: none). ``f`` ``(n,)`` and ``F``
    ``(n, D)`` are scratch (the spring forces and their tangents); ``haslog[i]``: some direction
    moves story ``i``'s ``p`` (the log of the power is then needed). The loops over the
    directions hold no branch (the story's coefficients are formed first), so they vectorise."""
    _story_tangent(y, Y, n, D, m, k0, al, p, dy, de, kg, P, haslog, f, F, out, OUT)
    _floor_tangent(y, Y, ag, n, D, m, C, bw, Kc, bwc, dC, dKc, f, F, out, OUT)


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _story_tangent(y, Y, n, D, m, k0, al, p, dy, de, kg, P, haslog, f, F, out, OUT):
    """The story springs' part of :func:`_rhs_tangent`: each story's Bouc-Wen rates and their
    tangents into ``out``/``OUT``, its spring force and tangent into ``f``/``F``."""
    u_below = 0.0
    v_below = 0.0
    for i in range(n):
        u = y[i]
        v = y[n + i]
        z = y[2 * n + i]
        e = y[3 * n + i]
        x = u - u_below
        xd = v - v_below
        ai, ki, mi, di, pi, yi = al[i], k0[i], m[i], de[i], p[i], dy[i]
        c = ENERGY_SCALE * (1.0 - ai) * (ki / mi)
        eta = 1.0 + di * (c * e)
        s = xd * z
        loading = 0.5 * ((s > 0.0) * 1.0 - (s < 0.0) * 1.0 + 1.0)
        w = loading * abs(z / yi)
        q = w ** pi
        rate = xd * (1.0 - q) / eta
        out[2 * n + i] = rate
        out[3 * n + i] = z * xd
        f[i] = ai * ki * x + (1.0 - ai) * ki * z - kg[i] * x
        out[i] = v
        # the tangent, linear in (dx, dxd, dz, de, dk0, dalpha, dp, ddy, ddelta_eta, dkg) with these
        # coefficients: d eta, d q (w > 0 only: on unloading q is 0 whatever moves), d rate, d f
        ieta = 1.0 / eta
        ce = ENERGY_SCALE * e / mi
        e_de, e_da, e_dk, e_e = (1.0 - ai) * ki * ce, -di * ki * ce, di * (1.0 - ai) * ce, di * c
        if w > 0.0:
            q_p = q * np.log(w) if haslog[i] else 0.0
            q_z = q * pi / z
            q_y = -q * pi / yi
        else:
            q_p = 0.0
            q_z = 0.0
            q_y = 0.0
        r_xd = (1.0 - q) * ieta
        r_q = -xd * ieta
        r_eta = -rate * ieta
        f_da, f_dk, f_dx, f_dz = (x - z) * ki, ai * x + (1.0 - ai) * z, ai * ki - kg[i], (1.0 - ai) * ki
        sb = 1.0 if i > 0 else 0.0
        im = max(i - 1, 0)
        for d in range(D):
            dx = Y[i, d] - sb * Y[im, d]
            dxd = Y[n + i, d] - sb * Y[n + im, d]
            dz = Y[2 * n + i, d]
            deta = e_de * P[4, i, d] + e_da * P[1, i, d] + e_dk * P[0, i, d] + e_e * Y[3 * n + i, d]
            dq = q_p * P[2, i, d] + q_z * dz + q_y * P[3, i, d]
            OUT[2 * n + i, d] = r_xd * dxd + r_q * dq + r_eta * deta
            OUT[3 * n + i, d] = xd * dz + z * dxd
            F[i, d] = f_da * P[1, i, d] + f_dk * P[0, i, d] + f_dx * dx + f_dz * dz - x * P[5, i, d]
            OUT[i, d] = Y[n + i, d]
        u_below = u
        v_below = v


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _floor_tangent(y, Y, ag, n, D, m, C, bw, Kc, bwc, dC, dKc, f, F, out, OUT):
    """The floors' part of :func:`_rhs_tangent`: each floor's acceleration from the story forces
    ``f``, the damping ``C`` and the coupling ``Kc``, and its tangent from ``F``, ``dC``, ``dKc``."""
    for j in range(n):
        fd = 0.0
        lo, hi = max(0, j - bw), min(n, j + bw + 1)
        for k in range(lo, hi):
            fd += C[j, k] * y[n + k]
        lc, hc = max(0, j - bwc), min(n, j + bwc + 1)
        for k in range(lc, hc):
            fd += Kc[j, k] * y[k]
        f_above = f[j + 1] if j + 1 < n else 0.0
        out[n + j] = -(f[j] - f_above + fd) / m[j] - ag
        sa = 1.0 if j + 1 < n else 0.0
        ja = min(j + 1, n - 1)
        im = -1.0 / m[j]
        for d in range(D):
            OUT[n + j, d] = F[j, d] - sa * F[ja, d]
        for k in range(lo, hi):
            cjk = C[j, k]
            vk = y[n + k]
            for d in range(D):
                OUT[n + j, d] += cjk * Y[n + k, d] + dC[j, k, d] * vk
        for k in range(lc, hc):
            kjk = Kc[j, k]
            uk = y[k]
            for d in range(D):
                OUT[n + j, d] += kjk * Y[k, d] + dKc[j, k, d] * uk
        for d in range(D):
            OUT[n + j, d] *= im


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _acc_tangent(y, Y, n, D, m, k0, al, kg, C, bw, Kc, bwc, P, dC, dKc, F, dacc):
    """``dacc[:, d]`` ``(n, D)``: the tangent of the absolute floor accelerations
    (:func:`hlaid.simulate._kernel._absolute_acc`) at state ``y`` in direction ``d``."""
    u_below = 0.0
    for i in range(n):
        x = y[i] - u_below
        z = y[2 * n + i]
        ai, ki = al[i], k0[i]
        f_da, f_dk, f_dx, f_dz = (x - z) * ki, ai * x + (1.0 - ai) * z, ai * ki - kg[i], (1.0 - ai) * ki
        sb = 1.0 if i > 0 else 0.0
        im = max(i - 1, 0)
        for d in range(D):
            dx = Y[i, d] - sb * Y[im, d]
            F[i, d] = f_da * P[1, i, d] + f_dk * P[0, i, d] + f_dx * dx + f_dz * Y[2 * n + i, d] - x * P[5, i, d]
        u_below = y[i]
    for j in range(n):
        lo, hi = max(0, j - bw), min(n, j + bw + 1)
        sa = 1.0 if j + 1 < n else 0.0
        ja = min(j + 1, n - 1)
        im = -1.0 / m[j]
        for d in range(D):
            dacc[j, d] = F[j, d] - sa * F[ja, d]
        for k in range(lo, hi):
            cjk = C[j, k]
            vk = y[n + k]
            for d in range(D):
                dacc[j, d] += cjk * Y[n + k, d] + dC[j, k, d] * vk
        for k in range(max(0, j - bwc), min(n, j + bwc + 1)):
            kjk = Kc[j, k]
            uk = y[k]
            for d in range(D):
                dacc[j, d] += kjk * Y[k, d] + dKc[j, k, d] * uk
        for d in range(D):
            dacc[j, d] *= im


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _rk4_tangent(y, Y, hs, g0, gm, g1, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, work):
    """One RK4 step ``hs`` of the replay ``y`` ``(4*story,)`` and its tangent ``Y`` ``(4*story, D)``,
    in place, under ground ``g0`` / ``gm`` / ``g1`` at the step's start / middle / end."""
    f, F, yt, Yt, k1, k2, k3, k4, K1, K2, K3, K4 = work
    S = 4 * n
    _rhs_tangent(y, Y, g0, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, f, F, k1, K1)
    for j in range(S):
        yt[j] = y[j] + 0.5 * hs * k1[j]
        for d in range(D):
            Yt[j, d] = Y[j, d] + 0.5 * hs * K1[j, d]
    _rhs_tangent(yt, Yt, gm, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, f, F, k2, K2)
    for j in range(S):
        yt[j] = y[j] + 0.5 * hs * k2[j]
        for d in range(D):
            Yt[j, d] = Y[j, d] + 0.5 * hs * K2[j, d]
    _rhs_tangent(yt, Yt, gm, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, f, F, k3, K3)
    for j in range(S):
        yt[j] = y[j] + hs * k3[j]
        for d in range(D):
            Yt[j, d] = Y[j, d] + hs * K3[j, d]
    _rhs_tangent(yt, Yt, g1, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, f, F, k4, K4)
    for j in range(S):
        y[j] = y[j] + hs / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        for d in range(D):
            Y[j, d] = Y[j, d] + hs / 6.0 * (K1[j, d] + 2.0 * K2[j, d] + 2.0 * K3[j, d] + K4[j, d])


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _sample_tangent(y, Y, y_prev, Y_prev, lo, dg, dt, nsub, refine, n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc,
                    P, dC, dKc, haslog, work):
    """One record sample (ground ``lo`` to ``lo + dg``) of the replay and its tangent with ``nsub``
    sub-steps, redone with 2x ... 16x as many where ``|z|`` overshoots ``dy`` (as
    :func:`hlaid.simulate._kernel.integrate` does). Returns :data:`STATUS_OK`, or
    :data:`STATUS_REFINED` where the sample needs refining and ``refine`` is False."""
    S = 4 * n
    for j in range(S):
        y_prev[j] = y[j]
        for d in range(D):
            Y_prev[j, d] = Y[j, d]
    ns = nsub
    while True:
        hs = dt / ns
        for s in range(ns):
            _rk4_tangent(y, Y, hs, lo + dg * (s / ns), lo + dg * ((s + 0.5) / ns), lo + dg * ((s + 1.0) / ns),
                         n, D, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, haslog, work)
        bad = False
        for i in range(n):
            if not (abs(y[2 * n + i]) <= dy[i] * (1.0 + 1e-5)):
                bad = True
        if bad and not refine:  # the sample needs finer sub-steps: the caller replays in full
            return STATUS_REFINED
        if not bad or ns >= 16 * nsub:
            return STATUS_OK
        for j in range(S):
            y[j] = y_prev[j]
            for d in range(D):
                Y[j, d] = Y_prev[j, d]
        ns *= 2


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _record_tangent(k, y, Y, a, da, n, D, d0, base, ok, acc, peak_drift, peak_acc):
    """Write sample ``k`` of the replay (where ``base``) and of its ``D`` directions from ``d0`` into
    the outputs; the peaks start at sample 0. A non-finite acceleration marks its direction not ``ok``."""
    for i in range(n):
        xb = y[i] - (y[i - 1] if i > 0 else 0.0)
        if base:
            acc[0, k, i] = a[i]
            if k == 0 or abs(xb) > peak_drift[0, i]:
                peak_drift[0, i] = abs(xb)
            if k == 0 or abs(a[i]) > peak_acc[0, i]:
                peak_acc[0, i] = abs(a[i])
        for d in range(D):
            ad = a[i] + da[i, d]
            acc[1 + d0 + d, k, i] = ad
            x = xb + Y[i, d] - (Y[i - 1, d] if i > 0 else 0.0)
            if k == 0 or abs(x) > peak_drift[1 + d0 + d, i]:
                peak_drift[1 + d0 + d, i] = abs(x)
            if k == 0 or abs(ad) > peak_acc[1 + d0 + d, i]:
                peak_acc[1 + d0 + d, i] = abs(ad)
            if k > 0 and not np.isfinite(ad):
                ok[d] = False


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _finish_tangent(k, T, st, y, Y, n, D, d0, base, ok, acc, final, n_done, status):
    """After the last sample ``k`` done: NaN accelerations beyond it, the final states, samples
    done and status of the replay (where ``base``) and of the ``D`` directions from ``d0``."""
    S = 4 * n
    for kk in range(k + 1, T):
        for i in range(n):
            if base:
                acc[0, kk, i] = np.nan
            for d in range(D):
                acc[1 + d0 + d, kk, i] = np.nan
    if base:
        for j in range(S):
            final[0, j] = y[j]
        status[0] = st
        n_done[0] = k + 1
    for d in range(D):
        n_done[1 + d0 + d] = k + 1
        for j in range(S):
            final[1 + d0 + d, j] = y[j] + Y[j, d]
            if not np.isfinite(Y[j, d]):
                ok[d] = False
        status[1 + d0 + d] = st if ok[d] else STATUS_DIVERGED


@nb.njit(cache=True, parallel=True, fastmath=_FASTMATH, error_model="numpy")
def integrate_tangent(g, dt, T, nsub, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, P, dC, dKc, y0, Y0, groups, refine,
                      acc, final, peak_drift, peak_acc, n_done, status):  # pragma: no cover (compiled)
    """The replay of one building and its tangent in ``D`` directions; see the module's doc.

    Parameters
    ----------
    g : (time,) ground acceleration [mm/s^2] (scaled); dt : sample interval; T : samples
    nsub : RK4 sub-steps per sample, refined per sample as :func:`hlaid.simulate._kernel.integrate` does
    m, k0, al, p, dy, de, kg : (story,) the building; C : (story, story) its damping matrix;
        bw : the band of ``C`` and of every ``dC``
    P : (N_PAR, story, D) parameter directions (k0, alpha, p, dy, delta_eta, kg); dC : (story,
        story, D) damping directions; Kc : (story, story) the linear coupling, bwc its band (-1:
        none, in no direction), dKc : (story, story, D) its directions; y0 : (4*story,) initial
        state; Y0 : (4*story, D) its directions
    groups : (G + 1,) direction bounds of the G groups that run in parallel, each with its own
        copy of the replay (the replay is sequential in time; its copies cost less than a second
        core left idle)
    refine : a sample whose step lets |z| overshoot dy is redone with 2x ... 16x the sub-steps, its
        tangent with it, as :func:`hlaid.simulate._kernel.integrate` does; False: the replay stops
        there with status :data:`STATUS_REFINED` (see :func:`run_linearised`)

    Outputs (element 0 the replay, element ``1 + d`` the replay plus direction ``d``'s tangent):
    acc (1 + D, time, story) (NaN after a diverged replay's end), final (1 + D, 4*story),
    peak_drift, peak_acc (1 + D, story), n_done, status (1 + D,)
    """
    n = m.shape[0]
    S = 4 * n
    G = groups.shape[0] - 1
    haslog = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        for d in range(P.shape[2]):
            if P[2, i, d] != 0.0:
                haslog[i] = True
    for gi in nb.prange(G):
        d0 = groups[gi]
        D = groups[gi + 1] - d0
        Pg = np.ascontiguousarray(P[:, :, d0:d0 + D])
        dCg = np.ascontiguousarray(dC[:, :, d0:d0 + D])
        dKcg = np.ascontiguousarray(dKc[:, :, d0:d0 + D])
        y = y0.copy()
        Y = np.ascontiguousarray(Y0[:, d0:d0 + D])
        y_prev = np.empty(S)
        Y_prev = np.empty((S, D))
        work = (np.empty(n), np.empty((n, D)), np.empty(S), np.empty((S, D)), np.empty(S), np.empty(S),
                np.empty(S), np.empty(S), np.empty((S, D)), np.empty((S, D)), np.empty((S, D)), np.empty((S, D)))
        f, F = work[0], work[1]
        a = np.empty(n)
        da = np.empty((n, D))
        ok = np.ones(D, dtype=np.bool_)
        _absolute_acc(y, n, m, al, k0, kg, C, bw, Kc, bwc, f, a)
        _acc_tangent(y, Y, n, D, m, k0, al, kg, C, bw, Kc, bwc, Pg, dCg, dKcg, F, da)
        _record_tangent(0, y, Y, a, da, n, D, d0, gi == 0, ok, acc, peak_drift, peak_acc)
        st = STATUS_OK
        k = 0
        while k < T - 1:
            st = _sample_tangent(y, Y, y_prev, Y_prev, g[k], g[k + 1] - g[k], dt, nsub, refine, n, D, m, k0, al,
                                 p, dy, de, kg, C, bw, Kc, bwc, Pg, dCg, dKcg, haslog, work)
            if st == STATUS_REFINED:
                break
            k += 1
            _absolute_acc(y, n, m, al, k0, kg, C, bw, Kc, bwc, f, a)
            _acc_tangent(y, Y, n, D, m, k0, al, kg, C, bw, Kc, bwc, Pg, dCg, dKcg, F, da)
            if not _all_finite(y):
                st = STATUS_DIVERGED
                break
            _record_tangent(k, y, Y, a, da, n, D, d0, gi == 0, ok, acc, peak_drift, peak_acc)
        _finish_tangent(k, T, st, y, Y, n, D, d0, gi == 0, ok, acc, final, n_done, status)


def run_linearised(P: dict, g: np.ndarray, dt: float, nsub: int, y0: np.ndarray, n_threads: int | None = None,
                   refine: bool = False):
    """The batch of parameter arrays ``P`` (:meth:`~hlaid.model.BuildingTensors.numpy`, element 0
    the base) under ground ``g`` ``(time,)`` from ``y0`` ``(batch, 4*story)``: the base's replay
    and every other element's first-order response. Returns ``acc, final, peak_drift, peak_acc,
    n_done, status`` as :func:`integrate_tangent` writes them.

    ``refine`` False (the default): where the replay needs a refined sample (``|z|`` overshooting
    ``dy`` within a step: a yield displacement small against the drift increments of a sample),
    it stops and every status is :data:`STATUS_REFINED`; the caller then replays the batch in
    full. There the discrete replay jumps where a perturbed building refines other samples than
    the base: the difference quotient of full replays holds those jumps and the tangent does not,
    and a search steered by one or the other goes elsewhere (the steel frame's joint fit of three
    events: to another mode of its posterior). Elsewhere the two agree to the quotient's O(h)."""
    B, n = P["mass"].shape
    D = B - 1
    S = 4 * n
    T = g.shape[0]
    base = {k: np.ascontiguousarray(v[0]) for k, v in P.items() if k != "collapse"}
    dirs = np.zeros((N_PAR, n, D))
    for r, name in enumerate(("k0", "alpha", "p", "dy", "delta_eta", "kg")):
        dirs[r] = (P[name][1:] - P[name][0]).T
    dC = np.ascontiguousarray((P["damping"][1:] - P["damping"][0]).transpose(1, 2, 0))
    bw = int(damping_bandwidth(P["damping"]).max(initial=0))
    dKc = np.ascontiguousarray((P["coupling"][1:] - P["coupling"][0]).transpose(1, 2, 0))
    bwc = int(coupling_bandwidth(P["coupling"]).max(initial=-1))
    Y0 = np.ascontiguousarray((y0[1:] - y0[0]).T)
    G = max(1, min(D // GROUP_DIRECTIONS, int(n_threads if n_threads is not None else nb.get_num_threads())))
    groups = np.linspace(0, D, G + 1).round().astype(np.int64)
    acc = np.empty((B, T, n))
    final = np.empty((B, S))
    peak_drift, peak_acc = np.zeros((B, n)), np.zeros((B, n))
    status = np.zeros(B, dtype=np.int64)
    n_done = np.zeros(B, dtype=np.int64)
    integrate_tangent(np.ascontiguousarray(g, dtype=np.float64), float(dt), int(T), int(nsub), base["mass"],
                      base["k0"], base["alpha"], base["p"], base["dy"], base["delta_eta"], base["kg"],
                      np.ascontiguousarray(base["damping"]), bw, np.ascontiguousarray(base["coupling"]), bwc, dirs, dC,
                      dKc, np.ascontiguousarray(y0[0]), Y0, groups,
                      bool(refine), acc, final, peak_drift, peak_acc, n_done, status)
    if np.any(status == STATUS_REFINED):
        status[:] = STATUS_REFINED
    return acc, final, peak_drift, peak_acc, n_done, status


def covers(P: dict, n_motions: int, sc: np.ndarray, bi: np.ndarray, stop: np.ndarray, S: int) -> bool:
    """Whether a batch can be linearised: two or more buildings of the paper's law and equal masses,
    each once under one motion at one scale, no drift limit."""
    n = P["mass"].shape[1]
    return (n_motions == 1 and bi.size >= 2 and S == 4 * n and np.array_equal(bi, np.arange(bi.size))
            and bool(np.all(sc == sc[0])) and bool(np.all(np.isinf(stop)))
            and bool(np.all(P["mass"] == P["mass"][0])))
