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
All pair problems live in one padded tensor: a pair ``(a, b)`` has
``L = 2 * Lc`` slots (``Lc`` = largest class size), the first ``Lc`` for the
samples of class ``a``, the last ``Lc`` for those of class ``b``.  The loop
works on a packed *working set* ``S`` of shape ``(n_active_pairs, 5, La)``
holding ``F``, ``beta``, the ``I_up`` / ``I_low`` penalties (``0`` or
``-inf`` / ``+inf``) and the upper bound of the active variables.  Each
iteration is a fixed number (~60) of tensor operations whatever the number
of pairs (run under ``torch.inference_mode``; no boolean-mask indexing and no
host synchronisation inside the loop when the kernel is precomputed).  Every
``check_every`` iterations the host synchronises once: converged pairs leave
the working set (once they are at least 1/8 of it; until then they are
frozen), and with ``shrinking`` the bounded variables that libsvm's rule says
cannot be selected are dropped (``La`` shrinks).  A pair whose shrunk problem converged gets its gradient
reconstructed exactly from its support vectors and is re-tested on all its
variables before it is declared converged, as libsvm does.

Kernel blocks
-------------
Kernel values are cached as blocks ``k(x_r, class c)`` of length ``Lc``
(one sample against all samples of one class, padded).  The row of sample
``r`` in pair ``(a, b)`` is the two blocks ``(r, a)`` and ``(r, b)``, so a
batch of kernel rows for all pairs is a single ``index_select``.  Blocks are
computed on first use, one GEMM per class for all blocks missing in an
iteration; up to :data:`FULL_PRECOMPUTE_MAX` samples the whole kernel is
computed before the loop instead.  The cache holds ``cache_size`` MB; when
the whole ``n x n`` kernel does not fit at float64 the blocks are stored in
float32 (gradients stay in the working dtype), and when the cache is full it
is emptied and refilled on demand.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from types import SimpleNamespace

import torch
from sklearn.exceptions import ConvergenceWarning

from ._kernels import Kernel

__all__ = ["OvOLayout", "SMOResult", "KernelBlockCache", "smo_ovo"]

#: libsvm's floor for the curvature ``a_ij`` of non-positive-definite pairs.
TAU = 1e-12
#: Up to this many samples the whole kernel is computed before the loop.
FULL_PRECOMPUTE_MAX = 5000


@dataclass
class OvOLayout:
    """Index bookkeeping for the padded one-vs-one layout.

    Attributes
    ----------
    n_classes : int
    order : LongTensor of shape (n_samples,)
        Stable sort of the samples by class: sorted position -> original index.
    counts, starts : LongTensor of shape (n_classes,)
        Class sizes and first sorted position of each class.
    Lc : int
        Largest class size; a pair problem has ``L = 2 * Lc`` slots.
    pairs : LongTensor of shape (n_pairs, 2)
        ``(a, b)``, ``a < b``, in libsvm order (0,1), (0,2), ..., (1,2), ...
    gmap : LongTensor of shape (n_pairs, L)
        Sorted position of the sample in each slot (0 for padding).
    valid : BoolTensor of shape (n_pairs, L)
        False on padding slots.
    """

    n_classes: int
    order: torch.Tensor
    counts: torch.Tensor
    starts: torch.Tensor
    Lc: int
    pairs: torch.Tensor
    gmap: torch.Tensor
    valid: torch.Tensor

    @classmethod
    def build(cls, y: torch.Tensor, n_classes: int) -> "OvOLayout":
        """Layout for encoded labels ``y`` (values ``0 .. n_classes-1``).

        Parameters
        ----------
        y : LongTensor of shape (n_samples,)
        n_classes : int

        Returns
        -------
        OvOLayout
        """
        dev = y.device
        order = torch.argsort(y, stable=True)
        counts = torch.bincount(y, minlength=n_classes)
        starts = torch.cumsum(counts, 0) - counts
        Lc = int(counts.max())
        pairs = torch.combinations(torch.arange(n_classes, device=dev), 2)
        pa, pb = pairs[:, 0], pairs[:, 1]
        k = torch.arange(Lc, device=dev)
        va = k[None, :] < counts[pa][:, None]
        vb = k[None, :] < counts[pb][:, None]
        zero = torch.zeros((), dtype=torch.long, device=dev)
        ga = torch.where(va, starts[pa][:, None] + k[None, :], zero)
        gb = torch.where(vb, starts[pb][:, None] + k[None, :], zero)
        return cls(n_classes=n_classes, order=order, counts=counts, starts=starts, Lc=Lc,
                   pairs=pairs, gmap=torch.cat([ga, gb], 1), valid=torch.cat([va, vb], 1))

    @property
    def n_pairs(self) -> int:
        return self.pairs.shape[0]

    def padded_rows(self, Xs: torch.Tensor) -> torch.Tensor:
        """Sorted samples scattered into class-padded order.

        Parameters
        ----------
        Xs : Tensor of shape (n_samples, n_features)
            Samples in sorted (by class) order.

        Returns
        -------
        Tensor of shape (n_classes * Lc, n_features)
            Row ``c * Lc + k`` is the ``k``-th sample of class ``c``; padding
            rows are zero.
        """
        m, Lc = self.n_classes, self.Lc
        out = Xs.new_zeros(m * Lc, Xs.shape[1])
        cls_of = torch.repeat_interleave(torch.arange(m, device=Xs.device), self.counts)
        pos = torch.arange(Xs.shape[0], device=Xs.device) - self.starts[cls_of]
        out[cls_of * Lc + pos] = Xs
        return out


