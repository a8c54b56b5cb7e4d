"""The :class:`KernelSVC` estimator (scikit-learn contract, torch inside)."""

from __future__ import annotations

import numbers
import os
from typing import Any, cast

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, column_or_1d

from .._threads import one_thread
from ..errors import InputError
from ._batch import coefficients, fit_many, prepare_fit
from ._checks import np_dtype, plain_fit_input, plain_predict_input, resolve_dtype, to_numpy
from ._ddag import PairwiseMachines, ovr_decision, resolve_multiclass
from ._kernels import KERNELS, make_kernel
from ._persist import model_state, read_state, write_state

try:  # scikit-learn >= 1.6
    from sklearn.utils.validation import validate_data as _validate_data
except ImportError:  # pragma: no cover - older scikit-learn
    def _validate_data(estimator, X="no_validation", y="no_validation", **kw):
        return estimator._validate_data(X, y, **kw)

__all__ = ["KernelSVC"]

class KernelSVC(ClassifierMixin, BaseEstimator):
    """Multi-class kernel C-SVC: libsvm's solver compiled, the model in torch.

    The ``n_classes (n_classes - 1) / 2`` one-vs-one binary machines are
    trained by a compiled port of libsvm's SMO solver (second-order
    working-set selection of Fan, Chen & Lin 2005, shrinking, a kernel-row
    cache, libsvm's stopping rule and intercept: the same iterations as
    scikit-learn's ``SVC``), all of them in one call, in parallel over the
    cores (:func:`hlaid.svm.fit_many` trains the machines of many fits
    together). They are combined by a Decision Directed Acyclic Graph (Platt
    et al. 2000) or by libsvm's one-vs-one voting.  Fitted attributes follow
    the layout of :class:`sklearn.svm.SVC`, so the two can be compared
    directly.

    Parameters
    ----------
    C : float, default=1.0
        Box constraint of the dual (``0 <= alpha <= C``), > 0.
    kernel : str, default="rbf"
        One of :data:`hlaid.svm.KERNELS` (``"rbf"``, ``"linear"``, ``"poly"``,
        ``"sigmoid"``).
    degree : int, default=3
        Degree of the ``poly`` kernel.
    gamma : {"scale", "auto"} or float, default="scale"
        Kernel coefficient, as in scikit-learn: ``"scale"`` is
        ``1 / (n_features * X.var())``, ``"auto"`` is ``1 / n_features``.
    coef0 : float, default=0.0
        Independent term of ``poly`` and ``sigmoid``.
    tol : float, default=1e-3
        The solver stops when the maximal violating pair gap
        ``m(alpha) - M(alpha)`` is below ``tol`` (per binary problem).
    max_iter : int, default=-1
        Cap on ``n_iter_`` per binary problem; ``-1`` (or None) means libsvm's
        safety cap ``max(1e7, 100 * n)``.  Stopping on the cap issues a
        :class:`~sklearn.exceptions.ConvergenceWarning`.
    shrinking : bool, default=True
        Use libsvm's shrinking heuristic (bounded variables that cannot be
        selected leave the scans; optimality is always checked on all
        variables).
    multiclass : {"ddag", "ovo"}, default="ddag"
        Combination rule used by :meth:`predict` (see
        :data:`hlaid.svm.MULTICLASS`).
    decision_function_shape : {"ovr", "ovo"}, default="ovr"
        Shape of :meth:`decision_function` for more than two classes, as in
        :class:`sklearn.svm.SVC`.
    cache_size : float, default=1024.0
        Memory for kernel rows during training, in MB, shared by the machines
        trained at the same time (one per thread); rows are float32, as
        libsvm's.
    device : str or torch.device, optional
        Device of the fitted model and of prediction; by default the device
        of ``X`` when it is a tensor, else the CPU.  Training always runs on
        the CPU.
    dtype : torch.dtype, default=torch.float64
        dtype of the fitted model and of prediction (``torch.float64`` or
        ``torch.float32``); training is in float64.

    Attributes
    ----------
    classes_ : ndarray of shape (n_classes,)
    support_ : ndarray of shape (n_SV,)
        Indices of the support vectors, grouped by class.
    support_vectors_ : ndarray of shape (n_SV, n_features)
    dual_coef_ : ndarray of shape (n_classes - 1, n_SV)
        ``y * alpha`` in libsvm's one-vs-one layout (sign flipped for two
        classes, as scikit-learn does).
    intercept_ : ndarray of shape (n_classes * (n_classes - 1) / 2,)
    n_support_ : ndarray of shape (n_classes,)
    n_features_in_ : int
    feature_names_in_ : ndarray of shape (n_features_in_,)
        Only when ``X`` had string feature names.
    gamma_ : float
        The resolved kernel coefficient.
    n_iter_ : ndarray of shape (n_classes * (n_classes - 1) / 2,)
        Solver iterations per binary problem (libsvm's).
    dual_objective_ : ndarray of shape (n_classes * (n_classes - 1) / 2,)
        Final dual objective ``1/2 a^T Q a - e^T a`` per binary problem
        (libsvm's ``obj``).
    fit_status_ : int
        0 when every binary problem converged, 1 otherwise.

    Notes
    -----
    On the CPU, :meth:`predict` and :meth:`decision_function` run on one
    torch thread and restore torch's setting on return: they are chains of
    small tensor operations, which extra threads slow down on a busy machine
    (``docs/svm.md``).  :meth:`fit` runs the machines in parallel over
    numba's threads, except in a child process (pool workers are one per
    core).
    """

    def __init__(self, *, C: float = 1.0, kernel: str = "rbf", degree: int = 3,
                 gamma: str | float = "scale", coef0: float = 0.0, tol: float = 1e-3,
                 max_iter: int | None = -1, shrinking: bool = True, multiclass: str = "ddag",
                 decision_function_shape: str = "ovr", cache_size: float = 1024.0,
                 device: str | torch.device | None = None,
                 dtype: torch.dtype = torch.float64) -> None:
        self.C = C
        self.kernel = kernel
        self.degree = degree
        self.gamma = gamma
        self.coef0 = coef0
        self.tol = tol
        self.max_iter = max_iter
        self.shrinking = shrinking
        self.multiclass = multiclass
        self.decision_function_shape = decision_function_shape
        self.cache_size = cache_size
        self.device = device
        self.dtype = dtype

    # ------------------------------------------------------------------ checks
    def _check_params(self) -> None:
        def real(name: str, lo: float, closed: bool) -> None:
            v = getattr(self, name)
            ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and np.isfinite(cast(float, v))
            if not ok or v < lo or (v == lo and not closed):
                rel = ">=" if closed else ">"
                raise ValueError(f"{name} must be a finite number {rel} {lo}; got {v!r}.")

        real("C", 0.0, False)
        real("tol", 0.0, False)
        real("cache_size", 0.0, False)
        real("coef0", -np.inf, True)
        if self.kernel not in KERNELS:
            raise ValueError(f"Unknown kernel {self.kernel!r}; valid kernels are {sorted(KERNELS)}.")
        if not isinstance(self.gamma, str):
            real("gamma", 0.0, True)
        elif self.gamma not in ("scale", "auto"):
            raise ValueError(f"gamma must be 'scale', 'auto' or a non-negative float; got {self.gamma!r}.")
        if not isinstance(self.degree, numbers.Integral) or isinstance(self.degree, bool) \
                or self.degree < 0:
            raise ValueError(f"degree must be a non-negative integer; got {self.degree!r}.")
        mi = self.max_iter
        if mi is not None and (not isinstance(mi, numbers.Integral) or isinstance(mi, bool)
                               or (mi < 1 and mi != -1)):
            raise ValueError(f"max_iter must be -1, None or a positive integer; got {mi!r}.")
        resolve_multiclass(self.multiclass)
        if self.decision_function_shape not in ("ovr", "ovo"):
            raise ValueError("decision_function_shape must be 'ovr' or 'ovo'; got "
                             f"{self.decision_function_shape!r}.")
        resolve_dtype(self.dtype)

    def _resolve_device(self, X: Any) -> torch.device:
        if self.device is None:
            return X.device if isinstance(X, torch.Tensor) else torch.device("cpu")
        try:
            return torch.device(self.device)
        except (RuntimeError, TypeError):
            raise ValueError(f"Invalid device {self.device!r}.") from None

    # --------------------------------------------------------------------- fit
    def fit(self, X: Any, y: Any) -> KernelSVC:
        """Train the one-vs-one machines.

        Parameters
        ----------
        X : array-like or Tensor of shape (n_samples, n_features)
            Training samples (finite values).
        y : array-like or Tensor of shape (n_samples,)
            Class labels; at least two classes.

        Returns
        -------
        self : KernelSVC
        """
        fit_many([self], [X], [y])
        return self

    def _prepare(self, X: Any, y: Any) -> Any:
        """Check the parameters and the data; the fit's entry in a batch (:func:`fit_many`)."""
        self._check_params()
        dtype = resolve_dtype(self.dtype)
        device = self._resolve_device(X)
        X, y = to_numpy(X), to_numpy(y)
        if plain_fit_input(X, y):
            self.n_features_in_ = X.shape[1]
            if hasattr(self, "feature_names_in_"):
                del self.feature_names_in_
            X = np.ascontiguousarray(X)
        else:
            X, y = _validate_data(self, X, y, dtype=np.float64, order="C", y_numeric=False)
            y = column_or_1d(y, warn=True)
            check_classification_targets(y)
        classes, y_enc = np.unique(y, return_inverse=True)
        if classes.shape[0] < 2:
            raise ValueError("The number of classes has to be greater than one; got "
                             f"{classes.shape[0]} class.")
        self.classes_ = classes
        return prepare_fit(self, X, y_enc.astype(np.int64), dtype, device)

    def _finish(self, f: Any, P_int: np.ndarray, alpha: np.ndarray, res_f: np.ndarray,
                res_i: np.ndarray) -> None:
        """Set the fitted attributes from the solved problems of this fit (scikit-learn's
        layout)."""
        coef = coefficients(f, P_int, alpha)
        sv_pos = np.flatnonzero((coef != 0).any(0))
        self.support_ = f.order[sv_pos].astype(np.int32)
        self.support_vectors_ = f.X[self.support_].astype(np_dtype(f.dtype))
        dual = coef[:, sv_pos]
        intercept = -res_f[:, 0]
        if not (np.isfinite(dual).all() and np.isfinite(intercept).all()):
            raise ValueError("The dual coefficients or intercepts are not finite; the input "
                             "data may contain values too large for the kernel (scale X).")
        m = self.classes_.shape[0]
        self.n_support_ = np.bincount(f.y_enc[self.support_], minlength=m).astype(np.int32)
        self.n_iter_ = res_i[:, 0].copy()
        self.dual_objective_ = res_f[:, 1].copy()
        self.fit_status_ = int((res_i[:, 1] != 0).any())
        self.shape_fit_ = f.X.shape
        with one_thread(f.device):
            self._set_model(torch.from_numpy(dual), torch.from_numpy(intercept),
                            torch.from_numpy(self.support_vectors_), f.device, f.dtype, f.kernel)

    def _set_model(self, dual: torch.Tensor, intercept: torch.Tensor, sv: torch.Tensor,
                   device: torch.device, dtype: torch.dtype, kern) -> None:
        """Store internal (libsvm-signed) tensors and the public attributes."""
        self._dual_coef = dual.to(device=device, dtype=dtype)
        self._intercept = intercept.to(device=device, dtype=dtype)
        self._device = device
        self._kernel = kern
        n_sup = torch.as_tensor(self.n_support_, dtype=torch.long, device=device)
        self._machines = PairwiseMachines(kern, sv.to(device=device, dtype=dtype),
                                          self._dual_coef, n_sup, self._intercept)
        dual_np = self._dual_coef.cpu().numpy()
        icpt_np = self._intercept.cpu().numpy()
        if len(self.classes_) == 2:  # scikit-learn's binary sign convention
            dual_np, icpt_np = -dual_np, -icpt_np
        self.dual_coef_ = dual_np
        self.intercept_ = icpt_np

    # ----------------------------------------------------------------- predict
    def _predict_input(self, X: Any) -> torch.Tensor:
        """The samples as a tensor of the model's dtype and device (call under
        :class:`one_thread`: a copy on the CPU is a parallel region)."""
        check_is_fitted(self)
        X = to_numpy(X)
        if not plain_predict_input(X, self.n_features_in_, hasattr(self, "feature_names_in_")):
            X = _validate_data(self, X, dtype=np.float64, order="C", reset=False)
        return torch.as_tensor(np.ascontiguousarray(X)).to(device=self._device,
                                                           dtype=self._dual_coef.dtype)

    def decision_function(self, X: Any) -> np.ndarray:
        """Decision values.

        Parameters
        ----------
        X : array-like or Tensor of shape (n_samples, n_features)

        Returns
        -------
        ndarray of shape (n_samples,), (n_samples, n_classes) or (n_samples, n_pairs)
            Two classes: positive means ``classes_[1]``.  Otherwise ``"ovo"``
            gives one column per machine ``(a, b)``, ``a < b`` (positive means
            ``a``), and ``"ovr"`` scikit-learn's vote-plus-confidence transform.
        """
        check_is_fitted(self)
        m = len(self.classes_)
        with torch.inference_mode(), one_thread(self._device):
            dec = self._machines.decision_ovo(self._predict_input(X))
            if m == 2:
                dec = -dec[:, 0]
            elif self.decision_function_shape == "ovr":
                dec = ovr_decision(dec, m)
            return dec.cpu().numpy()

    def predict(self, X: Any) -> np.ndarray:
        """Predict class labels with the ``multiclass`` rule.

        Parameters
        ----------
        X : array-like or Tensor of shape (n_samples, n_features)

        Returns
        -------
        ndarray of shape (n_samples,)
            Labels from ``classes_``.
        """
        check_is_fitted(self)
        rule = resolve_multiclass(self.multiclass)
        with torch.inference_mode(), one_thread(self._device):
            idx = rule(self._machines, self._predict_input(X)).cpu().numpy()
        return self.classes_[idx]

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = False
        tags.input_tags.sparse = False
        return tags

    # --------------------------------------------------------------- save/load
    def save(self, path: str | os.PathLike, *, force: bool = False) -> None:
        """Write the fitted model to one file (atomically).

        The file is a ``torch.save`` dictionary of tensors, strings and
        numbers (loadable with ``weights_only=True``); it is written to a
        temporary file in the same folder and renamed over ``path``, so a
        reader never sees a partial file.

        Parameters
        ----------
        path : str or os.PathLike
        force : bool, default False
            Replace an existing file (otherwise an existing ``path`` is an error).
        """
        check_is_fitted(self)
        write_state(path, model_state(self), force=force)

    @classmethod
    def load(cls, path: str | os.PathLike, *,
             device: str | torch.device | None = None) -> KernelSVC:
        """Load a model written by :meth:`save`.

        Parameters
        ----------
        path : str or os.PathLike
        device : str or torch.device, optional
            Where to put the model; default: the saved ``device`` parameter
            (CPU when it was None).

        Returns
        -------
        KernelSVC
            A fitted estimator.

        Raises
        ------
        FileNotFoundError
            If ``path`` does not exist.
        hlaid.errors.InputError
            (a ``ValueError``) if the file is not a KernelSVC model file; the
            message starts with the file name.
        """
        src = os.fspath(path)
        state = read_state(src)
        try:
            params = dict(state["params"])
            params["dtype"] = resolve_dtype(params["dtype"])
            if device is not None:
                params["device"] = device
            est = cls(**params)
            dtype = params["dtype"]
            dev = est._resolve_device(None)
            est.classes_ = np.asarray(state["classes"], dtype=np.dtype(state["classes_dtype"]))
            est.gamma_ = state["gamma_"]
            est.n_features_in_ = state["n_features_in_"]
            if state["feature_names_in_"] is not None:
                est.feature_names_in_ = np.asarray(state["feature_names_in_"], dtype=object)
            est.support_ = state["support_"].numpy().astype(np.int32)
            est.support_vectors_ = state["support_vectors_"].numpy()
            est.n_support_ = state["n_support_"].numpy().astype(np.int32)
            est.n_iter_ = state["n_iter_"].numpy()
            est.dual_objective_ = state["dual_objective_"].numpy()
            est.fit_status_ = state["fit_status_"]
            est.shape_fit_ = tuple(state["shape_fit_"])
            kern = make_kernel(est.kernel, gamma=est.gamma_, degree=est.degree, coef0=est.coef0)
            est._set_model(state["dual_coef"], state["intercept"], state["support_vectors_"],
                           dev, dtype, kern)
        except (KeyError, TypeError, ValueError, AttributeError, RuntimeError) as exc:
            raise InputError(f"corrupt KernelSVC model file ({type(exc).__name__}: {exc})",
                             source=src) from None
        return est
