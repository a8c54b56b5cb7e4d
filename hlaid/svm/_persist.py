"""The KernelSVC model file: one ``torch.save`` dictionary of tensors, strings and numbers
(loadable with ``weights_only=True``), written atomically, checked on reading."""

from __future__ import annotations

import os

import numpy as np
import torch

from .._fileio import atomic_write
from ..errors import InputError

FORMAT = "hlaid.svm.KernelSVC"
FORMAT_VERSION = 1


def model_state(est) -> dict:
    """The state dictionary of a fitted :class:`~hlaid.svm.KernelSVC` (what :func:`write_state`
    stores)."""
    params = est.get_params()
    params["dtype"] = str(params["dtype"]).replace("torch.", "")
    params["device"] = None if params["device"] is None else str(params["device"])
    return {
        "params": params,
        "classes": est.classes_,
        "gamma_": float(est.gamma_),
        "n_features_in_": int(est.n_features_in_),
        "feature_names_in_": (est.feature_names_in_.tolist()
                              if hasattr(est, "feature_names_in_") else None),
        "support_": torch.from_numpy(est.support_.astype(np.int64)),
        "support_vectors_": torch.from_numpy(np.ascontiguousarray(est.support_vectors_)),
        "n_support_": torch.from_numpy(est.n_support_.astype(np.int64)),
        "dual_coef": est._dual_coef.cpu(),
        "intercept": est._intercept.cpu(),
        "n_iter_": torch.from_numpy(np.asarray(est.n_iter_, dtype=np.int64)),
        "dual_objective_": torch.from_numpy(np.asarray(est.dual_objective_)),
        "fit_status_": int(est.fit_status_),
        "shape_fit_": list(est.shape_fit_),
    }


def write_state(path: str | os.PathLike, state: dict, *, force: bool) -> None:
    """Write a fitted model's ``state`` (its ``classes`` as an array) to ``path`` atomically.

    Raises ValueError for class labels that are not integers, floats, booleans or strings.
    """
    classes = np.asarray(state["classes"])
    if classes.dtype.kind not in "biufU":
        raise ValueError("save() supports integer, float, boolean or string class labels; "
                         f"got classes_ of dtype {classes.dtype}.")
    full = {"format": FORMAT, "version": FORMAT_VERSION, **state,
            "classes": classes.tolist(), "classes_dtype": classes.dtype.str}
    atomic_write(path, lambda tmp: torch.save(full, tmp), force=force)


def read_state(src: str) -> dict:
    """The state dictionary in the model file ``src``, checked for its format and version.

    Raises FileNotFoundError when ``src`` does not exist and :class:`~hlaid.errors.InputError`
    (a ValueError; the message starts with the file name) when it is not a model file.
    """
    if not os.path.exists(src):
        raise FileNotFoundError(f"{src}: file not found")
    try:
        state = torch.load(src, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise InputError(f"not a KernelSVC model file (torch.load failed: "
                         f"{type(exc).__name__})", source=src) from None
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise InputError(f"not a KernelSVC model file (expected format {FORMAT!r})", source=src)
    if state.get("version") != FORMAT_VERSION:
        raise InputError(f"KernelSVC model format version {state.get('version')!r}; "
                         f"this version reads {FORMAT_VERSION}", source=src)
    return state
