"""Compiled (numba) dual solver for batches of binary C-SVC problems, libsvm's algorithm.

Each problem is libsvm's ``Solver::Solve`` for a C-SVC (Fan, Chen & Lin 2005), ported step
by step so that it takes libsvm's iterations and reaches libsvm's solution:

* the dual ``min 1/2 a'Qa - e'a``, ``0 <= a <= C``, ``y'a = 0``, ``Q_ij = y_i y_j K_ij``,
  gradient ``G = Qa - e``, started from ``a = 0``;
* working set by second-order selection (WSS 2): ``i`` maximises ``-y_i G_i`` over
  ``I_up``, ``j`` minimises ``-(m - (-y_j G_j))^2 / a_ij`` over ``I_low``, ``a_ij = K_ii +
  K_jj - 2 K_ij`` (``tau = 1e-12`` where not positive), ties to the last position as libsvm;
* libsvm's analytic two-variable update with its clipping, the gradient update over the
  active variables, ``G_bar`` (the gradient part of the variables at ``C``) updated when a
  variable reaches or leaves ``C``;
* shrinking every ``min(l, 1000)`` iterations (``l`` variables) with libsvm's rule, its index
  swaps and its one-time unshrink when the gap is below ``10 eps``; before stopping, the
  gradient of the shrunk variables is reconstructed and optimality checked again on all of
  them (libsvm's stopping rule ``m - M < eps`` on the full problem);
* ``rho`` as ``calculate_rho`` and the objective as libsvm's ``obj``.

The arithmetic is libsvm's, operation for operation (no contraction into fused
multiply-adds; the state is kept as ``F = -y G``, which differs from ``G`` by exact sign
changes only), and kernel rows are stored in float32 as libsvm's ``Qfloat``: the iterates
round as libsvm's do. Kernel values are computed in float64 with libsvm's formulas, from a
fit's Gram matrix (many features, see :mod:`hlaid.svm._batch`) or from the samples (one
``axpy`` per feature, then a vectorised ``exp``), whole rows on first use, kept in a
least-recently-used cache per problem.

Speed comes from the layout, not from fewer iterations: the scans (selection of ``i`` and
``j``, gradient update and next ``m``) are loops that LLVM vectorises (max / min reductions
through ``llvm.maximum`` / ``llvm.minimum``, contiguous rows until the first shrinking swap),
and the iteration is written out in one function (see :func:`_solve_one`).

A batch holds many problems (the one-vs-one pairs of several multi-class fits, with their
own ``C`` and kernel parameters): :func:`solve_batch` runs them in parallel over numba's
threads (``prange`` over problems, largest first, one at a time per thread), or one after
the other.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["P_FLT", "P_INT", "R_FLT", "R_INT", "solve_batch"]

# the kernel rows: fused multiply-add and reciprocal multiplication, as the simulator's kernels
# (the rows are stored in float32, as libsvm's); the solver's steps: plain IEEE arithmetic in
# libsvm's order (no contraction), so that they round as libsvm's do
_jit_fast = nb.njit(cache=True, fastmath={"contract", "arcp"}, error_model="numpy")
_jit = nb.njit(cache=True, error_model="numpy")
# small helpers inlined into the solver (numba IR); those of the iteration take scalars only:
# passing an array, even to an inlined function, costs atomic reference count updates
_jit_inline = nb.njit(cache=True, error_model="numpy", inline="always")

#: Columns of the integer problem table: offsets and sizes of the two classes' samples in
#: ``Xt``, kernel code, degree, iteration cap, shrinking (0/1), offset of the output, bytes
#: of kernel rows the problem may cache (float32 rows; at least two whatever it says), and
#: the fit's Gram matrix: its offset in ``gram`` (-1: none), the fit's first column in ``Xt``
#: and its number of samples.
P_INT = ("start_pos", "n_pos", "start_neg", "n_neg", "kernel", "degree", "max_iter", "shrinking", "out",
         "cache", "gram", "gram_base", "gram_n")
#: Columns of the float problem table.
P_FLT = ("C", "gamma", "coef0", "eps")
#: Columns of the float results: ``rho``, dual objective, final gap ``m - M``.
R_FLT = ("rho", "objective", "gap")
#: Columns of the integer results: iterations, status (0 solved, 1 iteration cap), kernel
#: rows computed.
R_INT = ("n_iter", "status", "n_rows")

TAU = 1e-12


def _llvm_binary(name: str):
    """A float64 binary LLVM intrinsic as a numba function. ``llvm.maximum`` / ``llvm.minimum``
    (IEEE maximum / minimum) are what lets LLVM vectorise the scans' max / min reductions:
    numba's ``max`` and ``a if a > b else b`` are left scalar."""
    @intrinsic
    def fn(typingctx, a, b):
        def codegen(context, builder, signature, args):
            fnty = ir.FunctionType(ir.DoubleType(), [ir.DoubleType(), ir.DoubleType()])
            return builder.call(cgutils.get_or_insert_function(builder.module, fnty, name), args)
        return types.float64(types.float64, types.float64), codegen
    return fn


