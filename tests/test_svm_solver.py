"""The compiled solver of :mod:`hlaid.svm` (libsvm's algorithm in numba, many problems per call).

Checked against an independent solve of the same dual (scipy's SLSQP on small problems: the
optimum, the KKT conditions, the objective), against scikit-learn's libsvm on the pipeline's
regime (heavily overlapping classes, large C), for batches (parallel = serial = one problem
at a time) and for the process rules (no parallel region in a forked worker).
"""

from __future__ import annotations

import multiprocessing as mp
import warnings

import numpy as np
import pytest
import torch
from scipy.optimize import minimize
from sklearn.metrics.pairwise import linear_kernel, polynomial_kernel, rbf_kernel
from sklearn.svm import SVC

from hlaid.svm import KERNELS, KernelSVC, fit_many
from hlaid.svm._batch import parallel_ok
from hlaid.svm._solver import P_FLT, P_INT, R_FLT, R_INT, _exp_inplace, solve_batch


def overlapping(n: int, n_classes: int, seed: int, noise: float = 0.2, n_features: int = 11):
    """Class centres along a smooth curve in [0, 1]^d plus Gaussian noise (classes overlap)."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n_classes)
    phase = rng.uniform(0.0, 2.0 * np.pi, n_features)
    freq = rng.uniform(0.5, 1.5, n_features)
    centres = 0.5 + 0.35 * np.sin(np.pi * freq[None] * s[:, None] + phase[None])
    y = rng.integers(0, n_classes, n)
    X = np.clip(centres[y] + noise * rng.standard_normal((n, n_features)), -0.2, 1.2)
    return X, y


def table(problems, cache_bytes=1 << 24):
    """``Xt`` and the problem tables for ``[(X_pos, X_neg, C, kernel, gamma, coef0, degree, tol)]``."""
    cols, rows_i, rows_f, start, out = [], [], [], 0, 0
    for Xp, Xn, C, kernel, gamma, coef0, degree, tol in problems:
        cols += [Xp, Xn]
        na, nb = len(Xp), len(Xn)
        rows_i.append([start, na, start + na, nb, KERNELS[kernel].code, degree, 10**7, 1, out,
                       cache_bytes, -1, 0, 0])     # no Gram matrix: dot products from Xt
        rows_f.append([C, gamma, coef0, tol])
        start += na + nb
        out += na + nb
    Xt = np.ascontiguousarray(np.concatenate(cols).T)
    P_int, P_flt = np.array(rows_i, np.int64), np.array(rows_f, np.float64)
    assert P_int.shape[1] == len(P_INT) and P_flt.shape[1] == len(P_FLT)
    return Xt, P_int, P_flt


def kernel_matrix(X, kernel, gamma, coef0, degree):
    if kernel == "rbf":
        K = rbf_kernel(X, X, gamma=gamma)
    elif kernel == "linear":
        K = linear_kernel(X, X)
    else:
        K = polynomial_kernel(X, X, degree=degree, gamma=gamma, coef0=coef0)
    return K.astype(np.float32).astype(np.float64)   # the solver's rows are float32, as libsvm's


def binary(seed: int, n: int = 40, d: int = 3):
    rng = np.random.default_rng(seed)
    Xp = rng.normal(0.0, 1.0, (n // 2, d))
    Xn = rng.normal(0.8, 1.0, (n - n // 2, d))
    return Xp, Xn


@pytest.mark.parametrize("kernel,gamma,coef0,degree", [("rbf", 0.5, 0.0, 3), ("linear", 0.0, 0.0, 3),
                                                      ("poly", 0.3, 1.0, 2)])
@pytest.mark.parametrize("C", [0.1, 1.0, 20.0])
@pytest.mark.parametrize("seed", [0, 1])
def test_optimum_of_the_dual(seed, C, kernel, gamma, coef0, degree):
    """The solution is the optimum of the dual (SLSQP to 1e-12 on the same kernel values), and it
    satisfies the KKT conditions on the exactly recomputed gradient."""
    Xp, Xn = binary(seed)
    X = np.concatenate([Xp, Xn])
    y = np.r_[np.ones(len(Xp)), -np.ones(len(Xn))]
    tol = 1e-6
    Xt, P_int, P_flt = table([(Xp, Xn, C, kernel, gamma, coef0, degree, tol)])
    alpha, res_f, res_i = solve_batch(Xt, P_int, P_flt, parallel=False)
    rho, obj, gap = res_f[0]
    assert res_i[0, R_INT.index("status")] == 0 and gap < tol
    K = kernel_matrix(X, kernel, gamma, coef0, degree)
    Q = y[:, None] * y[None, :] * K
    # feasible: box and equality
    assert np.all(alpha >= 0.0) and np.all(alpha <= C)
    assert abs(y @ alpha) < 1e-10 * C * len(y)
    # the reported objective is the objective of the reported alpha
    obj_a = 0.5 * alpha @ Q @ alpha - alpha.sum()
    assert obj == pytest.approx(obj_a, rel=1e-10, abs=1e-12)
    # KKT on the recomputed gradient: libsvm's gap m - M below tol
    F = -y * (Q @ alpha - 1.0)
    up = ((y > 0) & (alpha < C)) | ((y < 0) & (alpha > 0))
    low = ((y > 0) & (alpha > 0)) | ((y < 0) & (alpha < C))
    assert F[up].max() - F[low].min() < tol + 1e-9
    # rho: mean of -F over the free variables (libsvm's calculate_rho)
    free = (alpha > 0) & (alpha < C)
    if free.any():
        assert rho == pytest.approx(np.mean(-F[free]), abs=1e-6)
    # the optimum, by an independent solver
    r = minimize(lambda a: (0.5 * a @ Q @ a - a.sum(), Q @ a - 1.0), np.zeros(len(y)), jac=True,
                 method="SLSQP", bounds=[(0.0, C)] * len(y),
                 constraints=[{"type": "eq", "fun": lambda a: y @ a, "jac": lambda a: y}],
                 options={"ftol": 1e-14, "maxiter": 2000})
    obj_qp = 0.5 * r.x @ Q @ r.x - r.x.sum()
    assert obj <= obj_qp + 1e-9 * abs(obj_qp)           # not worse than the independent optimum
    assert obj == pytest.approx(obj_qp, rel=1e-7)


def test_exp_matches_libm():
    a = np.concatenate([-np.logspace(-300, np.log10(745.0), 5000), np.linspace(-5.0, 1.0, 2001),
                        [0.0, -0.0, -708.0, -1e-320]])
    out, scratch = a.copy(), np.empty_like(a)
    _exp_inplace(out, scratch)
    ref = np.exp(np.maximum(a, -708.0))
    np.testing.assert_allclose(out, ref, rtol=4e-16 * 8, atol=0)
    assert out[-4] == 1.0 and out[-3] == 1.0
    out, scratch = np.array([-800.0, -1e6]), np.empty(2)
    _exp_inplace(out, scratch)
    assert np.all(out > 0) and np.all(out < 1e-307)      # exp(-708): nothing in a kernel sums it


def batch_problems():
    """Problems of several sizes, C, kernels and tolerances, as a pass's batch holds."""
    out = []
    for k, (C, kernel, gamma, tol) in enumerate([(10.0, "rbf", 0.09, 1e-3), (1.0, "rbf", 0.5, 1e-3),
                                                 (1000.0, "rbf", 0.03, 1e-3), (0.5, "linear", 0.0, 1e-2),
                                                 (3.0, "poly", 0.1, 1e-3), (10.0, "rbf", 1.0, 1e-4)]):
        X, y = overlapping(60 + 70 * k, 2, seed=k, noise=0.4)
        out.append((X[y == 0], X[y == 1], C, kernel, gamma, 1.0, 3, tol))
    return out


