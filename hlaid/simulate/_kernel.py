"""Compiled (numba) fixed-step RK4 integrator of the shear building, batched and parallel.

The hysteretic law is not re-written here: the functions of
:mod:`hlaid.model._equations` are compiled as they are. The structural assembly mirrors
:meth:`hlaid.model.BoucWenBuilding.rates` loop by loop, and a test holds the two to 1e-8.

With a collapse model the state carries the memory ``[xp, xn]`` (``6*story`` wide, see
BoucWenBuilding); the gap springs' force is then added to the rates computed as without it
(:func:`_add_collapse`), so the paper's law runs the very code it ran before.

Each batch element ``b`` integrates building ``bi[b]`` under motion ``mi[b]`` scaled by
``sc[b]``; elements run in parallel (``prange``).
"""

from __future__ import annotations

import types

import numba as nb
import numpy as np

from ..model import equations as eq

# fused multiply-add and reciprocal multiplication only (no 'nnan'/'ninf': the divergence check
# needs isfinite): results move by a few ulps (tested to 1e-8 against the torch module), ~20 %
# faster (scripts/bench_simulator.py)
_FASTMATH = {"contract", "arcp"}
_jit = nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
_degradation = _jit(eq.degradation)
_hysteretic_rate = _jit(eq.hysteretic_rate)
_spring_force = _jit(eq.spring_force)


def _jit_composed(names):
    """Compile functions of ``_equations`` that call each other: each is compiled with the
    already compiled ones as its globals (the source stays the one in ``_equations``)."""
    done = {}
    for name in names:
        fn = getattr(eq, name)
        done[name] = _jit(types.FunctionType(fn.__code__, {**vars(eq), **done}, fn.__name__, fn.__defaults__))
    return done


_c = _jit_composed(("_pos", "gap_offset", "gap_force", "peak_rate"))
_gap_force, _peak_rate = _c["gap_force"], _c["peak_rate"]

STATUS_OK, STATUS_DRIFT_LIMIT, STATUS_DIVERGED = 0, 1, 2

COLLAPSE = False
"""Whether a compiled :func:`integrate` runs the collapse law; frozen per specialisation (below)."""


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _rhs(y, ag, n, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, f, out):
    """``out = dy/dt`` for one building; ``f`` is scratch ``(n,)``; ``C`` is zero beyond ``bw``
    off its diagonal (see :func:`damping_bandwidth`), the coupling ``Kc`` beyond ``bwc`` (-1: no
    coupling, none of its arithmetic). See BoucWenBuilding.rates."""
    u_below = 0.0
    v_below = 0.0
    for i in range(n):
        u = y[i]
        v = y[n + i]
        z = y[2 * n + i]
        x = u - u_below
        xd = v - v_below
        eta = _degradation(y[3 * n + i], al[i], k0[i], m[i], de[i])
        out[2 * n + i] = _hysteretic_rate(xd, z, dy[i], p[i], eta)
        out[3 * n + i] = z * xd
        f[i] = _spring_force(x, z, al[i], k0[i]) - kg[i] * x
        out[i] = v
        u_below = u
        v_below = v
    for j in range(n):
        fd = 0.0
        for k in range(max(0, j - bw), min(n, j + bw + 1)):
            fd += C[j, k] * y[n + k]
        for k in range(max(0, j - bwc), min(n, j + bwc + 1)):
            fd += Kc[j, k] * y[k]
        f_above = f[j + 1] if j + 1 < n else 0.0
        out[n + j] = -(f[j] - f_above + fd) / m[j] - ag


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _all_finite(y):
    """Whether every entry of the state ``y`` is finite (a replay that is not has diverged)."""
    for j in range(y.shape[0]):
        if not np.isfinite(y[j]):
            return False
    return True


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _absolute_acc(y, n, m, al, k0, kg, C, bw, Kc, bwc, f, acc):
    """Absolute floor accelerations ``-(R + K_c u + C v)/m`` at state ``y``."""
    u_below = 0.0
    for i in range(n):
        x = y[i] - u_below
        f[i] = _spring_force(x, y[2 * n + i], al[i], k0[i]) - kg[i] * x
        u_below = y[i]
    for j in range(n):
        fd = 0.0
        for k in range(max(0, j - bw), min(n, j + bw + 1)):
            fd += C[j, k] * y[n + k]
        for k in range(max(0, j - bwc), min(n, j + bwc + 1)):
            fd += Kc[j, k] * y[k]
        f_above = f[j + 1] if j + 1 < n else 0.0
        acc[j] = -(f[j] - f_above + fd) / m[j]


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _add_collapse(y, n, m, cp, g, out, rates):
    """Add the gap springs of the collapse law (``cp`` ``(n, 8)``) to the floor accelerations
    ``out[a:a+n]`` (``a = n`` for rates, 0 for absolute accelerations); with ``rates`` also write
    the memory rates ``out[4n:6n]``. ``g`` is scratch ``(n,)``."""
    u_below = 0.0
    v_below = 0.0
    for i in range(n):
        x = y[i] - u_below
        g[i] = _gap_force(x, y[4 * n + i], y[5 * n + i], cp[i, 0], cp[i, 1], cp[i, 2], cp[i, 3], cp[i, 4],
                          cp[i, 5], cp[i, 6], cp[i, 7])
        if rates:
            xd = y[n + i] - v_below
            out[4 * n + i] = _peak_rate(x, xd, y[4 * n + i])
            out[5 * n + i] = _peak_rate(-x, -xd, y[5 * n + i])
            v_below = y[n + i]
        u_below = y[i]
    a = n if rates else 0
    for j in range(n):
        g_above = g[j + 1] if j + 1 < n else 0.0
        out[a + j] -= (g[j] - g_above) / m[j]


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy")
def _update_peaks(y, n):
    """Collapse memory after a step: ``xp = max(xp, x)``, ``xn = max(xn, -x)`` (exact running peaks)."""
    u_below = 0.0
    for i in range(n):
        x = y[i] - u_below
        if x > y[4 * n + i]:
            y[4 * n + i] = x
        if -x > y[5 * n + i]:
            y[5 * n + i] = -x
        u_below = y[i]


