"""Input conversions and checks of :class:`hlaid.svm.KernelSVC` (those scikit-learn's
``validate_data`` does not do for it)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

DTYPES = {"float64": torch.float64, "float32": torch.float32}


def to_numpy(a: Any) -> Any:
    """Tensors to numpy (host copy); anything else unchanged."""
    if isinstance(a, torch.Tensor):
        return a.detach().cpu().numpy()
    return a


def plain_fit_input(X: Any, y: Any) -> bool:
    """Finite float64 samples (2-D, not empty) and integer labels of the same length: the
    input of a pipeline's fits, which scikit-learn's checks would accept unchanged, so it is
    taken as it is (the checks cost about a millisecond a fit); anything else goes through
    them."""
    return (type(X) is np.ndarray and X.dtype == np.float64 and X.ndim == 2 and X.shape[0] > 0
            and X.shape[1] > 0 and type(y) is np.ndarray and y.ndim == 1 and y.dtype.kind in "iu"
            and y.shape[0] == X.shape[0] and bool(np.isfinite(X).all()))


def plain_predict_input(X: Any, n_features: int, has_names: bool) -> bool:
    """The same at prediction: finite float64 samples with the fitted number of features, for a
    model fitted without feature names."""
    return (type(X) is np.ndarray and X.dtype == np.float64 and X.ndim == 2 and X.shape[0] > 0
            and X.shape[1] == n_features and not has_names and bool(np.isfinite(X).all()))


def resolve_dtype(dtype: Any) -> torch.dtype:
    """``torch.float64`` / ``torch.float32`` (or their names); anything else is an error."""
    if isinstance(dtype, torch.dtype) and dtype in DTYPES.values():
        return dtype
    if isinstance(dtype, str) and dtype in DTYPES:
        return DTYPES[dtype]
    raise ValueError(f"dtype must be torch.float64 or torch.float32; got {dtype!r}.")


def np_dtype(dtype: torch.dtype) -> np.dtype:
    """The numpy dtype of a working dtype."""
    return np.dtype(np.float32) if dtype == torch.float32 else np.dtype(np.float64)