_fmax = _llvm_binary("llvm.maximum.f64")
_fmin = _llvm_binary("llvm.minimum.f64")
_LOWER, _UPPER, _FREE = 0, 1, 2

# exp: x = k ln2 + r, |r| <= ln2 / 2, 2^k from the exponent bits of k + 1.5 * 2^52
_MAGIC = 6755399441055744.0
_LOG2E = 1.4426950408889634
_LN2_HI = 0.6931471803691238
_LN2_LO = 1.9082149292705877e-10


@_jit_fast
def _exp_inplace(a, s):
    """``a = exp(a)`` (arguments below -708 give ``exp(-708)``, about 3e-308), in three loops
    that vectorise; ``s`` is scratch of ``a``'s length. Within a few ulps of ``math.exp``."""
    n = a.shape[0]
    for u in range(n):
        x = max(a[u], -708.0)
        t = x * _LOG2E + _MAGIC
        s[u] = t
        k = t - _MAGIC
        r = (x - k * _LN2_HI) - k * _LN2_LO
        a[u] = 1.0 + r * (1.0 + r * (0.5 + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (
            1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0 + r * (1.0 / 40320.0 + r * (
                1.0 / 362880.0 + r * (1.0 / 3628800.0 + r * (1.0 / 39916800.0 + r * (
                    1.0 / 479001600.0))))))))))))
    sb = s.view(np.int64)
    for u in range(n):
        sb[u] = (sb[u] + 1023) << 52
    for u in range(n):
        a[u] *= s[u]


@_jit_fast
def _kernel_row(data, c, row, out, tmp):
    """``row[u] = k(x_c, x_u)`` (float32) for the problem's samples ``u`` (columns
    ``sa..sa+na`` then ``sb..sb+nb`` of ``Xt``), libsvm's formulas; ``out`` and ``tmp`` are
    float64 scratch. The dot products come from the fit's Gram matrix when there is one
    (``goff >= 0``), else from ``Xt`` (one ``axpy`` per feature)."""
    Xt, xsq, gram, sa, na, sb, nb_, goff, gbase, gn, kt, gamma, coef0, degree = data
    o1 = out[:na]                 # slices, not offset indices: numba then needs no
    o2 = out[na:na + nb_]         # negative-index handling and the loops vectorise
    if goff >= 0:
        g = gram[goff + (c - gbase) * gn:goff + (c - gbase + 1) * gn]
        ga = g[sa - gbase:sa - gbase + na]
        gb = g[sb - gbase:sb - gbase + nb_]
        for u in range(na):
            o1[u] = ga[u]
        for u in range(nb_):
            o2[u] = gb[u]
    else:
        for u in range(na + nb_):
            out[u] = 0.0
        for f in range(Xt.shape[0]):
            v = Xt[f, c]
            xa = Xt[f, sa:sa + na]
            xb = Xt[f, sb:sb + nb_]
            for u in range(na):
                o1[u] += v * xa[u]
            for u in range(nb_):
                o2[u] += v * xb[u]
    n = na + nb_
    if kt == 0:  # exp(-gamma (|x|^2 + |z|^2 - 2 <x, z>))
        xc = xsq[c]
        qa = xsq[sa:sa + na]
        qb = xsq[sb:sb + nb_]
        for u in range(na):
            o1[u] = -gamma * (xc + qa[u] - 2.0 * o1[u])
        for u in range(nb_):
            o2[u] = -gamma * (xc + qb[u] - 2.0 * o2[u])
        _exp_inplace(out, tmp)
    elif kt == 2:
        for u in range(n):
            out[u] = (gamma * out[u] + coef0) ** degree
    elif kt == 3:
        for u in range(n):
            out[u] = math.tanh(gamma * out[u] + coef0)
    for u in range(n):
        row[u] = out[u]


