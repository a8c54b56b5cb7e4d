"""Kernel functions for :mod:`hlaid.svm` and their registry.

Every kernel is a small class holding its hyper-parameters and computing
blocks ``K[a, b] = k(A[a], B[b])`` with dense matrix products, so that a
block of kernel rows costs one GEMM plus one element-wise pass.  The
formulas are those of scikit-learn / libsvm:

* ``linear``  ``<x, z>``
* ``poly``    ``(gamma <x, z> + coef0) ** degree``
* ``rbf``     ``exp(-gamma ||x - z||^2)``
* ``sigmoid`` ``tanh(gamma <x, z> + coef0)``

``gamma="scale"`` and ``gamma="auto"`` are resolved by :func:`resolve_gamma`
exactly as :class:`sklearn.svm.SVC` does.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import torch

__all__ = ["KERNELS", "Kernel", "LinearKernel", "PolyKernel", "RBFKernel",
           "SigmoidKernel", "make_kernel", "resolve_gamma"]


def resolve_gamma(gamma: str | float, X: np.ndarray | torch.Tensor) -> float:
    """Resolve ``gamma`` as :class:`sklearn.svm.SVC` does.

    Parameters
    ----------
    gamma : {"scale", "auto"} or float
        ``"scale"`` gives ``1 / (n_features * X.var())`` (``1.0`` when the
        variance is zero), ``"auto"`` gives ``1 / n_features``, a number is
        returned unchanged.
    X : array of shape (n_samples, n_features)
        Training data; the variance is taken over all its entries.

    Returns
    -------
    gamma : float
    """
    n_features = X.shape[1]
    if isinstance(gamma, str):
        if gamma == "scale":
            if isinstance(X, torch.Tensor):
                var = float(X.to(torch.float64).var(unbiased=False))
            else:
                var = float(np.asarray(X, dtype=np.float64).var())
            return 1.0 / (n_features * var) if var != 0 else 1.0
        if gamma == "auto":
            return 1.0 / n_features
        raise ValueError(
            f"gamma must be 'scale', 'auto' or a non-negative float; got {gamma!r}."
        )
    return float(gamma)


class Kernel:
    """Base class: a positive semi-definite kernel on row vectors.

    Parameters
    ----------
    gamma : float
        Kernel coefficient (ignored by ``linear``).
    degree : int
        Degree of ``poly``.
    coef0 : float
        Independent term of ``poly`` and ``sigmoid``.
    """

    name: ClassVar[str] = ""
    #: The kernel's code in the compiled solver (:mod:`hlaid.svm._solver`), which evaluates it
    #: by this number.
    code: ClassVar[int] = -1
    #: True when ``k(x, x)`` is the same constant for every ``x``.
    constant_diag: ClassVar[bool] = False

    def __init__(self, gamma: float = 1.0, degree: int = 3, coef0: float = 0.0) -> None:
        self.gamma = float(gamma)
        self.degree = int(degree)
        self.coef0 = float(coef0)

    def prepare(self, B: torch.Tensor) -> torch.Tensor:
        """Right-hand operand in the form :meth:`__call__` wants (cacheable).

        Parameters
        ----------
        B : Tensor of shape (n_b, n_features)

        Returns
        -------
        Tensor of shape (n_b, n_features_aug)
        """
        return B

    def prepare_left(self, A: torch.Tensor) -> torch.Tensor:
        """Left-hand operand in the form :meth:`__call__` wants.

        Parameters
        ----------
        A : Tensor of shape (n_a, n_features)

        Returns
        -------
        Tensor of shape (n_a, n_features_aug)
        """
        return A

    def _finish(self, G: torch.Tensor) -> torch.Tensor:
        """Turn the product block into kernel values, in place."""
        return G

    def __call__(self, A: torch.Tensor, B: torch.Tensor, *, prepared: bool = False,
                 out: torch.Tensor | None = None) -> torch.Tensor:
        """Kernel block ``K[a, b] = k(A[a], B[b])``.

        Parameters
        ----------
        A : Tensor of shape (n_a, n_features)
        B : Tensor of shape (n_b, n_features)
            Or the outputs of :meth:`prepare_left` / :meth:`prepare` when
            ``prepared`` is true; prepared operands may carry a leading batch
            dimension, ``(batch, n_a, .)`` and ``(batch, n_b, .)``, giving
            ``(batch, n_a, n_b)``.
        prepared : bool
            Whether ``A`` and ``B`` were already passed through ``prepare*``.
        out : Tensor of shape (n_a, n_b), optional
            Contiguous tensor (same dtype) to write the result into.

        Returns
        -------
        K : Tensor of shape (n_a, n_b)
        """
        if not prepared:
            A, B = self.prepare_left(A), self.prepare(B)
        if out is None:
            G = torch.matmul(A, B.transpose(-1, -2))
        else:
            G = torch.mm(A, B.T, out=out)
        return self._finish(G)

    def diag(self, A: torch.Tensor) -> torch.Tensor:
        """Diagonal ``k(A[a], A[a])``.

        Parameters
        ----------
        A : Tensor of shape (n_samples, n_features)

        Returns
        -------
        Tensor of shape (n_samples,)
        """
        return self._finish((A * A).sum(dim=1))

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(gamma={self.gamma!r}, degree={self.degree!r}, "
                f"coef0={self.coef0!r})")


class LinearKernel(Kernel):
    """``k(x, z) = <x, z>``."""

    name = "linear"
    code = 1


class PolyKernel(Kernel):
    """``k(x, z) = (gamma <x, z> + coef0) ** degree``."""

    name = "poly"
    code = 2

    def _finish(self, G: torch.Tensor) -> torch.Tensor:
        return G.mul_(self.gamma).add_(self.coef0).pow_(self.degree)


class SigmoidKernel(Kernel):
    """``k(x, z) = tanh(gamma <x, z> + coef0)`` (not positive semi-definite in general)."""

    name = "sigmoid"
    code = 3

    def _finish(self, G: torch.Tensor) -> torch.Tensor:
        return G.mul_(self.gamma).add_(self.coef0).tanh_()


class RBFKernel(Kernel):
    """``k(x, z) = exp(-gamma ||x - z||^2)``.

    The squared distance is expanded as libsvm does,
    ``|x|^2 + |z|^2 - 2 <x, z>``, and folded into a single GEMM by augmenting
    the operands: ``[x, |x|^2, 1] . [2 gamma z, -gamma, -gamma |z|^2]``,
    followed by one in-place ``exp``.  Rounding can leave values a few ulps
    above 1 for (near-)identical points; callers that need ``K <= 1`` clamp
    what they use (the SMO solver floors the curvature instead).
    """

    name = "rbf"
    code = 0
    constant_diag = True

    def prepare_left(self, A: torch.Tensor) -> torch.Tensor:
        sq = (A * A).sum(dim=1, keepdim=True)
        return torch.cat([A, sq, torch.ones_like(sq)], dim=1)

    def prepare(self, B: torch.Tensor) -> torch.Tensor:
        g = self.gamma
        sq = (B * B).sum(dim=1, keepdim=True)
        return torch.cat([B * (2.0 * g), torch.full_like(sq, -g), sq * (-g)], dim=1)

    def _finish(self, G: torch.Tensor) -> torch.Tensor:
        return G.exp_()

    def diag(self, A: torch.Tensor) -> torch.Tensor:
        return torch.ones(A.shape[0], dtype=A.dtype, device=A.device)


#: Registry of kernels: name -> class.
KERNELS: dict[str, type[Kernel]] = {
    cls.name: cls for cls in (RBFKernel, LinearKernel, PolyKernel, SigmoidKernel)
}


def make_kernel(name: str, *, gamma: float = 1.0, degree: int = 3, coef0: float = 0.0) -> Kernel:
    """Instantiate a registered kernel.

    Parameters
    ----------
    name : str
        Key of :data:`KERNELS`.
    gamma, degree, coef0 :
        Kernel hyper-parameters (resolved ``gamma``, a float).

    Returns
    -------
    Kernel

    Raises
    ------
    ValueError
        If ``name`` is not registered; the message lists the valid names.
    """
    try:
        cls = KERNELS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"Unknown kernel {name!r}; valid kernels are {sorted(KERNELS)}."
        ) from None
    return cls(gamma=gamma, degree=degree, coef0=coef0)
