"""Parity of :class:`hlaid.svm.KernelSVC` with scikit-learn's libsvm ``SVC``.

The compiled solver takes libsvm's steps (same working sets, same float32 kernel rows, same
arithmetic), so it reaches libsvm's solution itself: the same iterations on every machine, the
same support vectors, coefficients and intercepts to rounding (:func:`assert_same_machines`).
Beyond that the looser properties any correct solver must have are checked too: dual objective
within 1e-4 (relative) of the one recomputed from scikit-learn's coefficients, decision values
within 1e-3 of scikit-learn's range; multi-class (iris, wine, digits, synthetic 15 classes x 20
features): OvO predictions identical, accuracy within 0.5 point, DDAG accuracy within 1 point of
OvO, the libsvm attribute layout.
"""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.datasets import load_breast_cancer, load_digits, load_iris, load_wine, make_classification, make_moons
from sklearn.metrics.pairwise import linear_kernel, polynomial_kernel, rbf_kernel
from sklearn.model_selection import train_test_split
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from hlaid.svm import KernelSVC


def _sk_kernel(est, A, B):
    if est.kernel == "rbf":
        return rbf_kernel(A, B, gamma=est._gamma)
    if est.kernel == "linear":
        return linear_kernel(A, B)
    return polynomial_kernel(A, B, degree=est.degree, gamma=est._gamma, coef0=est.coef0)


def sklearn_pair_objectives(est: SVC) -> np.ndarray:
    """Dual objective ``1/2 b^T K b - sum |b|`` of every OvO machine of a fitted SVC.

    Reads the machines out of ``dual_coef_`` with libsvm's layout (coefficients
    of class ``a`` in row ``b - 1``, of class ``b`` in row ``a``).
    """
    m = len(est.classes_)
    starts = np.r_[0, np.cumsum(est.n_support_)]
    coef = est._dual_coef_
    out = []
    for a in range(m):
        for b in range(a + 1, m):
            A = np.arange(starts[a], starts[a + 1])
            B = np.arange(starts[b], starts[b + 1])
            beta = np.r_[coef[b - 1, A], coef[a, B]]
            sv = est.support_vectors_[np.r_[A, B]]
            K = _sk_kernel(est, sv, sv)
            out.append(0.5 * beta @ K @ beta - np.abs(beta).sum())
    return np.array(out)


def assert_same_machines(me: KernelSVC, sk: SVC, rtol: float = 1e-12) -> None:
    """libsvm's solution: equal iteration counts on every machine, equal support vectors, equal
    coefficients and intercepts (to ``rtol`` of C: kernel values may round differently in the
    last bit, e.g. scikit-learn's dot products go through BLAS)."""
    np.testing.assert_array_equal(me.n_iter_, sk.n_iter_)
    np.testing.assert_array_equal(me.support_, sk.support_)
    np.testing.assert_array_equal(me.n_support_, sk.n_support_)
    np.testing.assert_allclose(me.dual_coef_, sk.dual_coef_, rtol=0, atol=rtol * sk.C)
    np.testing.assert_allclose(me.intercept_, sk.intercept_, rtol=0, atol=rtol * max(1.0, sk.C))


def _binary_problems():
    X1, y1 = make_classification(n_samples=400, n_features=8, random_state=0)
    X2, y2 = make_moons(n_samples=300, noise=0.3, random_state=0)
    bc = load_breast_cancer()
    X3 = StandardScaler().fit_transform(bc.data)
    return {"classification": (X1, y1), "moons": (X2, y2), "breast_cancer": (X3, bc.target)}


BINARY = _binary_problems()