@_jit
def _kernel_diag(Xt, xsq, c, kt, gamma, coef0, degree):
    """``k(x_c, x_c)`` (libsvm's ``QD``, float64; exactly 1 for the RBF kernel)."""
    if kt == 0:
        return 1.0
    d = Xt.shape[0]
    s = 0.0
    for f in range(d):
        s += Xt[f, c] * Xt[f, c]
    if kt == 1:
        return s
    if kt == 2:
        return (gamma * s + coef0) ** degree
    return math.tanh(gamma * s + coef0)


@_jit
def _miss(v, cache, data):
    """Compute the kernel row of variable ``v`` into a row of the cache, evicting the least
    recently used row when full; returns the row. ``cache`` = (rows (float32, by variable in
    problem order), slot_of, owner, stamp, state = [rows used, clock, rows computed], scratch
    (2, l)); ``data`` = (Xt, xsq, gram, sa, na, sb, nb, gram offset, first column of the fit,
    fit size, kernel code, gamma, coef0, degree)."""
    rows, slot_of, owner, stamp, state, tmp = cache
    cap = rows.shape[0]
    if state[0] < cap:
        s = state[0]
        state[0] += 1
    else:
        s = 0
        for k in range(1, cap):
            if stamp[k] < stamp[s]:
                s = k
        slot_of[owner[s]] = -1
    sa, na, sb = data[3], data[4], data[5]
    _kernel_row(data, sa + v if v < na else sb + (v - na), rows[s], tmp[0], tmp[1])
    slot_of[v] = s
    owner[s] = v
    state[2] += 1
    return s


@_jit
def _fetch(v, cache, data):
    """Cache row holding the kernel row of variable ``v`` (see :func:`_miss`), marked as
    used. The solver's loop does the same inline: a call with array arguments costs atomic
    reference count updates, more than the scans of a small problem."""
    rows, slot_of, owner, stamp, state, tmp = cache
    s = slot_of[v]
    if s < 0:
        s = _miss(v, cache, data)
    stamp[s] = state[1]
    state[1] += 1
    return s


@_jit_inline
def _status(a, y, C):
    """libsvm's ``update_alpha_status`` for ``alpha = a`` (label ``y``): the status and the
    selection penalties ``(status, up, low)``: ``up = 0`` where ``-y G`` may go up
    (``I_up``), ``-inf`` elsewhere; ``low = 0`` on ``I_low``, ``+inf`` elsewhere."""
    s = _UPPER if a >= C else (_LOWER if a <= 0.0 else _FREE)
    pos = y > 0.0
    up = -np.inf if (s == _UPPER and pos) or (s == _LOWER and not pos) else 0.0
    low = np.inf if (s == _LOWER and pos) or (s == _UPPER and not pos) else 0.0
    return s, up, low


@_jit_inline
def _clip_sum(a, b, total, C):
    """One of libsvm's clippings of ``a + b = total`` into the box (the other swaps the
    roles): ``a`` at ``C`` when above it (total > C), else ``b`` at 0 when below."""
    if total > C:
        if a > C:
            return C, total - C
    elif b < 0.0:
        return total, 0.0
    return a, b


