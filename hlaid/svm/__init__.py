"""Kernel support vector machines in torch.

:class:`KernelSVC` is a multi-class C-SVC whose one-vs-one binary machines
are trained together by a batched SMO solver (second-order working-set
selection, as libsvm; nearly solved machines are finished by a batched
active-set solve, under libsvm's stopping rule) and combined by a Decision Directed Acyclic Graph
(``multiclass="ddag"``) or by one-vs-one voting (``multiclass="ovo"``).

Registries
----------
KERNELS : dict
    Kernel name -> :class:`Kernel` subclass (``rbf``, ``linear``, ``poly``,
    ``sigmoid``).
MULTICLASS : dict
    Combination rule name -> predict function (``ddag``, ``ovo``).
"""

from ._ddag import MULTICLASS, PairwiseMachines, predict_ddag, predict_vote
from ._kernels import KERNELS, Kernel, make_kernel, resolve_gamma
from ._smo import SMOResult, smo_ovo
from ._svc import KernelSVC

__all__ = ["KERNELS", "MULTICLASS", "Kernel", "KernelSVC", "PairwiseMachines", "SMOResult",
           "make_kernel", "predict_ddag", "predict_vote", "resolve_gamma", "smo_ovo"]