def test_batch_parallel_serial_and_single():
    """One call for many problems: the same solutions in parallel, serially and one problem
    per call (the batch order and the threads change nothing)."""
    probs = batch_problems()
    Xt, P_int, P_flt = table(probs)
    par = solve_batch(Xt, P_int, P_flt, parallel=True)
    ser = solve_batch(Xt, P_int, P_flt, parallel=False)
    for a, b in zip(par, ser):
        np.testing.assert_array_equal(a, b)
    alpha, res_f, res_i = par
    for k, p in enumerate(probs):
        Xt1, P1, F1 = table([p])
        a1, f1, i1 = solve_batch(Xt1, P1, F1, parallel=False)
        off, size = P_int[k, P_INT.index("out")], P1[0, 1] + P1[0, 3]
        np.testing.assert_array_equal(alpha[off:off + size], a1)
        np.testing.assert_array_equal(res_f[k], f1[0])
        np.testing.assert_array_equal(res_i[k, :2], i1[0, :2])
    assert np.all(res_f[:, R_FLT.index("gap")] < P_flt[:, P_FLT.index("eps")])


def test_overlapping_classes_as_libsvm():
    """The identification pipeline's regime: 8 heavily overlapping classes, C = 10 and C = 1000
    (80-100 % of the samples support vectors, thousands of iterations, shrinking): libsvm's
    iterations and solution."""
    X, y = overlapping(1200, 8, seed=4)
    for C in (10.0, 1000.0):
        sk = SVC(C=C).fit(X, y)
        me = KernelSVC(C=C, multiclass="ovo").fit(X, y)
        assert me.fit_status_ == 0 and np.max(me.n_iter_) > 1000
        np.testing.assert_array_equal(me.n_iter_, sk.n_iter_)
        np.testing.assert_array_equal(me.support_, sk.support_)
        np.testing.assert_allclose(me.dual_coef_, sk.dual_coef_, rtol=0, atol=1e-9 * C)
        np.testing.assert_allclose(me.intercept_, sk.intercept_, rtol=0, atol=1e-9 * C)
        np.testing.assert_array_equal(me.predict(X), sk.predict(X))