@pytest.mark.parametrize("C", [0.5, 1.0, 10.0])
@pytest.mark.parametrize("name", sorted(BINARY))
def test_binary_parity_rbf(name, C):
    X, y = BINARY[name]
    sk = SVC(C=C, kernel="rbf", gamma="scale").fit(X, y)
    me = KernelSVC(C=C, kernel="rbf", gamma="scale").fit(X, y)
    assert me.gamma_ == pytest.approx(sk._gamma, rel=1e-12)
    # dual objective
    obj_sk = sklearn_pair_objectives(sk)[0]
    assert abs(me.dual_objective_[0] - obj_sk) <= 1e-4 * abs(obj_sk)
    # our reported objective (libsvm's obj, from its float32 kernel rows) is the objective of our
    # reported coefficients
    K = rbf_kernel(me.support_vectors_, me.support_vectors_, gamma=me.gamma_)
    c = me.dual_coef_[0]
    assert me.dual_objective_[0] == pytest.approx(0.5 * c @ K @ c - np.abs(c).sum(), rel=1e-7)
    assert_same_machines(me, sk)
    # decision values
    d_sk, d_me = sk.decision_function(X), me.decision_function(X)
    assert d_me.shape == d_sk.shape == (X.shape[0],)
    assert np.max(np.abs(d_me - d_sk)) <= 1e-3 * np.ptp(d_sk)
    # support sets: Jaccard overlap
    s_sk, s_me = set(sk.support_.tolist()), set(me.support_.tolist())
    assert len(s_sk & s_me) / len(s_sk | s_me) >= 0.95
    # attribute layout and sign convention of the binary case
    assert me.dual_coef_.shape == (1, me.support_.size)
    assert me.intercept_.shape == (1,)
    common = np.intersect1d(sk.support_, me.support_)
    c_sk = dict(zip(sk.support_.tolist(), sk.dual_coef_[0]))
    c_me = dict(zip(me.support_.tolist(), me.dual_coef_[0]))
    assert all(np.sign(c_sk[k]) == np.sign(c_me[k]) for k in common.tolist())
    assert np.sign(me.intercept_[0]) == np.sign(sk.intercept_[0]) or abs(sk.intercept_[0]) < 1e-3
    np.testing.assert_array_equal(me.predict(X), sk.predict(X))


@pytest.mark.parametrize("kernel,kw", [("linear", {}),
                                       ("poly", {"degree": 3, "gamma": "auto", "coef0": 1.0})])
def test_binary_parity_other_kernels(kernel, kw):
    X, y = BINARY["breast_cancer"]
    sk = SVC(kernel=kernel, **kw).fit(X, y)
    me = KernelSVC(kernel=kernel, **kw).fit(X, y)
    obj_sk = sklearn_pair_objectives(sk)[0]
    assert abs(me.dual_objective_[0] - obj_sk) <= 1e-4 * abs(obj_sk)
    d_sk, d_me = sk.decision_function(X), me.decision_function(X)
    assert np.max(np.abs(d_me - d_sk)) <= 1e-3 * np.ptp(d_sk)
    s_sk, s_me = set(sk.support_.tolist()), set(me.support_.tolist())
    assert len(s_sk & s_me) / len(s_sk | s_me) >= 0.95
    assert_same_machines(me, sk, rtol=1e-9)


def _multiclass_problems():
    Xi, yi = load_iris(return_X_y=True)
    Xw, yw = load_wine(return_X_y=True)
    Xw = StandardScaler().fit_transform(Xw)
    Xd, yd = load_digits(return_X_y=True)
    Xs, ys = make_classification(n_samples=2000, n_features=20, n_informative=15, n_redundant=2,
                                 n_classes=15, n_clusters_per_class=1, class_sep=2.0,
                                 random_state=0)
    out = {}
    for name, (X, y), test in [("iris", (Xi, yi), 0.3), ("wine", (Xw, yw), 0.3),
                               ("digits", (Xd, yd), 0.3), ("synthetic15", (Xs, ys), 0.25)]:
        out[name] = train_test_split(X, y, test_size=test, random_state=0, stratify=y)
    return out


MULTI = _multiclass_problems()


@pytest.fixture(scope="module", params=sorted(MULTI))
def multiclass_fit(request):
    Xtr, Xte, ytr, yte = MULTI[request.param]
    sk = SVC(C=1.0, gamma="scale").fit(Xtr, ytr)
    me = KernelSVC(C=1.0, gamma="scale", multiclass="ovo").fit(Xtr, ytr)
    return request.param, sk, me, Xte, yte


def test_multiclass_predictions(multiclass_fit):
    name, sk, me, Xte, yte = multiclass_fit
    p_sk = sk.predict(Xte)
    p_ovo = me.set_params(multiclass="ovo").predict(Xte)
    p_ddag = me.set_params(multiclass="ddag").predict(Xte)
    me.set_params(multiclass="ovo")
    np.testing.assert_array_equal(p_ovo, p_sk)
    acc_sk, acc_ovo, acc_ddag = (np.mean(p == yte) for p in (p_sk, p_ovo, p_ddag))
    assert abs(acc_ovo - acc_sk) <= 0.005, name
    assert abs(acc_ddag - acc_ovo) <= 0.01, name
    assert acc_sk > 0.8  # the problems are meaningful


