"""Many :class:`KernelSVC` fits in one call of the compiled solver.

Every fit contributes its one-vs-one binary problems (classes ``a < b`` in libsvm's order) to
one problem table; :func:`hlaid.svm._solver.solve_batch` solves them all, in parallel over
numba's threads, and each fit gets its attributes in scikit-learn's layout.
"""

from __future__ import annotations

import multiprocessing
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numba
import numpy as np
import torch
from sklearn.exceptions import ConvergenceWarning

from .._threads import one_thread
from ._kernels import KERNELS, Kernel, make_kernel, resolve_gamma
from ._solver import P_FLT, P_INT, solve_batch

__all__ = ["fit_many"]

_PID = os.getpid()

#: A fit's Gram matrix (the dot products of its samples, float64) is computed by one matrix
#: product before the solver when it has at least :data:`GRAM_MIN_FEATURES` features, at
#: most :data:`GRAM_MAX_SAMPLES` samples and the batch's Gram matrices stay within
#: :data:`GRAM_MAX_BYTES`; otherwise the solver computes the dot products of the kernel rows
#: it needs (a fraction of them on easy problems). Measured (one thread, 1500-3000 samples):
#: the Gram matrix takes 1.6-2.3x the time with 11-20 features (writing n^2 values costs more
#: than the few products a row needs), about the same at 40, 0.3x at 160; the pipeline's fits
#: (160-500 features) take 0.25-0.35x.
GRAM_MIN_FEATURES = 32
GRAM_MAX_SAMPLES = 4096
GRAM_MAX_BYTES = 512 * 2**20


def parallel_ok() -> bool:
    """Whether the solver may run problems in parallel here: more than one numba thread, and
    not in a child process (numba's GNU OpenMP layer aborts a forked child of a process that ran
    a parallel region; pool workers are one per core anyway)."""
    return (numba.get_num_threads() > 1 and os.getpid() == _PID
            and multiprocessing.parent_process() is None)


@dataclass
class _Fit:
    """One fit's validated data in the batch.

    Attributes
    ----------
    X : (n_samples, n_features) float64 training samples; y_enc : class indices
    order : sorted position -> sample index (stable sort by class)
    counts, starts : class sizes and first sorted positions; base : first column in ``Xt`` (set
        by :func:`_problems`)
    kernel : the resolved kernel; dtype, device : of the fitted model
    first, n_pairs : the fit's rows in the problem table
    """

    X: np.ndarray
    y_enc: np.ndarray
    order: np.ndarray
    counts: np.ndarray
    starts: np.ndarray
    base: int
    kernel: Kernel
    dtype: torch.dtype
    device: torch.device
    first: int = 0
    n_pairs: int = 0


@runtime_checkable
class _Trainable(Protocol):
    """What :func:`fit_many` trains in the compiled solver: a :class:`~hlaid.svm.KernelSVC` (its
    ``_prepare`` validates the data and lays out its one-vs-one problems); anything else is fitted
    with its own ``fit``. A protocol, so this module needs no import of the estimator's."""

    def _prepare(self, X: Any, y: Any) -> Any: ...


def fit_many(estimators: Sequence[Any], Xs: Sequence[Any], ys: Sequence[Any]) -> list:
    """Fit ``estimators[k]`` on ``(Xs[k], ys[k])`` for every ``k``.

    The :class:`KernelSVC` among them are trained together: all their one-vs-one problems go
    to one call of the compiled solver (in parallel over the cores). Other estimators (e.g.
    scikit-learn's ``SVC``) are fitted one after the other with their own ``fit``.

    Parameters
    ----------
    estimators : sequence of estimators
    Xs : sequence of array-likes or Tensors of shape (n_samples_k, n_features)
    ys : sequence of array-likes or Tensors of shape (n_samples_k,)

    Returns
    -------
    list
        The fitted estimators (the same objects), in order.
    """
    if not len(estimators) == len(Xs) == len(ys):
        raise ValueError(f"fit_many: {len(estimators)} estimators, {len(Xs)} X and {len(ys)} y; "
                         "expected one X and one y per estimator.")
    ours = [k for k, e in enumerate(estimators) if isinstance(e, _Trainable)]
    for k, e in enumerate(estimators):
        if k not in set(ours):
            e.fit(Xs[k], ys[k])
    fits = [estimators[k]._prepare(Xs[k], ys[k]) for k in ours]
    if fits:
        _solve(fits, [estimators[k] for k in ours])
    return list(estimators)


