"""Padded one-vs-one layout and the kernel block cache of the batched SMO solver.

All pair problems live in one padded tensor: a pair ``(a, b)`` has
``L = 2 * Lc`` slots (``Lc`` = largest class size), the first ``Lc`` for the
samples of class ``a``, the last ``Lc`` for those of class ``b``
(:class:`OvOLayout`).

Kernel values are cached as blocks ``k(x_r, class c)`` of length ``Lc``
(one sample against all samples of one class, padded).  The row of sample
``r`` in pair ``(a, b)`` is the two blocks ``(r, a)`` and ``(r, b)``, so a
batch of kernel rows for all pairs is a single ``index_select``
(:class:`KernelBlockCache`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ._kernels import Kernel

__all__ = ["KernelAmong", "KernelBlockCache", "OvOLayout", "compact", "kernel_storage"]


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
    def build(cls, y: torch.Tensor, n_classes: int) -> OvOLayout:
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




class KernelAmong:
    """Kernel among given samples, computed directly (one batched GEMM).

    Parameters
    ----------
    kernel : Kernel
    Xs : Tensor of shape (n_samples, n_features)
        Samples sorted by class, in the working dtype.
    """

    def __init__(self, kernel: Kernel, Xs: torch.Tensor) -> None:
        self.kernel = kernel
        self.left = kernel.prepare_left(Xs)
        self.right = kernel.prepare(Xs)

    def __call__(self, g: torch.Tensor) -> torch.Tensor:
        """Kernel blocks ``K[r, s, t] = k(x_g[r, s], x_g[r, t])``: (R, k) -> (R, k, k)."""
        return self.kernel(self.left[g], self.right[g], prepared=True)


def kernel_storage(n: int, m: int, Lc: int, dtype: torch.dtype,
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


def compact(keep: torch.Tensor) -> torch.Tensor:
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
