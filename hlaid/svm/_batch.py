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
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
import torch
from sklearn.exceptions import ConvergenceWarning

from ._kernels import Kernel, make_kernel, resolve_gamma
from ._solver import KERNEL_CODES, P_FLT, P_INT, solve_batch

if TYPE_CHECKING:
    from ._svc import KernelSVC

__all__ = ["fit_many"]

_PID = os.getpid()


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
    counts, starts : class sizes and first sorted positions; base : first column in ``Xt``
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
    from ._svc import KernelSVC

    if not len(estimators) == len(Xs) == len(ys):
        raise ValueError(f"fit_many: {len(estimators)} estimators, {len(Xs)} X and {len(ys)} y; "
                         "expected one X and one y per estimator.")
    ours = [k for k, e in enumerate(estimators) if isinstance(e, KernelSVC)]
    for k, e in enumerate(estimators):
        if k not in set(ours):
            e.fit(Xs[k], ys[k])
    fits, base = [], 0
    for k in ours:
        f = estimators[k]._prepare(Xs[k], ys[k], base)
        fits.append(f)
        base += f.X.shape[0]
    if fits:
        _solve(fits, [estimators[k] for k in ours])
    return list(estimators)


def _problems(fits: list[_Fit], ests: list[KernelSVC]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Xt`` and the problem tables of all fits."""
    d = max(f.X.shape[1] for f in fits)
    Xt = np.zeros((d, sum(f.X.shape[0] for f in fits)))
    rows_i, rows_f = [], []
    threads = numba.get_num_threads() if parallel_ok() else 1
    out = row = 0
    for f, est in zip(fits, ests):
        n = f.X.shape[0]
        Xt[: f.X.shape[1], f.base:f.base + n] = f.X[f.order].T
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
        code = KERNEL_CODES[est.kernel]
        rows_i.append(np.stack([f.base + f.starts[a], na, f.base + f.starts[b], nb,
                                np.full(a.shape, code), np.full(a.shape, int(est.degree)), cap,
                                np.full(a.shape, int(bool(est.shrinking))), offs,
                                np.full(a.shape, cache)], 1))
        rows_f.append(np.tile([float(est.C), f.kernel.gamma, float(est.coef0), float(est.tol)],
                              (a.shape[0], 1)))
    P_int = np.concatenate(rows_i).astype(np.int64)
    P_flt = np.concatenate(rows_f).astype(np.float64)
    assert P_int.shape[1] == len(P_INT) and P_flt.shape[1] == len(P_FLT)
    return np.ascontiguousarray(Xt), P_int, P_flt


def _solve(fits: list[_Fit], ests: list[KernelSVC]) -> None:
    Xt, P_int, P_flt = _problems(fits, ests)
    alpha, res_f, res_i = solve_batch(Xt, P_int, P_flt, parallel=parallel_ok())
    for f, est in zip(fits, ests):
        sl = slice(f.first, f.first + f.n_pairs)
        est._finish(f, P_int[sl], alpha, res_f[sl], res_i[sl])
    capped = res_i[:, 1] != 0
    if capped.any():
        warnings.warn(
            f"the solver stopped on the iteration cap before reaching tol on {int(capped.sum())} of "
            f"{capped.shape[0]} pair problems; consider a larger max_iter, a larger tol or scaling "
            "the data.", ConvergenceWarning, stacklevel=4)


def prepare_fit(est: KernelSVC, X: np.ndarray, y_enc: np.ndarray, base: int, dtype: torch.dtype,
                device: torch.device) -> _Fit:
    """A validated fit's entry in the batch (the classes sorted, the kernel resolved)."""
    m = int(y_enc.max()) + 1
    order = np.argsort(y_enc, kind="stable")
    counts = np.bincount(y_enc, minlength=m)
    starts = np.cumsum(counts) - counts
    est.gamma_ = resolve_gamma(est.gamma, X)
    kern = make_kernel(est.kernel, gamma=est.gamma_, degree=est.degree, coef0=est.coef0)
    return _Fit(X=X, y_enc=y_enc, order=order, counts=counts, starts=starts, base=base,
                kernel=kern, dtype=dtype, device=device)


def coefficients(f: _Fit, P_int: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The fit's signed coefficients ``(max(m - 1, 1), n_samples)`` in sorted sample order,
    libsvm's one-vs-one layout: for machine ``(a, b)`` the coefficients of class ``a`` go to row
    ``b - 1``, those of class ``b`` to row ``a``."""
    m = f.counts.shape[0]
    coef = np.zeros((max(m - 1, 1), f.X.shape[0]))
    a, b = np.triu_indices(m, 1)
    for k in range(a.shape[0]):
        sa, na, sb, nb, off = (int(v) for v in P_int[k, [0, 1, 2, 3, 8]])
        sa, sb = sa - f.base, sb - f.base
        coef[b[k] - 1, sa:sa + na] = alpha[off:off + na]
        coef[a[k], sb:sb + nb] = -alpha[off + na:off + na + nb]
    return coef
