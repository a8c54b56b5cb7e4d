"""Kernel support vector machines: compiled solver, torch model.

:class:`KernelSVC` is a multi-class C-SVC whose one-vs-one binary machines are trained by a
compiled (numba) port of libsvm's solver (second-order working-set selection, shrinking, a
kernel-row cache, libsvm's stopping rule: the same iterations as scikit-learn's ``SVC``), all
machines of a fit, or of many fits (:func:`fit_many`), in one call, in parallel over the cores.
The fitted machines, the kernel and prediction are torch tensors; they are combined by a
Decision Directed Acyclic Graph (``multiclass="ddag"``) or by one-vs-one voting
(``multiclass="ovo"``).

Registries
----------
KERNELS : dict
    Kernel name -> :class:`Kernel` subclass (``rbf``, ``linear``, ``poly``,
    ``sigmoid``).
MULTICLASS : dict
    Combination rule name -> predict function (``ddag``, ``ovo``).
"""

from ._batch import fit_many
from ._ddag import MULTICLASS, PairwiseMachines, predict_ddag, predict_vote
from ._kernels import KERNELS, Kernel, make_kernel, resolve_gamma
from ._svc import KernelSVC

__all__ = ["KERNELS", "MULTICLASS", "Kernel", "KernelSVC", "PairwiseMachines", "fit_many",
           "make_kernel", "predict_ddag", "predict_vote", "resolve_gamma"]
