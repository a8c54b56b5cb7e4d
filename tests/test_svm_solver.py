"""The batched solver of :mod:`hlaid.svm`: active-set refinement and thread handling.

The refinement (:func:`hlaid.svm._active_set.refine`) is checked against
libsvm run to a tight tolerance (an independent solver of the same dual), on
its own and inside :func:`hlaid.svm.smo_ovo`, on heavily overlapping classes
with ``C = 10`` (the identification pipeline's regime, where it is used most).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from sklearn.metrics.pairwise import rbf_kernel
from sklearn.svm import SVC

from hlaid.svm import KernelSVC, make_kernel, resolve_gamma, smo_ovo
from hlaid.svm._active_set import refine


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


def binary_pair(seed: int, C: float = 10.0, n: int = 160):
    """A hard binary problem in the solver's padded layout, SMO stopped early.

    Returns ``(F, beta, hi, lo, valid, K)`` for the single pair (batch of 1),
    ``beta`` from plain SMO at ``tol = 0.2`` (feasible, far from optimal), the
    kernel among the pair's slots and the samples/labels in slot order.
    """
    X, y = overlapping(n, 2, seed, noise=0.6)
    g = resolve_gamma("scale", X)
    res, lay = smo_ovo(torch.tensor(X), torch.tensor(y), 2, kernel=make_kernel("rbf", gamma=g),
                       C=C, tol=0.2, refine_active_set=False)
    valid = lay.valid[0].numpy()
    Xs = X[lay.order.numpy()][lay.gmap[0].numpy()]
    ys = np.where(np.arange(valid.size) < lay.Lc, 1.0, -1.0) * valid
    K = rbf_kernel(Xs, Xs, gamma=g)
    beta = res.beta[0].numpy()
    F = ys - K @ np.where(valid, beta, 0.0)
    hi = np.where(valid & (ys > 0), C, 0.0)
    lo = np.where(valid & (ys < 0), -C, 0.0)

    def t(a):
        return torch.tensor(a)[None]

    return (t(F), t(beta), t(hi), t(lo), t(valid), t(K)), (Xs[valid], ys[valid], K, g)


@pytest.mark.parametrize("C", [0.3, 10.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_refine_reaches_libsvm_optimum(seed, C):
    (F, beta, hi, lo, valid, K), (Xv, yv, Kfull, g) = binary_pair(seed, C=C)
    Fn, bn, ok, its = refine(F, beta, hi, lo, valid, K, tol=1e-3)
    assert bool(ok[0]) and 1 <= int(its[0]) <= 30
    v = valid[0].numpy()
    b = bn[0].numpy()
    # feasible: box, bounds hit exactly, sum(beta) = 0
    assert np.all(b[v] >= lo[0].numpy()[v]) and np.all(b[v] <= hi[0].numpy()[v])
    assert abs(b[v].sum()) < 1e-9 * C * v.sum()
    assert np.all(b[~v] == 0.0)
    # libsvm's stopping rule on the exact gradient (recomputed here)
    Fx = yv - Kfull[np.ix_(v, v)] @ b[v]
    np.testing.assert_allclose(Fn[0].numpy()[v], Fx, atol=1e-8)
    up = b[v] < hi[0].numpy()[v]
    low = b[v] > lo[0].numpy()[v]
    assert Fx[up].max() - Fx[low].min() < 1e-3
    # the same optimum as libsvm run to a tight tolerance
    sk = SVC(C=C, gamma=g, tol=1e-10).fit(Xv, (yv < 0).astype(int))
    coef = np.zeros(v.sum())
    coef[sk.support_] = -sk.dual_coef_[0]               # libsvm's sign: + for the first class
    obj_sk = 0.5 * coef @ Kfull[np.ix_(v, v)] @ coef - yv @ coef
    obj = 0.5 * b[v] @ Kfull[np.ix_(v, v)] @ b[v] - yv @ b[v]
    assert abs(obj - obj_sk) <= 1e-6 * abs(obj_sk)
    assert obj <= 0.5 * beta[0].numpy() @ K[0].numpy() @ beta[0].numpy() - yv @ beta[0].numpy()[v]
    sv_sk, sv = set(np.nonzero(np.abs(coef) > 1e-8)[0]), set(np.nonzero(b[v])[0])
    assert len(sv_sk ^ sv) <= 0.02 * len(sv_sk)


def test_refine_failure_keeps_the_input():
    (F, beta, hi, lo, valid, K), _ = binary_pair(0)
    beta0 = torch.zeros_like(beta)
    F0 = torch.where(valid, torch.where(hi > 0, 1.0, -1.0), 0.0).to(F.dtype)
    Fn, bn, ok, its = refine(F0, beta0, hi, lo, valid, K, tol=1e-3, max_iter=1)
    assert not bool(ok[0]) and int(its[0]) == 1
    assert torch.equal(Fn, F0) and torch.equal(bn, beta0)


@pytest.fixture(scope="module")
def overlapping_fits():
    X, y = overlapping(900, 8, seed=3)
    g = resolve_gamma("scale", X)
    kern = make_kernel("rbf", gamma=g)
    args = (torch.tensor(X), torch.tensor(y), 8)
    plain, _ = smo_ovo(*args, kernel=kern, C=10.0, refine_active_set=False)
    refined, _ = smo_ovo(*args, kernel=kern, C=10.0)
    return X, y, plain, refined


def test_refinement_solves_the_same_problems(overlapping_fits):
    _, _, plain, refined = overlapping_fits
    assert plain.converged and refined.converged
    assert plain.n_refined == 0 and refined.n_refined > 0
    # fewer batched iterations: the long SMO tails are cut
    assert refined.n_loops < plain.n_loops
    assert np.all(refined.gap.numpy() < 1e-3)
    np.testing.assert_allclose(refined.objective.numpy(), plain.objective.numpy(), rtol=1e-4)
    # refined machines are at least as optimal as plain SMO's (up to rounding)
    assert np.all(refined.objective.numpy() <= plain.objective.numpy() + 1e-9 * np.abs(plain.objective.numpy()))


def test_overlapping_classes_parity():
    """The pipeline's regime: 8 heavily overlapping classes, C = 10."""
    X, y = overlapping(1800, 8, seed=4)
    X, Xte, y, yte = X[:1200], X[1200:], y[:1200], y[1200:]
    sk = SVC(C=10.0).fit(X, y)
    me = KernelSVC(C=10.0, multiclass="ovo").fit(X, y)
    assert me.fit_status_ == 0
    assert 0.3 < np.mean(sk.predict(Xte) == yte) < 0.9          # really overlapping
    assert np.mean(me.predict(Xte) == sk.predict(Xte)) >= 0.99
    assert abs(np.mean(me.predict(Xte) == yte) - np.mean(sk.predict(Xte) == yte)) <= 0.005
    d_sk = sk.set_params(decision_function_shape="ovo").decision_function(Xte)
    d_me = me.set_params(decision_function_shape="ovo").decision_function(Xte)
    assert np.max(np.abs(d_me - d_sk)) <= 1e-3 * np.ptp(d_sk)
    s_sk, s_me = set(sk.support_.tolist()), set(me.support_.tolist())
    assert len(s_sk & s_me) / len(s_sk | s_me) >= 0.95


def test_float32_with_refinement():
    X, y = overlapping(600, 6, seed=6)
    sk = SVC(C=10.0).fit(X, y)
    me = KernelSVC(C=10.0, multiclass="ovo", dtype=torch.float32).fit(X, y)
    assert me.fit_status_ == 0
    assert np.mean(me.predict(X) == sk.predict(X)) >= 0.98


def test_one_thread_inside_and_restored(monkeypatch):
    import hlaid.svm._svc as svc_mod

    seen = []
    real = svc_mod.smo_ovo

    def spy(*args, **kw):
        seen.append(torch.get_num_threads())
        return real(*args, **kw)

    monkeypatch.setattr(svc_mod, "smo_ovo", spy)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        X, y = overlapping(200, 3, seed=7)
        est = KernelSVC().fit(X, y)
        assert seen == [1]
        assert torch.get_num_threads() == 2
        est.predict(X)
        est.decision_function(X)
        assert torch.get_num_threads() == 2
        with pytest.raises(ValueError, match="greater than one"):
            KernelSVC().fit(X, np.zeros(len(y)))          # fails inside fit
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
