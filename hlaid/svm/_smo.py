"""Batched SMO solver for all one-vs-one C-SVC problems at once.

Problem
-------
For classes ``a < b`` the binary C-SVC dual (libsvm's ``Solver``) is, in the
signed variables ``beta_t = y_t alpha_t`` (``y = +1`` for class ``a``,
``-1`` for class ``b``)::

    min_beta  1/2 beta^T K beta - y^T beta
    s.t.      sum_t beta_t = 0,   lo_t <= beta_t <= hi_t,

with ``[lo, hi] = [0, C]`` for class ``a`` and ``[-C, 0]`` for class ``b``.
``beta`` is exactly libsvm's ``sv_coef`` (``y * alpha``).  The solver keeps
``F = y - K beta`` (libsvm's ``-y * G``) and, per iteration, for every pair
problem at once:

1. ``i = argmax {F_t : beta_t < hi_t}`` (``m = F_i``) and
   ``M = min {F_t : beta_t > lo_t}``; a problem with ``m - M < tol`` has
   converged (libsvm's stopping rule) and is frozen;
2. ``j`` by the second-order rule of Fan, Chen & Lin (2005):
   ``argmax (m - F_j)^2 / a_ij`` over ``beta_j > lo_j, F_j < m`` with
   ``a_ij = K_ii + K_jj - 2 K_ij`` (floored at ``tau = 1e-12`` as libsvm);
3. the analytic two-variable step ``beta_i += t, beta_j -= t``,
   ``t = min((m - F_j) / a_ij, hi_i - beta_i, beta_j - lo_j)``, with values
   snapped exactly onto the bounds;
4. ``F -= dbeta_i K_i + dbeta_j K_j`` with the two kernel rows.

Layout
------
Pair problems are padded to ``L = 2 * Lc`` slots (:class:`OvOLayout`).  The
loop works on a packed *working set* ``S`` of shape ``(n_active_pairs, 5, La)``
holding ``F``, ``beta``, the ``I_up`` / ``I_low`` penalties (``0`` or
``-inf`` / ``+inf``) and the upper bound of the active variables.  Each
iteration is a fixed number (~40) of small tensor operations whatever the
number of pairs (run under ``torch.inference_mode``, on one CPU thread; no
boolean-mask indexing and no host synchronisation inside the loop when the
kernel is precomputed).  When ``n_active_pairs * La**2`` is small the kernel
among the working set's variables is materialised, so a kernel row is one
``gather``.  Every ``check_every`` iterations the host synchronises once:
converged pairs leave the working set (once they are at least 1/8 of it;
until then they are frozen), and with ``shrinking`` the bounded variables
that libsvm's rule says cannot be selected are dropped (``La`` shrinks).  A
pair whose shrunk problem converged gets its gradient reconstructed exactly
from its support vectors and is re-tested on all its variables before it is
declared converged, as libsvm does.

Active-set refinement
---------------------
SMO needs thousands of steps on hard problems (heavily overlapping classes,
large ``C``), most of them spent on the last digits once the free support
vectors are known.  At a synchronisation point, a pair whose gap is below
:data:`REFINE_GAP` after at least :data:`REFINE_MIN_STEPS` steps (and an
eighth of its variable count) is handed to :func:`hlaid.svm._active_set.refine`,
a batched primal-dual active-set solve (a few Cholesky factorisations of the
free variables' kernel) that usually lands on the optimum.  A solved pair
gets its gradient reconstructed and is re-tested on all variables with
libsvm's rule like any other; a pair the refinement could not solve keeps
its SMO state and tries again after doubling its step count.

Kernel blocks
-------------
See :class:`KernelBlockCache`: blocks ``k(x_r, class c)`` computed on first
use, or all before the loop up to :data:`FULL_PRECOMPUTE_MAX` samples; when
the whole ``n x n`` kernel does not fit in ``cache_size`` MB at float64 the
blocks are stored in float32 (gradients stay in the working dtype), and when
the cache is full it is emptied and refilled on demand.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from types import SimpleNamespace
from typing import cast

import torch
from sklearn.exceptions import ConvergenceWarning

from .._threads import one_thread
from ._active_set import refine
from ._kernels import Kernel
from ._layout import KernelAmong, KernelBlockCache, OvOLayout, compact, kernel_storage

__all__ = ["KernelBlockCache", "OvOLayout", "SMOResult", "smo_ovo"]

#: libsvm's floor for the curvature ``a_ij`` of non-positive-definite pairs.
TAU = 1e-12
#: Up to this many samples the whole kernel is computed before the loop.
FULL_PRECOMPUTE_MAX = 5000
#: Active-set refinement: gap below which a pair is tried ...
REFINE_GAP = 0.5
#: ... after at least this many SMO steps and ``n_variables / 8``
#: (``n_variables / 2`` when the kernel is computed on demand).
REFINE_MIN_STEPS = 64
#: Active-set iterations per attempt (counted in ``n_iter``; never beyond
#: ``max_iter``).
REFINE_ITER = 30
#: Largest refined problem (variables kept by the shrinking rule) ...
REFINE_MAX_VARS = 1024
#: ... and kernel values per refinement batch (pairs beyond wait).
REFINE_MAX_ELEMENTS = 1 << 23


@dataclass
class SMOResult:
    """Solution of all pair problems (padded layout, see :class:`OvOLayout`).

    Attributes
    ----------
    beta : Tensor of shape (n_pairs, L)
        Signed dual coefficients ``y * alpha`` (0 on padding).
    rho : Tensor of shape (n_pairs,)
        libsvm's ``rho``; the decision function is ``K beta - rho``.
    objective : Tensor of shape (n_pairs,)
        Dual objective ``1/2 beta^T K beta - y^T beta`` (libsvm's ``obj``).
    n_iter : LongTensor of shape (n_pairs,)
        SMO steps plus active-set iterations taken per pair.
    gap : Tensor of shape (n_pairs,)
        Final maximal violation ``m - M`` on all variables.
    converged : bool
        Whether every pair met ``m - M < tol``.
    n_kernel_blocks : int
        Kernel blocks (one sample against one class) computed.
    n_cache_flushes : int
        Times the kernel cache was full and emptied.
    kernel_storage : torch.dtype
        dtype the kernel blocks were stored in.
    n_loops : int
        Iterations of the batched loop (the largest ``n_iter`` plus the
        iterations spent at synchronisation points).
    n_refined : int
        Pair problems finished by the active-set refinement (see
        :mod:`hlaid.svm._active_set`).
    """

    beta: torch.Tensor
    rho: torch.Tensor
    objective: torch.Tensor
    n_iter: torch.Tensor
    gap: torch.Tensor
    converged: bool
    n_kernel_blocks: int
    n_cache_flushes: int
    kernel_storage: torch.dtype
    n_loops: int
    n_refined: int = 0


def _reconstruct(F_full: torch.Tensor, beta_full: torch.Tensor, y_pair: torch.Tensor,
                 pidx: torch.Tensor, layout: OvOLayout, cache: KernelBlockCache,
                 block_elements: int = 1 << 23) -> None:
    """Recompute ``F = y - K beta`` exactly, in place, for the pairs ``pidx``.

    Only the non-zero ``beta`` (support vectors) contribute; their kernel
    rows come from the cache, in chunks of at most ``block_elements`` values.
    """
    L = 2 * layout.Lc
    beta = beta_full.index_select(0, pidx)
    nz = beta != 0
    smax = int(nz.sum(1).max())
    acc = torch.zeros_like(beta)
    if smax > 0:
        order = compact(nz)[:, :smax]                   # support vectors first
        bsv = beta.gather(1, order)                      # zero beyond the SV count
        gsv = layout.gmap.index_select(0, pidx).gather(1, order)
        cls = layout.pairs.index_select(0, pidx)[:, None, :]     # (R, 1, 2)
        R = pidx.shape[0]
        chunk = max(1, min(block_elements // max(1, R * L), cache.capacity // (2 * R)))
        for s in range(0, smax, chunk):
            idx = cache.index(gsv[:, s:s + chunk, None], cls)   # (R, c, 2)
            Kc = cache.flat.index_select(0, idx.reshape(-1)).view(R, -1, L)
            acc += torch.bmm(bsv[:, None, s:s + chunk].to(Kc.dtype), Kc).squeeze(1).to(acc.dtype)
    F_full.index_copy_(0, pidx, y_pair.index_select(0, pidx) - acc)


def smo_ovo(X: torch.Tensor, y: torch.Tensor, n_classes: int, *, kernel: Kernel,
            C: float, tol: float = 1e-3, max_iter: int = -1, shrinking: bool = True,
            cache_size: float = 1024.0, check_every: int = 16,
            layout: OvOLayout | None = None, refine_active_set: bool = True,
            ) -> tuple[SMOResult, OvOLayout]:
    """Train all ``n_classes (n_classes - 1) / 2`` one-vs-one C-SVCs together.

    Parameters
    ----------
    X : Tensor of shape (n_samples, n_features)
        Training samples (dtype and device of the computation).
    y : LongTensor of shape (n_samples,)
        Encoded labels in ``0 .. n_classes-1``; every class non-empty.
    n_classes : int
        At least 2.
    kernel : Kernel
        Kernel with resolved hyper-parameters.
    C : float
        Box constraint (> 0).
    tol : float
        Stopping tolerance on the maximal violating pair gap ``m - M``.
    max_iter : int
        Cap on SMO steps per pair; ``-1`` means libsvm's safety cap
        ``max(10_000_000, 100 * L)``.  A :class:`ConvergenceWarning` is issued
        when a pair stops on the cap.
    shrinking : bool
        Use libsvm's shrinking heuristic.
    cache_size : float
        Memory for kernel blocks, in MB.
    check_every : int
        Iterations between host synchronisations (stop test, dropping
        converged pairs, shrinking, active-set refinement).
    layout : OvOLayout, optional
        Precomputed layout for ``y``.
    refine_active_set : bool
        Hand pairs close to their optimum to the active-set refinement (see
        the module docstring); False gives plain SMO.

    Returns
    -------
    result : SMOResult
    layout : OvOLayout

    Notes
    -----
    On the CPU the solve runs on one torch thread (see :class:`one_thread`);
    torch's setting is restored on return.
    """
    if layout is None:
        layout = OvOLayout.build(y, n_classes)
    with torch.inference_mode():
        res = _solve(X, layout, kernel=kernel, C=float(C), tol=float(tol), max_iter=max_iter,
                     shrinking=bool(shrinking), cache_size=float(cache_size),
                     check_every=max(1, int(check_every)), refine_on=bool(refine_active_set))
    if not res.converged:
        cap_iter = max(10_000_000, 200 * layout.Lc) if max_iter is None or max_iter < 0 \
            else int(max_iter)
        warnings.warn(
            f"SMO stopped on the iteration cap ({cap_iter}) before reaching "
            f"tol={tol} on {int((res.gap >= tol).sum())} of {layout.n_pairs} pair problems; "
            "consider a larger max_iter, a larger tol or scaling the data.",
            ConvergenceWarning, stacklevel=4)     # smo_ovo <- KernelSVC._fit <- fit <- caller
    # plain tensors (not inference tensors) for the caller
    for name in ("beta", "rho", "objective", "n_iter", "gap"):
        setattr(res, name, getattr(res, name).clone())
    return res, layout


def _solve(X: torch.Tensor, layout: OvOLayout, *, kernel: Kernel, C: float, tol: float,
           max_iter: int | None, shrinking: bool, cache_size: float,
           check_every: int, refine_on: bool) -> SMOResult:
    dev, dt = X.device, X.dtype
    n = X.shape[0]
    m, Lc = layout.n_classes, layout.Lc
    Xs = X[layout.order]
    store, cap = kernel_storage(n, m, Lc, dt, cache_size)
    with one_thread(dev):
        cache = KernelBlockCache(kernel, Xs, layout, store, cap,
                                 precompute=(cap >= n * m and n <= FULL_PRECOMPUTE_MAX))
        return _loop(layout, cache, kernel=kernel, Xs=Xs, C=C, tol=tol, max_iter=max_iter,
                     shrinking=shrinking, check_every=check_every, refine_on=refine_on)


def _loop(layout: OvOLayout, cache: KernelBlockCache, *, kernel: Kernel, Xs: torch.Tensor,
          C: float, tol: float, max_iter: int | None, shrinking: bool, check_every: int,
          refine_on: bool) -> SMOResult:
    dev, dt = Xs.device, Xs.dtype
    Lc, P = layout.Lc, layout.n_pairs
    L = 2 * Lc
    store = cache.flat.dtype
    convert = store != dt
    const_diag = kernel.constant_diag
    kd_full = None if const_diag else kernel.diag(Xs).to(dt)[layout.gmap]
    among = KernelAmong(kernel, Xs)

    inf = math.inf
    valid = layout.valid
    side = torch.zeros(P, L, dtype=torch.bool, device=dev)
    side[:, Lc:] = True
    zero_t = torch.zeros((), dtype=dt, device=dev)
    ninf_t = torch.full((), -inf, dtype=dt, device=dev)
    pinf_t = torch.full((), inf, dtype=dt, device=dev)
    one_t = torch.ones((), dtype=dt, device=dev)
    y_pair = torch.where(valid, torch.where(side, -one_t, one_t), zero_t)
    hi_full = torch.where(valid & ~side, C * one_t, zero_t)
    lo_full = torch.where(valid & side, -C * one_t, zero_t)
    nvalid = valid.sum(1)
    beta_full = torch.zeros(P, L, dtype=dt, device=dev)
    F_full = y_pair.clone()
    niter_all = torch.zeros(P, dtype=torch.long, device=dev)
    gap_all = torch.full((P,), inf, dtype=dt, device=dev)
    cap_iter = max(10_000_000, 100 * L) if max_iter is None or max_iter < 0 else int(max_iter)
    # kernel blocks computed on demand: the refinement (and the gradient
    # reconstruction after it) needs rows SMO never touched, so only hard pairs
    refine_at = torch.clamp_min(nvalid // (8 if cache.identity else 2), REFINE_MIN_STEPS)
    n_refined = 0

    sgn = torch.tensor([1.0, -1.0], dtype=dt, device=dev)
    first = torch.tensor([[True, False]], device=dev)
    # a_ij / 2 = 1 + tau - K_ij for the RBF kernel (K_ii = 1), floored at tau
    # (rounding can put K_ij a hair above 1); tau is raised to the dtype's
    # epsilon so that 1 + tau > 1 in float32 too
    one_tau = 1.0 + max(TAU, torch.finfo(dt).eps)
    arangeL = torch.arange(L, device=dev)
    flat = cache.flat

    w = SimpleNamespace()   # the packed working set, rebound by pack()

    def pack(pidx: torch.Tensor, keep: torch.Tensor) -> None:
        """Working set of pairs ``pidx`` with variables ``keep`` (full layout)."""
        cnt = keep.sum(1)
        La = max(1, int(cnt.max()))
        sel = compact(keep)[:, :La]                # kept variables first, in order
        wvalid = torch.arange(La, device=dev)[None, :] < cnt[:, None]

        def rows_of(full: torch.Tensor) -> torch.Tensor:
            return full.index_select(0, pidx).gather(1, sel)

        beta, hi, lo = rows_of(beta_full), rows_of(hi_full), rows_of(lo_full)
        w.S = torch.stack([rows_of(F_full), beta,
                           torch.where(wvalid & (beta < hi), zero_t, ninf_t),
                           torch.where(wvalid & (beta > lo), zero_t, pinf_t), hi], 1).contiguous()
        w.kd = None if const_diag else rows_of(cast(torch.Tensor, kd_full))  # None only when const_diag
        w.idx, w.loc, w.wvalid, w.cnt = pidx, sel, wvalid, cnt
        w.gA = rows_of(layout.gmap)
        w.cls = layout.pairs.index_select(0, pidx)
        w.Pa, w.La = pidx.shape[0], La
        w.prefix = bool((sel == arangeL[:La]).all())       # columns 0 .. La-1: no gather

    def writeback(gap: torch.Tensor) -> None:
        # Padding columns of the working set hold distinct, never-selected
        # variables: their beta is unchanged and a shrunk variable's F is only
        # read after reconstruction, so whole rows can be scattered back.
        for full, row in ((beta_full, 1), (F_full, 0)):
            full.index_copy_(0, w.idx, full.index_select(0, w.idx).scatter_(1, w.loc, w.S[:, row]))
        niter_all.index_copy_(0, w.idx, niter.squeeze(1))
        gap_all.index_copy_(0, w.idx, gap.squeeze(1))

    def refine_ripe(act: torch.Tensor, gap: torch.Tensor, mval: torch.Tensor) -> torch.Tensor:
        """Active-set refinement of the ripe pairs; returns the solved ones (Pa,)."""
        solved = torch.zeros(w.Pa, dtype=torch.bool, device=dev)
        nit = niter.squeeze(1)
        ripe = act.squeeze(1) & (gap.squeeze(1) < REFINE_GAP) & (
            nit >= refine_at.index_select(0, w.idx)) & (nit + REFINE_ITER <= cap_iter)
        if not bool(ripe.any()):
            return solved
        rl = ripe.nonzero().squeeze(1)
        Sr = w.S.index_select(0, rl)
        Fr, pur, plr = Sr[:, 0], Sr[:, 2], Sr[:, 3]
        # candidates: the variables libsvm's shrinking would keep (free, or
        # bounded inside [M, m]); the others stay fixed on their bound
        mv, gp = mval.index_select(0, rl), gap.index_select(0, rl)
        cand = w.wvalid.index_select(0, rl) & ~(((pur == -inf) & (Fr > mv))
                                                 | ((plr == inf) & (Fr < mv - gp)))
        nc = cand.sum(1)
        small = (nc <= REFINE_MAX_VARS).nonzero().squeeze(1)       # Cholesky cost ~ nc^3
        if small.numel() == 0:
            return solved
        small = small[:max(1, REFINE_MAX_ELEMENTS // max(1, int(nc[small].max()) ** 2))]
        rl, cand, nc, Sr = (t.index_select(0, small) for t in (rl, cand, nc, Sr))
        Nc = max(1, int(nc.max()))
        cord = compact(cand)[:, :Nc]
        cv = torch.arange(Nc, device=dev)[None, :] < nc[:, None]
        Kr = among(w.gA.index_select(0, rl).gather(1, cord))
        Fc, bc, hc = (Sr[:, k].gather(1, cord) for k in (0, 1, 4))
        Fn, bn, ok, its = refine(Fc, bc, hc, hc - C, cv, Kr, tol=tol, max_iter=REFINE_ITER)
        Sr[:, 0].scatter_(1, cord, Fn)      # F elsewhere: reconstructed before any use
        Sr[:, 1].scatter_(1, cord, bn)
        Sr[:, 2].scatter_(1, cord, torch.where(cv & (bn < hc), zero_t, ninf_t))
        Sr[:, 3].scatter_(1, cord, torch.where(cv & (bn > hc - C), zero_t, pinf_t))
        w.S.index_copy_(0, rl, Sr)
        niter.index_add_(0, rl, its[:, None])
        # a failed pair tries again once it has doubled its step count
        pf = w.idx.index_select(0, rl)
        refine_at.index_copy_(0, pf, torch.where(ok, refine_at.index_select(0, pf),
                                                 2 * niter.index_select(0, rl).squeeze(1)))
        solved[rl] = ok
        return solved

    pack(torch.arange(P, device=dev), valid)
    niter = niter_all.clone()[:, None]
    it = 0
    loops = 0
    next_sync = 0
    while True:
        # ---- (re)bind the working set -------------------------------------
        S, Pa, La, loc, gA, cls, kd = w.S, w.Pa, w.La, w.loc, w.gA, w.cls, w.kd
        F, pu, pl = S[:, 0], S[:, 2], S[:, 3]
        prefix = w.prefix
        exp5 = (Pa, 5, 2)
        exp3 = (Pa, 3, 2)
        S13 = S[:, 1:4]

        def row(c: torch.Tensor, gA=gA, cls=cls, Pa=Pa, La=La, prefix=prefix,
                loc=loc) -> torch.Tensor:
            """Kernel rows (Pa, La) of the working-set columns ``c`` (Pa, 1)."""
            r = flat.index_select(0, cache.index(gA.gather(1, c), cls).view(-1)).view(Pa, L)
            r = r[:, :La] if prefix else r.gather(1, loc)
            return r.to(dt) if convert else r

        while True:
            loops += 1
            Fu = torch.add(F, pu)
            mval, i = Fu.max(1, keepdim=True)
            b = torch.sub(mval, F).sub_(pl)                   # m - F on I_low, else -inf
            gap = b.amax(1, keepdim=True)
            act = gap >= tol
            if it >= next_sync or it >= cap_iter:
                break                                         # host synchronisation below
            niter += act
            # ---- working-set selection (second order) ---------------------
            Ki = row(i)
            if const_diag:
                a = torch.rsub(Ki, one_tau).clamp_min_(TAU)    # a_ij / 2 > 0
            else:
                kdi = kd.gather(1, i)
                a = torch.add(kd, Ki, alpha=-2.0).add_(kdi + TAU).clamp_min_(TAU)
            j = b.clamp_min_(0.0).square_().div_(a).max(1, keepdim=True)[1]
            # ---- analytic two-variable step -------------------------------
            ij = torch.cat([i, j], 1)
            G = S.gather(2, ij[:, None, :].expand(exp5))       # (F, beta, pu, pl, hi) at i, j
            aij = a.gather(1, j)
            if const_diag:
                aij = aij.mul_(2.0)
            bij, hij = G[:, 1], G[:, 4]
            lij = hij - C
            bnd = torch.where(first, hij, lij)                # i moves up, j moves down
            caps = (bnd - bij).mul_(sgn)
            t = torch.minimum(torch.sub(mval, G[:, 0, 1:]).div_(aij),
                              caps.amin(1, keepdim=True)).mul_(act)
            newb = torch.where(t >= caps, bnd, torch.addcmul(bij, t, sgn))
            d = newb - bij
            S13.scatter_(2, ij[:, None, :].expand(exp3),
                         torch.stack([newb, torch.where(newb < hij, zero_t, ninf_t),
                                      torch.where(newb > lij, zero_t, pinf_t)], 1))
            F.addcmul_(Ki, d[:, :1], value=-1.0).addcmul_(row(j), d[:, 1:], value=-1.0)
            it += 1

        # ---- host synchronisation: stop test, converged pairs, shrinking ---
        stop = it >= cap_iter
        refined = refine_ripe(act, gap, mval) if refine_on and not stop else None
        if refined is not None:
            act = act & ~refined[:, None]
            n_ref = int(refined.sum())
            n_refined += n_ref
        else:
            n_ref = 0
        conv = ~act.squeeze(1)
        full = w.cnt == nvalid.index_select(0, w.idx)
        done = conv & full
        if n_ref:
            assert refined is not None  # n_ref > 0 only when refined is set above
            done &= ~refined                       # refined pairs are re-checked exactly
        recon = conv & ~done
        n_done, n_recon = int(done.sum()), int(recon.sum())
        keep_w = w.wvalid
        shrink_gain = False
        if shrinking and not stop:
            # libsvm's rule: bounded variables beyond the current m / M
            shrinkable = (((pu == -inf) & (F > mval)) | ((pl == inf) & (F < mval - gap))) & act
            keep_w = w.wvalid & ~shrinkable
            shrink_gain = int(keep_w.sum(1).max()) <= (3 * w.La) // 4
        next_sync = it + check_every
        # converged pairs stay frozen in the working set until enough of them
        # (1/8 of the active pairs) are there to make a repack worth its cost
        if not (stop or n_done == Pa or n_done + n_recon > Pa // 8 or shrink_gain or n_ref):
            continue                                # same working set, go on stepping
        writeback(gap)
        if stop or n_done == Pa:
            break
        keep = torch.zeros(Pa, L + 1, dtype=torch.bool, device=dev)
        keep.scatter_(1, loc, keep_w)
        keep = keep[:, :L]
        if n_recon > 0:
            # exact gradient on all variables, then re-test and re-shrink
            rloc = recon.nonzero().squeeze(1)
            ridx = w.idx.index_select(0, rloc)
            _reconstruct(F_full, beta_full, y_pair, ridx, layout, cache)
            Fr, br, vr = (t_.index_select(0, ridx) for t_ in (F_full, beta_full, valid))
            up = vr & (br < hi_full.index_select(0, ridx))
            low = vr & (br > lo_full.index_select(0, ridx))
            mr = torch.where(up, Fr, ninf_t).amax(1, keepdim=True)
            Mr = torch.where(low, Fr, pinf_t).amin(1, keepdim=True)
            gap_r = (mr - Mr).squeeze(1)
            gap_all.index_copy_(0, ridx, gap_r)
            kr = vr
            if shrinking:
                kr = vr & ~((~up & (Fr > mr)) | (~low & (Fr < Mr)))
            keep.index_copy_(0, rloc, kr)
            done.index_copy_(0, rloc, gap_r < tol)
        cont = (~done).nonzero().squeeze(1)
        if cont.numel() == 0:
            w.idx, w.cnt = w.idx[:0], w.cnt[:0]      # every pair finished exactly
            break
        niter = niter.index_select(0, cont)
        pack(w.idx.index_select(0, cont), keep.index_select(0, cont))

    # pairs stopped by the cap with shrunk variables: exact gradient first
    not_full = (w.cnt != nvalid.index_select(0, w.idx)).nonzero().squeeze(1)
    if not_full.numel() > 0:
        _reconstruct(F_full, beta_full, y_pair, w.idx.index_select(0, not_full), layout, cache)
    up = valid & (beta_full < hi_full)
    low = valid & (beta_full > lo_full)
    gap_all = (torch.where(up, F_full, ninf_t).amax(1)
               - torch.where(low, F_full, pinf_t).amin(1))
    converged = bool((gap_all < tol).all())

    # ---- intercept (libsvm calculate_rho) and objective -----------------
    at_hi = valid & (beta_full >= hi_full)
    at_lo = valid & (beta_full <= lo_full)
    free = valid & ~at_hi & ~at_lo
    mF = -F_full                                  # libsvm's y * G
    n_free = free.sum(1)
    sum_free = torch.where(free, mF, zero_t).sum(1)
    ub = torch.where(at_lo, mF, pinf_t).amin(1)
    lb = torch.where(at_hi, mF, ninf_t).amax(1)
    rho = torch.where(n_free > 0, sum_free / n_free.clamp_min(1), (ub + lb) / 2)
    objective = -0.5 * (beta_full * (F_full + y_pair)).sum(1)
    return SMOResult(beta=beta_full, rho=rho, objective=objective, n_iter=niter_all,
                     gap=gap_all, converged=converged, n_kernel_blocks=cache.n_computed,
                     n_cache_flushes=cache.n_flushes, kernel_storage=store, n_loops=loops,
                     n_refined=n_refined)
