"""Estimator contract, input validation, save/load, registries and
multi-class combination of :class:`hlaid.svm.KernelSVC`."""

from __future__ import annotations

import os
import pickle
import warnings

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.datasets import load_iris, make_blobs
from sklearn.exceptions import ConvergenceWarning, NotFittedError
from sklearn.metrics.pairwise import linear_kernel, polynomial_kernel, rbf_kernel, sigmoid_kernel
from sklearn.svm import SVC
from sklearn.utils.estimator_checks import parametrize_with_checks

from hlaid.svm import KERNELS, MULTICLASS, KernelSVC, make_kernel, resolve_gamma
from hlaid.svm._ddag import ovr_decision, pair_index

X_IRIS, Y_IRIS = load_iris(return_X_y=True)


@pytest.fixture(scope="module")
def iris_model():
    return KernelSVC().fit(X_IRIS, Y_IRIS)


# ---------------------------------------------------------------- check_estimator
#: Checks expected to fail, with the reason (also listed in docs/svm.md).
EXPECTED_FAILED_CHECKS = {
    "check_parameters_default_constructible":
        "the dtype parameter defaults to torch.float64 (a torch.dtype instance), which the "
        "check does not accept as a default value type; dtype='float64' is also accepted",
}


@parametrize_with_checks([KernelSVC()],
                         expected_failed_checks=lambda est: EXPECTED_FAILED_CHECKS)
def test_sklearn_compatible(estimator, check):
    check(estimator)


# ------------------------------------------------------------------ contract
def test_init_only_stores_parameters():
    est = KernelSVC(C=-5, kernel="nope", gamma=-1, multiclass="bad", dtype="x")  # no validation
    assert est.get_params()["C"] == -5 and est.kernel == "nope"
    with pytest.raises(TypeError):
        KernelSVC(1.0)  # keyword-only
    assert KernelSVC().get_params()["dtype"] is torch.float64
    assert clone(KernelSVC(C=3.0)).C == 3.0


def test_fit_returns_self_and_attributes(iris_model):
    est = iris_model
    m, n_pairs = 3, 3
    assert isinstance(est.fit(X_IRIS, Y_IRIS), KernelSVC)
    np.testing.assert_array_equal(est.classes_, [0, 1, 2])
    assert est.n_features_in_ == 4
    assert est.support_.dtype == np.int32 and est.support_.ndim == 1
    assert est.support_vectors_.shape == (est.support_.size, 4)
    assert est.dual_coef_.shape == (m - 1, est.support_.size)
    assert est.intercept_.shape == (n_pairs,)
    assert est.n_support_.shape == (m,) and est.n_support_.sum() == est.support_.size
    assert est.n_iter_.shape == (n_pairs,) and np.all(est.n_iter_ >= 1)
    assert est.dual_objective_.shape == (n_pairs,)
    assert est.fit_status_ == 0
    assert est.gamma_ == pytest.approx(1.0 / (4 * X_IRIS.var()))
    assert est.score(X_IRIS, Y_IRIS) > 0.95


@pytest.mark.parametrize("method", ["predict", "decision_function", "score"])
def test_unfitted_refused(method):
    args = (X_IRIS, Y_IRIS) if method == "score" else (X_IRIS,)
    with pytest.raises(NotFittedError):
        getattr(KernelSVC(), method)(*args)


def test_accepts_tensors(iris_model):
    Xt, yt = torch.tensor(X_IRIS), torch.tensor(Y_IRIS)
    est = KernelSVC().fit(Xt, yt)
    np.testing.assert_array_equal(est.predict(Xt), iris_model.predict(X_IRIS))
    np.testing.assert_allclose(est.decision_function(Xt.float()),
                               iris_model.decision_function(X_IRIS), atol=1e-5)
    np.testing.assert_array_equal(est.dual_coef_, iris_model.dual_coef_)


def test_float32_dtype():
    est = KernelSVC(dtype=torch.float32).fit(X_IRIS, Y_IRIS)
    ref = KernelSVC().fit(X_IRIS, Y_IRIS)
    assert est.dual_coef_.dtype == np.float32
    assert np.mean(est.predict(X_IRIS) == ref.predict(X_IRIS)) >= 0.98
    np.testing.assert_allclose(est.dual_objective_, ref.dual_objective_, rtol=1e-3)