def test_multiclass_machines(multiclass_fit):
    name, sk, me, Xte, yte = multiclass_fit
    m = len(sk.classes_)
    n_pairs = m * (m - 1) // 2
    assert me.intercept_.shape == (n_pairs,)
    assert me.dual_coef_.shape == (m - 1, me.support_.size)
    assert me.n_support_.sum() == me.support_.size
    # per-machine dual objectives (reads the libsvm layout of dual_coef_)
    obj_sk = sklearn_pair_objectives(sk)
    np.testing.assert_allclose(me.dual_objective_, obj_sk, rtol=1e-4)
    # OvO decision values of every machine
    d_sk = sk.set_params(decision_function_shape="ovo").decision_function(Xte)
    d_me = me.set_params(decision_function_shape="ovo").decision_function(Xte)
    me.set_params(decision_function_shape="ovr")
    assert d_me.shape == d_sk.shape == (Xte.shape[0], n_pairs)
    assert np.max(np.abs(d_me - d_sk)) <= 1e-3 * np.ptp(d_sk)
    # support sets
    s_sk, s_me = set(sk.support_.tolist()), set(me.support_.tolist())
    assert len(s_sk & s_me) / len(s_sk | s_me) >= 0.95
    assert_same_machines(me, sk)


def test_ovr_decision_matches_sklearn():
    Xtr, Xte, ytr, _ = MULTI["iris"]
    sk = SVC().fit(Xtr, ytr)
    me = KernelSVC().fit(Xtr, ytr)
    d_sk, d_me = sk.decision_function(Xte), me.decision_function(Xte)
    assert d_me.shape == (Xte.shape[0], 3)
    np.testing.assert_allclose(d_me, d_sk, atol=1e-3)
    np.testing.assert_array_equal(np.argmax(d_me, 1), np.argmax(d_sk, 1))


def test_support_sorted_by_class():
    Xtr, _, ytr, _ = MULTI["wine"]
    sk = SVC().fit(Xtr, ytr)
    me = KernelSVC().fit(Xtr, ytr)
    cls = ytr[me.support_]
    assert np.all(np.diff(cls) >= 0)
    for c in np.unique(cls):
        assert np.all(np.diff(me.support_[cls == c]) > 0)
    np.testing.assert_array_equal(me.support_vectors_, Xtr[me.support_])
    np.testing.assert_array_equal(me.n_support_, np.bincount(cls, minlength=3))
    assert np.abs(me.n_support_ - sk.n_support_).max() <= 1


def test_unbalanced_classes_parity():
    """Very different class sizes exercise the padded layout."""
    rng = np.random.default_rng(0)
    sizes = [150, 12, 60, 4]
    X = np.concatenate([rng.normal(loc=2 * k, scale=1.5, size=(s, 3)) for k, s in enumerate(sizes)])
    y = np.repeat(np.arange(len(sizes)), sizes)
    perm = rng.permutation(len(y))
    X, y = X[perm], y[perm]
    sk = SVC(C=3.0).fit(X, y)
    me = KernelSVC(C=3.0, multiclass="ovo").fit(X, y)
    np.testing.assert_allclose(me.dual_objective_, sklearn_pair_objectives(sk), rtol=1e-4)
    np.testing.assert_array_equal(me.predict(X), sk.predict(X))
    assert_same_machines(me, sk)


@pytest.mark.parametrize("shrinking", [True, False])
def test_shrinking_as_libsvm(shrinking):
    """With and without shrinking, libsvm's iterations (C = 10: many variables at the bound,
    the shrinking, unshrinking and gradient reconstruction of libsvm all happen)."""
    Xtr, _, ytr, _ = MULTI["synthetic15"]
    sk = SVC(C=10.0, shrinking=shrinking).fit(Xtr[:600], ytr[:600])
    me = KernelSVC(C=10.0, shrinking=shrinking).fit(Xtr[:600], ytr[:600])
    np.testing.assert_allclose(me.dual_objective_, sklearn_pair_objectives(sk), rtol=1e-4)
    assert_same_machines(me, sk)


def test_small_kernel_cache():
    """A cache of a few rows (rows evicted and computed again all the time) gives the same
    machines."""
    Xtr, _, ytr, _ = MULTI["synthetic15"]
    X, y = Xtr[:900], ytr[:900]
    sk = SVC().fit(X, y)
    me = KernelSVC(cache_size=0.01).fit(X, y)       # 10 kB: about 10 rows of 120 per machine
    assert_same_machines(me, sk)
    np.testing.assert_array_equal(me.dual_coef_, KernelSVC().fit(X, y).dual_coef_)