class KernelBlockCache:
    """Cache of kernel blocks ``k(x_r, samples of class c)`` (length ``Lc``).

    Parameters
    ----------
    kernel : Kernel
    Xs : Tensor of shape (n_samples, n_features)
        Training samples sorted by class.
    layout : OvOLayout
    storage_dtype : torch.dtype
        dtype of the stored blocks.
    capacity : int
        Number of block slots (at most ``n_samples * n_classes``).
    precompute : bool
        Compute every block at construction (needs full capacity); block
        ``(r, c)`` then lives in slot ``r * n_classes + c``.

    Attributes
    ----------
    flat : Tensor of shape (capacity, Lc)
        Block storage.
    n_computed : int
        Blocks computed so far (misses, refills included).
    """

    def __init__(self, kernel: Kernel, Xs: torch.Tensor, layout: OvOLayout,
                 storage_dtype: torch.dtype, capacity: int, precompute: bool = False) -> None:
        n = Xs.shape[0]
        m, Lc = layout.n_classes, layout.Lc
        self.m, self.Lc, self.n = m, Lc, n
        self.kernel = kernel
        dev = Xs.device
        Xc = Xs.to(storage_dtype)
        self._left = kernel.prepare_left(Xc)
        self._right = kernel.prepare(layout.padded_rows(Xc))    # (m * Lc, d')
        self.capacity = max(1, min(int(capacity), n * m))
        self.n_computed = 0
        self.n_flushes = 0
        self.identity = bool(precompute)
        if precompute:
            if self.capacity < n * m:
                raise ValueError("precompute needs capacity >= n_samples * n_classes")
            rows = torch.empty(n, m * Lc, dtype=storage_dtype, device=dev)
            step = max(1, (1 << 22) // (m * Lc))
            for s in range(0, n, step):
                kernel(self._left[s:s + step], self._right, prepared=True,
                       out=rows[s:s + step])
            self.flat = rows.view(n * m, Lc)
            self.n_computed = n * m
            self.used = n * m
        else:
            self.flat = torch.empty(self.capacity, Lc, dtype=storage_dtype, device=dev)
            self.slot_of = torch.full((n * m,), -1, dtype=torch.long, device=dev)
            self.used = 0

    def index(self, r: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """Slots of blocks ``(r, c)``, computing the missing ones.

        Parameters
        ----------
        r : LongTensor
            Sorted sample positions.
        c : LongTensor
            Classes, broadcastable with ``r``.

        Returns
        -------
        LongTensor of the broadcast shape
            Row indices into :attr:`flat`.
        """
        key = torch.add(c, r, alpha=self.m)
        if self.identity:
            return key
        s = self.slot_of[key]
        miss = s < 0
        if bool(miss.any()):
            need = torch.unique(key[miss])
            if self.used + need.shape[0] > self.capacity:
                # full: empty the cache, then compute everything needed now
                self.slot_of.fill_(-1)
                self.used = 0
                self.n_flushes += 1
                need = torch.unique(key)
                if need.shape[0] > self.capacity:
                    raise MemoryError("cache_size too small for one iteration's kernel rows")
            self._compute(need)
            s = self.slot_of[key]
        return s

    def _compute(self, keys: torch.Tensor) -> None:
        """Compute distinct missing blocks ``keys = r * m + c`` into fresh slots."""
        m, Lc = self.m, self.Lc
        cls = keys % m
        order = torch.argsort(cls, stable=True)
        keys, cls = keys[order], cls[order]
        present, counts = torch.unique_consecutive(cls, return_counts=True)
        s0 = 0
        for c, k in zip(present.tolist(), counts.tolist()):
            kk = keys[s0:s0 + k]
            out = self.flat[self.used:self.used + k]
            self.kernel(self._left[kk // m], self._right[c * Lc:(c + 1) * Lc],
                        prepared=True, out=out)
            self.slot_of[kk] = torch.arange(self.used, self.used + k, device=keys.device)
            self.used += k
            s0 += k
        self.n_computed += keys.shape[0]


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
        SMO steps taken per pair.
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


def _kernel_storage(n: int, m: int, Lc: int, dtype: torch.dtype,
                    cache_size_mb: float) -> tuple[torch.dtype, int]:
    """Storage dtype and block capacity for the cache (see module docstring).

    The capacity is at least ``2 m^2`` blocks (two rows for every pair), whatever
    ``cache_size``.
    """
    budget = float(cache_size_mb) * 2**20
    store = dtype
    if dtype == torch.float64 and n * m * Lc * 8 > budget:
        store = torch.float32
    itemsize = torch.empty((), dtype=store).element_size()
    cap = int(budget // max(1, Lc * itemsize))
    return store, min(n * m, max(2 * m * m, cap))


def _compact(keep: torch.Tensor) -> torch.Tensor:
    """Per row, the column indices with ``keep`` first, then the others (stable).

    Parameters
    ----------
    keep : BoolTensor of shape (R, L)

    Returns
    -------
    LongTensor of shape (R, L), a permutation of ``0 .. L-1`` on every row.
    """
    L = keep.shape[1]
    ar = torch.arange(L, device=keep.device)
    ck = keep.long().cumsum(1)
    cnt = ck[:, -1:]
    pos = torch.where(keep, ck - 1, cnt + ar - ck)
    return torch.empty_like(pos).scatter_(1, pos, ar.expand_as(pos))


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
        order = _compact(nz)[:, :smax]                   # support vectors first
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
            layout: OvOLayout | None = None) -> tuple[SMOResult, OvOLayout]:
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
        converged pairs, shrinking).
    layout : OvOLayout, optional
        Precomputed layout for ``y``.

    Returns
    -------
    result : SMOResult
    layout : OvOLayout
    """
    if layout is None:
        layout = OvOLayout.build(y, n_classes)
    with torch.inference_mode():
        res = _solve(X, layout, kernel=kernel, C=float(C), tol=float(tol), max_iter=max_iter,
                     shrinking=bool(shrinking), cache_size=float(cache_size),
                     check_every=max(1, int(check_every)))
    # plain tensors (not inference tensors) for the caller
    for name in ("beta", "rho", "objective", "n_iter", "gap"):
        setattr(res, name, getattr(res, name).clone())
    return res, layout


def _solve(X: torch.Tensor, layout: OvOLayout, *, kernel: Kernel, C: float, tol: float,
           max_iter: int | None, shrinking: bool, cache_size: float,
           check_every: int) -> SMOResult:
    dev, dt = X.device, X.dtype
    n = X.shape[0]
    m, Lc, P = layout.n_classes, layout.Lc, layout.n_pairs
    L = 2 * Lc
    Xs = X[layout.order]
    store, cap = _kernel_storage(n, m, Lc, dt, cache_size)
    cache = KernelBlockCache(kernel, Xs, layout, store, cap,
                             precompute=(cap >= n * m and n <= FULL_PRECOMPUTE_MAX))
    convert = store != dt
    const_diag = kernel.constant_diag
    kd_full = None if const_diag else kernel.diag(Xs).to(dt)[layout.gmap]

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
        sel = _compact(keep)[:, :La]               # kept variables first, in order
        wvalid = torch.arange(La, device=dev)[None, :] < cnt[:, None]
        def rows_of(full: torch.Tensor) -> torch.Tensor:
            return full.index_select(0, pidx).gather(1, sel)

        beta, hi, lo = rows_of(beta_full), rows_of(hi_full), rows_of(lo_full)
        w.S = torch.stack([rows_of(F_full), beta,
                           torch.where(wvalid & (beta < hi), zero_t, ninf_t),
                           torch.where(wvalid & (beta > lo), zero_t, pinf_t), hi], 1).contiguous()
        w.kd = None if const_diag else rows_of(kd_full)
        w.idx, w.loc, w.wvalid, w.cnt = pidx, sel, wvalid, cnt
        w.gA = rows_of(layout.gmap)
        w.cls = layout.pairs.index_select(0, pidx)
        w.Pa, w.La = pidx.shape[0], La
        w.ident = La == L and bool((sel == arangeL).all())

    def writeback(gap: torch.Tensor) -> None:
        # Padding columns of the working set hold distinct, never-selected
        # variables: their beta is unchanged and a shrunk variable's F is only
        # read after reconstruction, so whole rows can be scattered back.
        for full, row in ((beta_full, 1), (F_full, 0)):
            full.index_copy_(0, w.idx, full.index_select(0, w.idx).scatter_(1, w.loc, w.S[:, row]))
        niter_all.index_copy_(0, w.idx, niter.squeeze(1))
        gap_all.index_copy_(0, w.idx, gap.squeeze(1))

    pack(torch.arange(P, device=dev), valid)
    niter = niter_all.clone()[:, None]
    it = 0
    loops = 0
    next_sync = 0
    while True:
        # ---- (re)bind the working set -------------------------------------
        S, Pa, loc, gA, cls, kd = w.S, w.Pa, w.loc, w.gA, w.cls, w.kd
        F, pu, pl = S[:, 0], S[:, 2], S[:, 3]
        gather_cols = not w.ident
        index = cache.index
        exp5 = (Pa, 5, 2)
        exp3 = (Pa, 3, 2)
        S13 = S[:, 1:4]
        while True:
            loops += 1
            Fu = torch.add(F, pu)
            i = Fu.argmax(1, keepdim=True)
            mval = Fu.gather(1, i)
            b = torch.sub(mval, F).sub_(pl)                   # m - F on I_low, else -inf
            gap = b.amax(1, keepdim=True)
            act = gap >= tol
            if it >= next_sync or it >= cap_iter:
                break                                         # host synchronisation below
            niter += act
            # ---- working-set selection (second order) ---------------------
            Ki = flat.index_select(0, index(gA.gather(1, i), cls).view(-1)).view(Pa, L)
            if gather_cols:
                Ki = Ki.gather(1, loc)
            if convert:
                Ki = Ki.to(dt)
            if const_diag:
                a = torch.rsub(Ki, one_tau).clamp_min_(TAU)    # a_ij / 2 > 0
            else:
                kdi = kd.gather(1, i)
                a = torch.add(kd, Ki, alpha=-2.0).add_(kdi + TAU).clamp_min_(TAU)
            j = b.clamp_min_(0.0).square_().div_(a).argmax(1, keepdim=True)
            # ---- analytic two-variable step -------------------------------
            ij = torch.cat([i, j], 1)
            G = S.gather(2, ij[:, None, :].expand(exp5))       # (F, beta, pu, pl, hi) at i, j
            Kij = Ki.gather(1, j)
            if const_diag:
                aij = torch.rsub(Kij, one_tau).clamp_min_(TAU).mul_(2.0)
            else:
                aij = (kdi + kd.gather(1, j) - 2.0 * Kij).clamp_min_(TAU)
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
            Kj = flat.index_select(0, index(gA.gather(1, j), cls).view(-1)).view(Pa, L)
            if gather_cols:
                Kj = Kj.gather(1, loc)
            F.addcmul_(Ki, d[:, :1], value=-1.0).addcmul_(Kj.to(dt) if convert else Kj,
                                                           d[:, 1:], value=-1.0)
            it += 1

        # ---- host synchronisation: stop test, converged pairs, shrinking ---
        stop = it >= cap_iter
        conv = ~act.squeeze(1)
        full = w.cnt == nvalid.index_select(0, w.idx)
        done = conv & full
        recon = conv & ~full
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
        if not (stop or n_done == Pa or n_done + n_recon > Pa // 8 or shrink_gain):
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
    if not converged:
        warnings.warn(
            f"SMO stopped on the iteration cap ({cap_iter}) before reaching "
            f"tol={tol} on {int((gap_all >= tol).sum())} of {P} pair problems; "
            "consider a larger max_iter, a larger tol or scaling the data.",
            ConvergenceWarning, stacklevel=4)

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
                     n_cache_flushes=cache.n_flushes, kernel_storage=store, n_loops=loops)