def test_string_labels_and_binary_sign():
    y = np.array(["setosa", "versicolor", "virginica"])[Y_IRIS]
    keep = y != "setosa"
    est = KernelSVC().fit(X_IRIS[keep], y[keep])
    np.testing.assert_array_equal(est.classes_, ["versicolor", "virginica"])
    d = est.decision_function(X_IRIS[keep])
    assert d.shape == (keep.sum(),)
    # positive decision means classes_[1], as in scikit-learn
    np.testing.assert_array_equal(est.predict(X_IRIS[keep]), est.classes_[(d > 0).astype(int)])
    # decision function from the public (scikit-learn signed) attributes
    K = rbf_kernel(X_IRIS[keep], est.support_vectors_, gamma=est.gamma_)
    np.testing.assert_allclose(K @ est.dual_coef_[0] + est.intercept_[0], d, atol=1e-10)


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_features(bad):
    X = X_IRIS.copy()
    X[3, 1] = bad
    with pytest.raises(ValueError, match="Input X contains (NaN|infinity)"):
        KernelSVC().fit(X, Y_IRIS)
    with pytest.raises(ValueError, match="Input X contains (NaN|infinity)"):
        KernelSVC().fit(torch.tensor(X), Y_IRIS)


def test_non_finite_features_at_predict(iris_model):
    X = X_IRIS[:5].copy()
    X[0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        iris_model.predict(X)


def test_one_class():
    with pytest.raises(ValueError, match="greater than one; got 1 class"):
        KernelSVC().fit(X_IRIS[:20], np.zeros(20))


def test_length_mismatch():
    with pytest.raises(ValueError, match="inconsistent numbers of samples"):
        KernelSVC().fit(X_IRIS, Y_IRIS[:-1])


def test_wrong_number_of_features(iris_model):
    with pytest.raises(ValueError, match="X has 3 features, but KernelSVC is expecting 4"):
        iris_model.predict(X_IRIS[:, :3])
    with pytest.raises(ValueError, match="X has 5 features"):
        iris_model.decision_function(np.hstack([X_IRIS, X_IRIS[:, :1]]))


def test_regression_target_refused():
    with pytest.raises(ValueError, match="Unknown label type"):
        KernelSVC().fit(X_IRIS, np.linspace(0, 1, len(X_IRIS)))


@pytest.mark.parametrize("params,match", [
    ({"kernel": "gauss"}, r"Unknown kernel 'gauss'; valid kernels are \['linear', 'poly', 'rbf', 'sigmoid'\]"),
    ({"multiclass": "ovr"}, r"Unknown multiclass rule 'ovr'; valid rules are \['ddag', 'ovo'\]"),
    ({"C": 0.0}, "C must be a finite number > 0"),
    ({"C": np.nan}, "C must be"),
    ({"tol": -1e-3}, "tol must be"),
    ({"gamma": -0.1}, "gamma must be a finite number >= 0"),
    ({"gamma": "sometimes"}, "gamma must be 'scale', 'auto'"),
    ({"degree": 2.5}, "degree must be a non-negative integer"),
    ({"max_iter": 0}, "max_iter must be -1, None or a positive integer"),
    ({"decision_function_shape": "x"}, "decision_function_shape must be"),
    ({"dtype": torch.float16}, "dtype must be torch.float64 or torch.float32"),
    ({"device": "gpu7"}, "Invalid device"),
])
def test_invalid_parameters(params, match):
    with pytest.raises(ValueError, match=match):
        KernelSVC(**params).fit(X_IRIS, Y_IRIS)


def test_max_iter_warns():
    with pytest.warns(ConvergenceWarning, match="iteration cap"):
        est = KernelSVC(max_iter=3).fit(X_IRIS, Y_IRIS)
    assert est.fit_status_ == 1
    assert np.all(est.n_iter_ <= 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert KernelSVC().fit(X_IRIS, Y_IRIS).fit_status_ == 0


# ---------------------------------------------------------------- save / load
def test_save_load_roundtrip(tmp_path, iris_model):
    path = tmp_path / "model.pt"
    iris_model.save(path)
    assert sorted(os.listdir(tmp_path)) == ["model.pt"]  # no temporary file left
    est = KernelSVC.load(path)
    for name in ("classes_", "support_", "support_vectors_", "dual_coef_", "intercept_",
                 "n_support_", "n_iter_", "dual_objective_"):
        np.testing.assert_array_equal(getattr(est, name), getattr(iris_model, name))
    assert est.get_params() == iris_model.get_params()
    assert est.n_features_in_ == 4 and est.gamma_ == iris_model.gamma_
    np.testing.assert_array_equal(est.predict(X_IRIS), iris_model.predict(X_IRIS))
    np.testing.assert_array_equal(est.decision_function(X_IRIS),
                                  iris_model.decision_function(X_IRIS))
    # an existing file is kept unless asked; overwrite in place (atomic replace) with force
    with pytest.raises(ValueError, match="already exists"):
        iris_model.save(path)
    iris_model.save(path, force=True)
    assert sorted(os.listdir(tmp_path)) == ["model.pt"]


def test_save_load_string_labels(tmp_path):
    y = np.array(["a", "b", "c"])[Y_IRIS]
    est = KernelSVC(kernel="poly", degree=2, multiclass="ovo").fit(X_IRIS, y)
    est.save(tmp_path / "m.pt")
    back = KernelSVC.load(tmp_path / "m.pt")
    np.testing.assert_array_equal(back.predict(X_IRIS), est.predict(X_IRIS))
    assert back.classes_.dtype == est.classes_.dtype


def test_load_wrong_format(tmp_path):
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"definitely not a model")
    with pytest.raises(ValueError, match="junk.pt.*not a KernelSVC model file"):
        KernelSVC.load(junk)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    with pytest.raises(ValueError, match="other.pt.*not a KernelSVC model file"):
        KernelSVC.load(other)
    with pytest.raises(FileNotFoundError):
        KernelSVC.load(tmp_path / "missing.pt")


def test_save_unfitted_refused(tmp_path):
    with pytest.raises(NotFittedError):
        KernelSVC().save(tmp_path / "x.pt")


def test_pickle(iris_model):
    back = pickle.loads(pickle.dumps(iris_model))
    np.testing.assert_array_equal(back.predict(X_IRIS), iris_model.predict(X_IRIS))


# ---------------------------------------------------------------- registries
def test_kernel_registry_matches_sklearn():
    rng = np.random.default_rng(0)
    A, B = rng.normal(size=(7, 5)), rng.normal(size=(9, 5))
    At, Bt = torch.tensor(A), torch.tensor(B)
    refs = {"rbf": rbf_kernel(A, B, gamma=0.3), "linear": linear_kernel(A, B),
            "poly": polynomial_kernel(A, B, degree=3, gamma=0.3, coef0=1.5),
            "sigmoid": sigmoid_kernel(A, B, gamma=0.3, coef0=1.5)}
    assert set(KERNELS) == set(refs)
    for name, ref in refs.items():
        k = make_kernel(name, gamma=0.3, degree=3, coef0=1.5)
        np.testing.assert_allclose(k(At, Bt).numpy(), ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(k.diag(At).numpy(), np.diag(make_kernel(
            name, gamma=0.3, degree=3, coef0=1.5)(At, At).numpy()), atol=1e-12)
    with pytest.raises(ValueError, match="valid kernels are"):
        make_kernel("laplace")


def test_gamma_resolution_matches_sklearn():
    X = np.random.default_rng(1).normal(scale=3.0, size=(50, 6))
    assert resolve_gamma("scale", X) == pytest.approx(SVC().fit(X, np.arange(50) % 2)._gamma,
                                                      rel=1e-14)
    assert resolve_gamma("auto", X) == 1 / 6
    assert resolve_gamma(0.25, X) == 0.25
    assert resolve_gamma("scale", np.ones((4, 2))) == 1.0     # zero variance
    assert resolve_gamma("scale", torch.tensor(X)) == pytest.approx(resolve_gamma("scale", X))


def test_multiclass_registry():
    assert set(MULTICLASS) == {"ddag", "ovo"}


# -------------------------------------------------------- multi-class rules
def _ddag_reference(dec: np.ndarray, m: int) -> np.ndarray:
    """Plain-Python DDAG walk over precomputed OvO decision values."""
    tab = pair_index(m).numpy()
    out = []
    for row in dec:
        lo, hi, evals = 0, m - 1, 0
        while lo < hi:
            evals += 1
            if row[tab[lo, hi]] > 0:
                hi -= 1
            else:
                lo += 1
        assert evals == m - 1
        out.append(lo)
    return np.array(out)


def test_ddag_and_vote_rules():
    X, y = make_blobs(n_samples=400, centers=6, n_features=4, cluster_std=3.0, random_state=3)
    est = KernelSVC(C=2.0, decision_function_shape="ovo").fit(X[:300], y[:300])
    Xte = X[300:]
    dec = est.decision_function(Xte)
    pairs = [(a, b) for a in range(6) for b in range(a + 1, 6)]
    votes = np.zeros((len(Xte), 6), dtype=int)
    for p, (a, b) in enumerate(pairs):
        votes[:, a] += dec[:, p] > 0
        votes[:, b] += dec[:, p] <= 0
    np.testing.assert_array_equal(est.set_params(multiclass="ovo").predict(Xte),
                                  np.argmax(votes, 1))
    np.testing.assert_array_equal(est.set_params(multiclass="ddag").predict(Xte),
                                  _ddag_reference(dec, 6))
    # ovo voting is libsvm's (scikit-learn's) prediction
    sk = SVC(C=2.0).fit(X[:300], y[:300])
    assert np.mean(est.set_params(multiclass="ovo").predict(Xte) == sk.predict(Xte)) >= 0.99


def test_ovr_decision_matches_sklearn_helper():
    from sklearn.utils.multiclass import _ovr_decision_function
    dec = np.random.default_rng(0).normal(size=(20, 10))
    ref = _ovr_decision_function(dec < 0, -dec, 5)
    np.testing.assert_allclose(ovr_decision(torch.tensor(dec), 5).numpy(), ref, atol=1e-12)


# ---------------------------------------------------------- solver properties
@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), C=st.sampled_from([0.1, 1.0, 50.0]),
       n_classes=st.integers(2, 5))