def _problems(fits: list[_Fit], ests: list[Any]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """``Xt``, the problem tables and the Gram matrices of all fits (sets each fit's ``base``).

    Fits on the same samples with the same labels (a cross-validation fold under several C and
    gamma) share their columns of ``Xt`` and their Gram matrix."""
    blocks: list[tuple[np.ndarray, int, int]] = []   # distinct sorted sets: (X, base, gram offset)
    rows_i, rows_f, grams = [], [], []
    threads = numba.get_num_threads() if parallel_ok() else 1
    out = row = g_off = ncol = 0
    for f, est in zip(fits, ests):
        n = f.X.shape[0]
        Xs = f.X[f.order]
        same = [blk for blk in blocks if blk[0].shape == Xs.shape and np.array_equal(blk[0], Xs)]
        if same:
            f.base, gram = same[0][1], same[0][2]
        else:
            f.base, gram = ncol, -1
            ncol += n
            if (Xs.shape[1] >= GRAM_MIN_FEATURES and n <= GRAM_MAX_SAMPLES
                    and (g_off + n * n) * 8 <= GRAM_MAX_BYTES):
                with one_thread():
                    xs = torch.from_numpy(Xs)
                    grams.append(torch.mm(xs, xs.T).numpy().reshape(-1))
                gram, g_off = g_off, g_off + n * n
            blocks.append((Xs, f.base, gram))
        m = f.counts.shape[0]
        a, b = np.triu_indices(m, 1)          # (0,1), (0,2), ..., (1,2), ...: libsvm's order
        na, nb = f.counts[a], f.counts[b]
        size = na + nb
        if est.max_iter is None or est.max_iter < 0:
            cap = np.maximum(10_000_000, 100 * size)
        else:
            cap = np.full(a.shape, int(est.max_iter))
        cache = int(float(est.cache_size) * 2**20 / threads)   # bytes per running problem
        offs = out + np.cumsum(size) - size
        out += int(size.sum())
        f.first, f.n_pairs = row, a.shape[0]
        row += a.shape[0]
        code = KERNELS[est.kernel].code
        full = np.full(a.shape, 1)
        rows_i.append(np.stack([f.base + f.starts[a], na, f.base + f.starts[b], nb, code * full,
                                int(est.degree) * full, cap, int(bool(est.shrinking)) * full, offs,
                                cache * full, gram * full, f.base * full, n * full], 1))
        rows_f.append(np.tile([float(est.C), f.kernel.gamma, float(est.coef0), float(est.tol)],
                              (a.shape[0], 1)))
    d = max(blk[0].shape[1] for blk in blocks)
    Xt = np.zeros((d, ncol))
    for X, base, _ in blocks:
        Xt[: X.shape[1], base:base + X.shape[0]] = X.T
    P_int = np.concatenate(rows_i).astype(np.int64)
    P_flt = np.concatenate(rows_f).astype(np.float64)
    assert P_int.shape[1] == len(P_INT) and P_flt.shape[1] == len(P_FLT)
    return Xt, P_int, P_flt, np.concatenate(grams) if grams else None


def _solve(fits: list[_Fit], ests: list[Any]) -> None:
    Xt, P_int, P_flt, gram = _problems(fits, ests)
    alpha, res_f, res_i = solve_batch(Xt, P_int, P_flt, parallel=parallel_ok(), gram=gram)
    for f, est in zip(fits, ests):
        sl = slice(f.first, f.first + f.n_pairs)
        est._finish(f, P_int[sl], alpha, res_f[sl], res_i[sl])
    capped = res_i[:, 1] != 0
    if capped.any():
        warnings.warn(
            f"the solver stopped on the iteration cap before reaching tol on {int(capped.sum())} of "
            f"{capped.shape[0]} pair problems; consider a larger max_iter, a larger tol or scaling "
            "the data.", ConvergenceWarning, stacklevel=4)


def prepare_fit(est: Any, X: np.ndarray, y_enc: np.ndarray, dtype: torch.dtype,
                device: torch.device) -> _Fit:
    """A validated fit's entry in the batch (the classes sorted, the kernel resolved)."""
    m = int(y_enc.max()) + 1
    order = np.argsort(y_enc, kind="stable")
    counts = np.bincount(y_enc, minlength=m)
    starts = np.cumsum(counts) - counts
    est.gamma_ = resolve_gamma(est.gamma, X)
    kern = make_kernel(est.kernel, gamma=est.gamma_, degree=est.degree, coef0=est.coef0)
    return _Fit(X=X, y_enc=y_enc, order=order, counts=counts, starts=starts, base=0,
                kernel=kern, dtype=dtype, device=device)


def coefficients(f: _Fit, P_int: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The fit's signed coefficients ``(max(m - 1, 1), n_samples)`` in sorted sample order,
    libsvm's one-vs-one layout: for machine ``(a, b)`` the coefficients of class ``a`` go to row
    ``b - 1``, those of class ``b`` (negated: ``y = -1``) to row ``a``."""
    m = f.counts.shape[0]
    coef = np.zeros((max(m - 1, 1), f.X.shape[0]))
    a, b = np.triu_indices(m, 1)
    na, size = P_int[:, 1], P_int[:, 1] + P_int[:, 3]
    k = np.repeat(np.arange(a.shape[0]), size)                # pair of each variable
    t = np.arange(k.shape[0]) - np.repeat(np.cumsum(size) - size, size)   # its place in the pair
    first = t < na[k]
    pos = np.where(first, P_int[k, 0] + t, P_int[k, 2] + t - na[k]) - f.base
    val = alpha[P_int[k, 8] + t]
    coef[np.where(first, b[k] - 1, a[k]), pos] = np.where(first, val, -val)
    return coef