@_jit_inline
def _wss2(f, lo, gmax, quad):
    """libsvm's second-order selection for one candidate ``j`` (``f = F_j``, ``lo`` its
    ``I_low`` penalty, ``quad = a_ij`` before the ``tau`` floor): ``(F_j + lo, obj_diff)``,
    ``obj_diff = -(m - F_j)^2 / a_ij`` where ``j`` may be chosen, ``+inf`` elsewhere."""
    gd = gmax - f
    quad = quad if quad > 0.0 else TAU
    od = -(gd * gd) / quad
    return f + lo, (od if (gd > 0.0) & (lo == 0.0) else np.inf)


@_jit_inline
def _scan_up(F, UP, active):
    """``m = max {F_p : p in I_up}`` over the active positions."""
    vmax = -np.inf
    for p in range(active):
        vmax = _fmax(vmax, F[p] + UP[p])
    return vmax


@_jit_inline
def _is_identity(vid):
    for p in range(vid.shape[0]):
        if vid[p] != p:
            return False
    return True


@_jit_inline
def _swap(p, q, F, A, Y, GB, UP, LO, QD, vid, st):
    F[p], F[q] = F[q], F[p]
    A[p], A[q] = A[q], A[p]
    Y[p], Y[q] = Y[q], Y[p]
    GB[p], GB[q] = GB[q], GB[p]
    UP[p], UP[q] = UP[q], UP[p]
    LO[p], LO[q] = LO[q], LO[p]
    QD[p], QD[q] = QD[q], QD[p]
    vid[p], vid[q] = vid[q], vid[p]
    st[p], st[q] = st[q], st[p]