def test_kkt_and_dual_feasibility(seed, C, n_classes):
    """Any problem: box and equality constraints hold, the reported decision
    function is the kernel expansion of the reported coefficients, and the
    solution is optimal to tol on every machine (gap recomputed here)."""
    X, y = make_blobs(n_samples=25 * n_classes, centers=n_classes, n_features=3,
                      cluster_std=2.5, random_state=seed)
    est = KernelSVC(C=C, decision_function_shape="ovo", tol=1e-3).fit(X, y)
    coef = est._dual_coef.numpy()
    assert np.all(np.abs(coef) <= C * (1 + 1e-12))
    K = rbf_kernel(X, X, gamma=est.gamma_)
    starts = np.r_[0, np.cumsum(est.n_support_)]
    dec = est.decision_function(X)
    if n_classes == 2:  # scikit-learn's sign convention: positive means classes_[1]
        dec = -dec[:, None]
    p = 0
    for a in range(n_classes):
        for b in range(a + 1, n_classes):
            A, B = np.arange(starts[a], starts[a + 1]), np.arange(starts[b], starts[b + 1])
            beta = np.zeros(len(X))
            beta[est.support_[A]] = coef[b - 1, A]
            beta[est.support_[B]] = coef[a, B]
            assert abs(beta.sum()) < 1e-9 * max(1.0, C)
            mask = (y == a) | (y == b)
            yy = np.where(y == a, 1.0, -1.0)[mask]
            bb = beta[mask]
            F = yy - K[np.ix_(mask, mask)] @ bb
            hi, lo = np.where(yy > 0, C, 0.0), np.where(yy > 0, 0.0, -C)
            gap = F[bb < hi].max() - F[bb > lo].min()
            assert gap < 1e-3 + 1e-9
            np.testing.assert_allclose(dec[:, p], K[:, mask] @ bb + est._intercept.numpy()[p],
                                       atol=1e-8)
            p += 1


# ---------------------------------------------------------------------- GPU
@pytest.mark.gpu
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_cuda_matches_cpu():
    X, y = make_blobs(n_samples=600, centers=5, n_features=8, cluster_std=3.0, random_state=0)
    cpu = KernelSVC(multiclass="ovo").fit(X, y)
    gpu = KernelSVC(multiclass="ovo", device="cuda").fit(X, y)
    assert gpu._dual_coef.device.type == "cuda"
    np.testing.assert_allclose(gpu.dual_objective_, cpu.dual_objective_, rtol=1e-6)
    np.testing.assert_array_equal(gpu.predict(X), cpu.predict(X))
    gpu.set_params(multiclass="ddag")
    assert np.mean(gpu.predict(X) == cpu.set_params(multiclass="ddag").predict(X)) >= 0.99
    # a CUDA tensor input selects the device by itself
    est = KernelSVC().fit(torch.tensor(X, device="cuda"), torch.tensor(y, device="cuda"))
    assert est._dual_coef.device.type == "cuda"