def test_fit_many_equals_single_fits():
    """fit_many trains several fits (other C, gamma, kernels, classes) in one call, as if each
    were fitted alone; other estimators are fitted with their own fit."""
    X, y = overlapping(500, 5, seed=1)
    ests = [KernelSVC(C=10.0), KernelSVC(C=1000.0, gamma=0.5), KernelSVC(kernel="poly", degree=2),
            SVC(C=3.0), KernelSVC(C=1.0, multiclass="ovo")]
    Xs = [X[:300], X[100:400], X, X[:200], X[::2]]
    ys = [y[:300], y[100:400], y, (y[:200] > 2).astype(int), y[::2]]
    out = fit_many(ests, Xs, ys)
    assert out == ests
    for est, Xk, yk in zip(ests, Xs, ys):
        alone = type(est)(**est.get_params()).fit(Xk, yk)
        np.testing.assert_array_equal(est.dual_coef_, alone.dual_coef_)
        np.testing.assert_array_equal(est.intercept_, alone.intercept_)
        np.testing.assert_array_equal(est.predict(Xk), alone.predict(Xk))
    with pytest.raises(ValueError, match="one X and one y per estimator"):
        fit_many(ests, Xs[:2], ys)


def _fit_in_worker(seed):
    X, y = overlapping(300, 4, seed=seed)
    return parallel_ok(), KernelSVC(C=10.0).fit(X, y).dual_coef_


@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="needs fork")
def test_forked_worker_trains_serially():
    """GNU OpenMP aborts a forked child of a process that ran a parallel region: in a pool
    worker the machines train one after the other, with the same result."""
    X, y = overlapping(300, 4, seed=5)
    here = KernelSVC(C=10.0).fit(X, y)                  # a parallel region in this process first
    Xt, P_int, P_flt = table(batch_problems()[:3])
    solve_batch(Xt, P_int, P_flt, parallel=True)
    with mp.get_context("fork").Pool(1) as pool:
        ok, coef = pool.apply_async(_fit_in_worker, (5,)).get(timeout=300)
    assert ok is False
    np.testing.assert_array_equal(coef, here.dual_coef_)


def test_iteration_cap():
    Xp, Xn = binary(3, n=200)
    Xt, P_int, P_flt = table([(Xp, Xn, 100.0, "rbf", 0.5, 0.0, 3, 1e-3)])
    P_int[0, P_INT.index("max_iter")] = 5
    alpha, res_f, res_i = solve_batch(Xt, P_int, P_flt, parallel=False)
    assert res_i[0, R_INT.index("n_iter")] == 5 and res_i[0, R_INT.index("status")] == 1
    assert res_f[0, R_FLT.index("gap")] >= 1e-3


def test_torch_threads_restored():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        X, y = overlapping(200, 3, seed=7)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            est = KernelSVC().fit(X, y)
        assert torch.get_num_threads() == 2
        est.predict(X)
        est.decision_function(X)
        assert torch.get_num_threads() == 2
        with pytest.raises(ValueError, match="greater than one"):
            KernelSVC().fit(X, np.zeros(len(y)))          # fails inside fit
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_gram_and_on_demand_rows_agree(monkeypatch):
    """Dot products from the fit's Gram matrix (small fits) or computed per kernel row (large
    fits): the same machines (libsvm's), also with a cache too small to keep the rows."""
    import hlaid.svm._batch as batch

    X, y = overlapping(700, 6, seed=2)
    sk = SVC(C=10.0).fit(X, y)
    monkeypatch.setattr(batch, "GRAM_MIN_FEATURES", 1)
    gram = KernelSVC(C=10.0).fit(X, y)
    monkeypatch.setattr(batch, "GRAM_MAX_SAMPLES", 0)
    rows = KernelSVC(C=10.0).fit(X, y)
    tiny = KernelSVC(C=10.0, cache_size=0.01).fit(X, y)
    for est in (gram, rows, tiny):
        np.testing.assert_array_equal(est.n_iter_, sk.n_iter_)
        np.testing.assert_array_equal(est.support_, sk.support_)
        np.testing.assert_allclose(est.dual_coef_, sk.dual_coef_, rtol=0, atol=1e-9)