@_jit
def _solve_one(Xt, xsq, gram, pi, pf, alpha_out):
    """libsvm's ``Solver::Solve`` on one problem (see the module docstring); writes ``alpha``
    (in problem order) to ``alpha_out``; returns ``(rho, obj, gap, n_iter, status, n_rows)``.

    The state is kept by position (libsvm's order after its shrinking swaps): ``F = -y G``,
    ``A`` = alpha, ``Y``, ``GB`` = G_bar, the penalties ``UP``/``LO``, ``QD``, the variable
    ``vid`` at each position and its status ``st``; kernel rows are by variable, read by row
    index (``rows[s, v]``). The steps of an iteration are written out here rather than called:
    every call with array arguments costs atomic reference count updates (measured: about
    half the time of the pipeline's small problems). ``ident``: positions are still the
    variables (no shrinking swap yet), so the scans read the rows without ``vid``."""
    sa, na, sb, nb_, kt, degree, max_iter, shrinking = pi[0], pi[1], pi[2], pi[3], pi[4], pi[5], pi[6], pi[7]
    C, gamma, coef0, eps = pf[0], pf[1], pf[2], pf[3]
    nv = na + nb_
    Y = np.empty(nv)
    Y[:na] = 1.0
    Y[na:] = -1.0
    F = Y.copy()                       # G = -1 at alpha = 0
    A = np.zeros(nv)
    GB = np.zeros(nv)
    UP = np.empty(nv)
    LO = np.empty(nv)
    st = np.empty(nv, np.int8)
    vid = np.arange(nv).astype(np.uint32)   # unsigned: gathers without negative-index checks
    QD = np.empty(nv)
    for p in range(nv):
        QD[p] = _kernel_diag(Xt, xsq, sa + p if p < na else sb + (p - na), kt, gamma, coef0, degree)
        st[p], UP[p], LO[p] = _status(0.0, Y[p], C)
    OD = np.empty(nv)
    cap = max(2, min(nv, pi[9] // max(1, 4 * nv)))
    rows = np.empty((cap, nv), np.float32)
    slot_of = np.full(nv, -1, np.int64)
    owner = np.zeros(cap, np.int64)
    stamp = np.zeros(cap, np.int64)
    state = np.zeros(3, np.int64)
    tmp = np.empty((2, nv))
    cache = (rows, slot_of, owner, stamp, state, tmp)
    data = (Xt, xsq, gram, sa, na, sb, nb_, pi[10], pi[11], pi[12], kt, gamma, coef0, degree)

    active = nv
    ident = True
    unshrink = False
    it = 0
    counter = min(nv, 1000) + 1
    status = 0
    gmax = _scan_up(F, UP, active)       # m of the current state, over the active positions
    rescan = False
    while True:
        if it >= max_iter:
            status = 1
            break
        counter -= 1
        if counter == 0:
            counter = min(nv, 1000)
            if shrinking:
                active, unshrink = _shrink(F, A, Y, GB, UP, LO, QD, vid, st, active, unshrink, eps,
                                           cache, data)
                ident = ident and _is_identity(vid)
                gmax = _scan_up(F, UP, active)
        # select_working_set (twice at most: again on all variables after reconstruction)
        i = j = si = -1
        for attempt in range(2):
            if rescan:
                gmax = _scan_up(F, UP, active)
                rescan = False
            # i: the last position of the largest F over I_up
            i = -1
            if gmax > -np.inf:
                for p in range(active - 1, -1, -1):
                    if F[p] + UP[p] == gmax:
                        i = p
                        break
            j = -1
            if i >= 0:
                v = vid[i]                                  # its kernel row, marked as used
                si = slot_of[v] if slot_of[v] >= 0 else _miss(v, cache, data)
                stamp[si], state[1] = state[1], state[1] + 1
                # j: the last position of the smallest -(m - F_j)^2 / a_ij over I_low, F_j < m
                fmin = np.inf
                omin = np.inf
                qi = QD[i]
                if ident:
                    for p in range(active):
                        fl, od = _wss2(F[p], LO[p], gmax, qi + QD[p] - 2.0 * rows[si, p])
                        fmin, omin, OD[p] = _fmin(fmin, fl), _fmin(omin, od), od
                else:
                    for p in range(active):
                        fl, od = _wss2(F[p], LO[p], gmax, qi + QD[p] - 2.0 * rows[si, vid[p]])
                        fmin, omin, OD[p] = _fmin(fmin, fl), _fmin(omin, od), od
                if omin < np.inf and gmax - fmin >= eps:
                    for p in range(active - 1, -1, -1):
                        if OD[p] == omin:
                            j = p
                            break
            if j >= 0 or attempt == 1:
                break
            # optimal on the active set: gradient of all variables, check again on all
            _reconstruct(F, A, Y, GB, st, vid, active, cache, data)
            active = nv
            rescan = True
            counter = 1  # shrink at the next iteration (if not optimal)
        if j < 0:
            break
        it += 1
        v = vid[j]
        sj = slot_of[v] if slot_of[v] >= 0 else _miss(v, cache, data)
        stamp[sj], state[1] = state[1], state[1] + 1
        yi, yj = Y[i], Y[j]
        old_i, old_j = A[i], A[j]
        Qij = yi * yj * rows[si, vid[j]]
        if yi != yj:
            quad = QD[i] + QD[j] + 2.0 * Qij
            if quad <= 0.0:
                quad = TAU
            delta = (-(-yi * F[i]) - (-yj * F[j])) / quad      # (-G_i - G_j) / quad
            diff = A[i] - A[j]
            A[i] += delta
            A[j] += delta
            if diff > 0.0:
                if A[j] < 0.0:
                    A[j] = 0.0
                    A[i] = diff
            elif A[i] < 0.0:
                A[i] = 0.0
                A[j] = -diff
            if diff > 0.0:  # C_i - C_j = 0: one C for both classes
                if A[i] > C:
                    A[i] = C
                    A[j] = C - diff
            elif A[j] > C:
                A[j] = C
                A[i] = C + diff
        else:
            quad = QD[i] + QD[j] - 2.0 * Qij
            if quad <= 0.0:
                quad = TAU
            delta = ((-yi * F[i]) - (-yj * F[j])) / quad         # (G_i - G_j) / quad
            total = A[i] + A[j]
            A[i] -= delta
            A[j] += delta
            A[i], A[j] = _clip_sum(A[i], A[j], total, C)   # libsvm's two symmetric clippings
            A[j], A[i] = _clip_sum(A[j], A[i], total, C)
        di = yi * (A[i] - old_i)
        dj = yj * (A[j] - old_j)
        ui, uj = st[i] == _UPPER, st[j] == _UPPER
        st[i], UP[i], LO[i] = _status(A[i], yi, C)
        st[j], UP[j], LO[j] = _status(A[j], yj, C)
        # libsvm's gradient update over the active positions (F = -y G), and the next m
        gmax = -np.inf
        if ident:
            for p in range(active):
                f = F[p] - (di * rows[si, p] + dj * rows[sj, p])
                F[p] = f
                gmax = _fmax(gmax, f + UP[p])
        else:
            for p in range(active):
                q = vid[p]
                f = F[p] - (di * rows[si, q] + dj * rows[sj, q])
                F[p] = f
                gmax = _fmax(gmax, f + UP[p])
        # G_bar += +-C Q_i over all positions where a variable reached or left C
        for s, r, was, y_ in ((si, i, ui, yi), (sj, j, uj, yj)):
            if was != (st[r] == _UPPER):
                c = -C * y_ if was else C * y_
                if ident:
                    for p in range(nv):
                        GB[p] += c * Y[p] * rows[s, p]
                else:
                    for p in range(nv):
                        GB[p] += c * Y[p] * rows[s, vid[p]]

    if status == 1 and active < nv:
        _reconstruct(F, A, Y, GB, st, vid, active, cache, data)
    # rho (libsvm's calculate_rho), objective, final gap, in libsvm's (position) order
    ub, lb, sum_free, n_free = np.inf, -np.inf, 0.0, 0
    gmin = np.inf
    gmax = -np.inf
    obj = 0.0
    for p in range(nv):
        yG = -F[p]
        if UP[p] != 0.0:
            lb = max(lb, yG)
        elif LO[p] != 0.0:
            ub = min(ub, yG)
        else:
            n_free += 1
            sum_free += yG
        gmax = max(gmax, F[p] + UP[p])
        gmin = min(gmin, F[p] + LO[p])
        obj += A[p] * (-Y[p] * F[p] - 1.0)
        alpha_out[vid[p]] = A[p]
    rho = sum_free / n_free if n_free > 0 else 0.5 * (ub + lb)
    return rho, 0.5 * obj, gmax - gmin, it, status, state[2]


@_jit
def _reconstruct(F, A, Y, GB, st, vid, active, cache, data):
    """libsvm's ``reconstruct_gradient``: ``F`` of the shrunk positions from ``G_bar`` and the
    free active variables."""
    rows = cache[0]
    nv = F.shape[0]
    if active == nv:
        return
    for p in range(active, nv):
        F[p] = -Y[p] * (GB[p] - 1.0)
    n_free = 0
    for p in range(active):
        if st[p] == _FREE:
            n_free += 1
    if n_free * nv > 2 * active * (nv - active):
        for p in range(active, nv):
            Kp = rows[_fetch(vid[p], cache, data)]
            g = -Y[p] * F[p]
            for q in range(active):
                if st[q] == _FREE:
                    g += A[q] * (Y[p] * Y[q] * Kp[vid[q]])
            F[p] = -Y[p] * g
    else:
        for q in range(active):
            if st[q] != _FREE:
                continue
            Kq = rows[_fetch(vid[q], cache, data)]
            aq = A[q]
            for p in range(active, nv):
                F[p] -= Y[p] * (aq * (Y[q] * Y[p] * Kq[vid[p]]))


@_jit
def _shrink(F, A, Y, GB, UP, LO, QD, vid, st, active, unshrink, eps, cache, data):
    """libsvm's ``do_shrinking``; returns the new active size and the unshrink flag."""
    gmax1 = -np.inf   # max -y G over I_up
    gmax2 = -np.inf   # max y G over I_low
    for p in range(active):
        gmax1 = max(gmax1, F[p] + UP[p])
        gmax2 = max(gmax2, -(F[p] + LO[p]))
    nv = F.shape[0]
    if not unshrink and gmax1 + gmax2 <= eps * 10.0:
        unshrink = True
        _reconstruct(F, A, Y, GB, st, vid, active, cache, data)
        active = nv
    p = 0
    while p < active:
        if (UP[p] != 0.0 and F[p] > gmax1) or (LO[p] != 0.0 and -F[p] > gmax2):
            active -= 1
            while active > p:
                q = active
                if not ((UP[q] != 0.0 and F[q] > gmax1) or (LO[q] != 0.0 and -F[q] > gmax2)):
                    _swap(p, q, F, A, Y, GB, UP, LO, QD, vid, st)
                    break
                active -= 1
        p += 1
    return active, unshrink


@_jit
def _solve_range(Xt, xsq, gram, P_int, P_flt, order, q, alpha_out, res_f, res_i):
    p = order[q]
    pi, pf = P_int[p], P_flt[p]
    nv = pi[1] + pi[3]
    off = pi[8]
    rho, obj, gap, n_iter, status, n_rows = _solve_one(Xt, xsq, gram, pi, pf, alpha_out[off:off + nv])
    res_f[p, 0] = rho
    res_f[p, 1] = obj
    res_f[p, 2] = gap
    res_i[p, 0] = n_iter
    res_i[p, 1] = status
    res_i[p, 2] = n_rows


@nb.njit(cache=True, parallel=True, error_model="numpy")
def _solve_parallel(Xt, xsq, gram, P_int, P_flt, order, alpha_out, res_f, res_i):
    for q in nb.prange(order.shape[0]):
        _solve_range(Xt, xsq, gram, P_int, P_flt, order, q, alpha_out, res_f, res_i)


@nb.njit(cache=True, error_model="numpy")
def _solve_serial(Xt, xsq, gram, P_int, P_flt, order, alpha_out, res_f, res_i):
    for q in range(order.shape[0]):
        _solve_range(Xt, xsq, gram, P_int, P_flt, order, q, alpha_out, res_f, res_i)


def solve_batch(Xt: np.ndarray, P_int: np.ndarray, P_flt: np.ndarray, *, parallel: bool,
                gram: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve every binary problem of a batch.

    Parameters
    ----------
    Xt : ndarray of shape (n_features, n_samples), float64
        The samples of all problems, one column each (C-contiguous).
    P_int : ndarray of shape (n_problems, len(P_INT)), int64
        Per problem: columns :data:`P_INT` (the class ``+1`` samples are columns
        ``start_pos .. start_pos + n_pos`` of ``Xt``, class ``-1`` ``start_neg ..``; the
        solution goes to ``alpha[out : out + n_pos + n_neg]``).
    P_flt : ndarray of shape (n_problems, len(P_FLT)), float64
    parallel : bool
        Problems in parallel over numba's threads (not in a forked child of a process that
        ran a parallel region: GNU OpenMP aborts there).
    gram : ndarray, optional
        Gram matrices ``Xt[:, base:base + n].T @ Xt[:, base:base + n]`` of some fits, flat,
        float64; a problem whose ``gram`` column is ``>= 0`` reads its dot products at that
        offset (row stride ``gram_n``) instead of computing them.

    Returns
    -------
    alpha : ndarray of shape (sum of the problems' sizes,)
        ``0 <= alpha <= C``; the signed coefficients are ``y * alpha``.
    res_f : ndarray of shape (n_problems, 3)
        Columns :data:`R_FLT`.
    res_i : ndarray of shape (n_problems, 3)
        Columns :data:`R_INT`.
    """
    P = P_int.shape[0]
    sizes = P_int[:, 1] + P_int[:, 3]
    alpha = np.zeros(int(sizes.sum()) if P else 0)
    res_f = np.zeros((P, len(R_FLT)))
    res_i = np.zeros((P, len(R_INT)), np.int64)
    if P == 0:
        return alpha, res_f, res_i
    xsq = np.einsum("fn,fn->n", Xt, Xt)
    order = np.argsort(-sizes, kind="stable")   # largest first: balances the threads
    args = (Xt, xsq, np.zeros(1) if gram is None else gram, P_int, P_flt, order, alpha, res_f, res_i)
    if parallel and P > 1:
        with nb.parallel_chunksize(1):
            _solve_parallel(*args)
    else:
        _solve_serial(*args)
    return alpha, res_f, res_i