def damping_bandwidth(C: np.ndarray) -> np.ndarray:
    """``(building,)`` largest ``|j - k|`` with ``C[b, j, k] != 0`` for ``C`` of shape
    ``(building, story, story)`` (0 for a zero or diagonal matrix). Leaving out exact zeros
    changes no sum: ``fd + 0.0 * v`` is ``fd``."""
    C = np.asarray(C)
    n = C.shape[-1]
    off = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    return np.where(C != 0.0, off[None], 0).reshape(C.shape[0], -1).max(axis=1, initial=0).astype(np.int64)


def coupling_bandwidth(Kc: np.ndarray) -> np.ndarray:
    """``(building,)`` the band of each coupling matrix ``Kc`` ``(building, story, story)`` as
    :func:`damping_bandwidth`, and -1 for a zero matrix (no coupling: the kernel skips it, and
    a shear chain runs the arithmetic it ran before, bit for bit)."""
    Kc = np.asarray(Kc)
    band = damping_bandwidth(Kc)
    return np.where(np.any(Kc.reshape(Kc.shape[0], -1) != 0.0, axis=1), band, -1).astype(np.int64)


def integrate(ag, dt, nt, mi, bi, sc, nsub, m, k0, al, p, dy, de, kg, C, bw, Kc, bwc, cpar, y0, stop_drift,
              save, states, save_acc, acc_hist, peak_drift, peak_acc, final, n_done, status):
    """Integrate every batch element; results are written into the output arrays.

    Parameters
    ----------
    ag : (motion, time) ground accelerations [mm/s^2], zero-padded
    dt : (motion,) sample intervals; nt : (motion,) samples to integrate
    mi, bi : (batch,) motion and building index of each element; sc : (batch,) scale factor
    nsub : RK4 sub-steps per sample; a sample whose step lets |z| overshoot dy (or the
        state blow up) is redone with 2x, 4x, ... up to 16x the sub-steps
    m, k0, al, p, dy, de, kg : (building, story) parameters; C : (building, story, story)
    bw : (building,) bandwidth of ``C`` (:func:`damping_bandwidth`): the damping force sums
        only the band (3 products per floor for a shear building's tridiagonal C instead of n),
        bit for bit the full product's values
    Kc : (building, story, story) linear coupling (:mod:`hlaid.model.coupling`); bwc : (building,)
        its band, -1 where it is zero (:func:`coupling_bandwidth`)
    cpar : (building, story, 8) collapse gap springs ``x1, dk1, ..., x4, dk4`` (hlaid.model.collapse),
        used when the state has the collapse memory
    y0 : (batch, 4*story) initial states, or (batch, 6*story) with the collapse memory
        ``[xp, xn]`` (largest past drift per direction), which switches the collapse law on
    stop_drift : (batch, story) |drift| [mm] at which an element stops (inf: never)
    save : write the state at every sample into ``states`` (batch, time, 4*story)
    save_acc : write the absolute floor acceleration at every sample into ``acc_hist``
        (batch, time, story), NaN after the element's end (the replay's only output)
    peak_drift, peak_acc : (batch, story) outputs; final : (batch, 4*story) last state
    n_done : (batch,) samples integrated; status : (batch,) 0 ok, 1 drift limit, 2 diverged
    """
    B = mi.shape[0]
    n = m.shape[1]
    col = COLLAPSE  # a compile-time constant: see _specialise
    S = (6 if col else 4) * n
    for b in nb.prange(B):
        g = ag[mi[b]]
        s_b = sc[b]
        w = bi[b]
        mb, k0b, alb, pb, dyb, deb, kgb, Cb, bwb = m[w], k0[w], al[w], p[w], dy[w], de[w], kg[w], C[w], bw[w]
        Kcb, bwcb = Kc[w], bwc[w]
        y = y0[b].copy()
        y_prev = np.empty(S)
        yt = np.empty(S)
        k1 = np.empty(S)
        k2 = np.empty(S)
        k3 = np.empty(S)
        k4 = np.empty(S)
        f = np.empty(n)
        acc = np.empty(n)
        cpb = cpar[w]
        T = nt[mi[b]]
        if save:
            states[b, 0, :] = y
        _absolute_acc(y, n, mb, alb, k0b, kgb, Cb, bwb, Kcb, bwcb, f, acc)
        if col:
            _add_collapse(y, n, mb, cpb, f, acc, False)
        if save_acc:
            for i in range(n):
                acc_hist[b, 0, i] = acc[i]
        for i in range(n):
            peak_acc[b, i] = abs(acc[i])
            peak_drift[b, i] = abs(y[i] - (y[i - 1] if i > 0 else 0.0))
        st = STATUS_OK
        k = 0
        while k < T - 1:
            lo = g[k] * s_b
            da = g[k + 1] * s_b - lo
            for j in range(S):
                y_prev[j] = y[j]
            ns = nsub
            while True:
                hs = dt[mi[b]] / ns
                for s in range(ns):
                    g0 = lo + da * (s / ns)
                    gm = lo + da * ((s + 0.5) / ns)
                    g1 = lo + da * ((s + 1.0) / ns)
                    _rhs(y, g0, n, mb, k0b, alb, pb, dyb, deb, kgb, Cb, bwb, Kcb, bwcb, f, k1)
                    if col:
                        _add_collapse(y, n, mb, cpb, f, k1, True)
                    for j in range(S):
                        yt[j] = y[j] + 0.5 * hs * k1[j]
                    _rhs(yt, gm, n, mb, k0b, alb, pb, dyb, deb, kgb, Cb, bwb, Kcb, bwcb, f, k2)
                    if col:
                        _add_collapse(yt, n, mb, cpb, f, k2, True)
                    for j in range(S):
                        yt[j] = y[j] + 0.5 * hs * k2[j]
                    _rhs(yt, gm, n, mb, k0b, alb, pb, dyb, deb, kgb, Cb, bwb, Kcb, bwcb, f, k3)
                    if col:
                        _add_collapse(yt, n, mb, cpb, f, k3, True)
                    for j in range(S):
                        yt[j] = y[j] + hs * k3[j]
                    _rhs(yt, g1, n, mb, k0b, alb, pb, dyb, deb, kgb, Cb, bwb, Kcb, bwcb, f, k4)
                    if col:
                        _add_collapse(yt, n, mb, cpb, f, k4, True)
                    for j in range(S):
                        y[j] = y[j] + hs / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
                    if col:
                        _update_peaks(y, n)
                # the step was too long if z overshot the yield surface or the state blew up:
                # redo this sample with twice the sub-steps (up to 16x)
                bad = False
                for i in range(n):
                    zi = y[2 * n + i]
                    if not (abs(zi) <= dyb[i] * (1.0 + 1e-5)):
                        bad = True
                if not bad or ns >= 16 * nsub:
                    break
                for j in range(S):
                    y[j] = y_prev[j]
                ns *= 2
            k += 1
            if save:
                states[b, k, :] = y
            _absolute_acc(y, n, mb, alb, k0b, kgb, Cb, bwb, Kcb, bwcb, f, acc)
            if col:
                _add_collapse(y, n, mb, cpb, f, acc, False)
            if save_acc:
                for i in range(n):
                    acc_hist[b, k, i] = acc[i]
            if not _all_finite(y):
                st = STATUS_DIVERGED
                break
            for i in range(n):
                x = abs(y[i] - (y[i - 1] if i > 0 else 0.0))
                if x > peak_drift[b, i]:
                    peak_drift[b, i] = x
                if abs(acc[i]) > peak_acc[b, i]:
                    peak_acc[b, i] = abs(acc[i])
                if x > stop_drift[b, i]:
                    st = STATUS_DRIFT_LIMIT
            if st != STATUS_OK:
                break
        if save:
            for kk in range(k + 1, states.shape[1]):
                for j in range(S):
                    states[b, kk, j] = np.nan
        if save_acc:
            for kk in range(k + 1, acc_hist.shape[1]):
                for i in range(n):
                    acc_hist[b, kk, i] = np.nan
        final[b, :] = y
        n_done[b] = k + 1
        status[b] = st


def _specialise(fn, collapse: bool, name: str):
    """``fn`` compiled with the global ``COLLAPSE`` frozen to ``collapse``: the paper's law
    (False) compiles without any collapse code, exactly the kernel it was before."""
    g = dict(globals())
    g["COLLAPSE"] = collapse
    f = types.FunctionType(fn.__code__, g, name, fn.__defaults__)
    f.__qualname__ = name
    f.__doc__ = fn.__doc__
    return nb.njit(cache=True, parallel=True, fastmath=_FASTMATH, error_model="numpy")(f)


_integrate_source = integrate
integrate = _specialise(_integrate_source, False, "integrate")
"""Integrate a batch with the paper's law (``4*story`` states); see the source function's doc."""
integrate_collapse = _specialise(_integrate_source, True, "integrate_collapse")
"""The same with the collapse law (``6*story`` states with the memory ``[xp, xn]``)."""
