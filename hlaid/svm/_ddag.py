"""Combining the one-vs-one binary machines into a multi-class decision.

:class:`PairwiseMachines` holds the ``m (m - 1) / 2`` trained machines, built from
scikit-learn's SVC attributes (``support_vectors_``, ``dual_coef_``, ``n_support_``,
``intercept_``):

* the support vectors, grouped by class (``starts[c] .. starts[c] + n_support[c]``);
* ``V`` (n_SV, m): ``V[k, o]`` is the coefficient of support vector ``k`` (of class ``c``)
  in the machine separating ``c`` from ``o`` (0 for ``o = c``);
* ``b`` (n_pairs,): machine offsets (``intercept_`` before scikit-learn's binary sign
  flip); the machine ``(a, b)``, ``a < b``, says ``a`` when its value is positive.

For a block of samples the kernel against all support vectors is one matrix product, and
``S[:, c, o] = K[:, class c] @ V[class c, o]`` (one small product per class) holds every
machine's two halves: machine ``(a, b)`` is ``S[:, a, b] + S[:, b, a] + b_ab``. That is
``n_SV * m`` multiply-adds a sample for all machines (a dense coefficient matrix would be
``n_SV * n_pairs``).

Combination rules (registry :data:`MULTICLASS`):

* ``"ddag"``: Decision Directed Acyclic Graph (Platt, Cristianini &
  Shawe-Taylor, 2000).  Each sample starts with the candidate list
  ``[0, ..., m-1]`` and evaluates the machine (first, last); the loser is
  removed, so ``m - 1`` binary evaluations per sample (read from ``S``), all
  samples in a block at once.
* ``"ovo"``: libsvm's max-wins voting over all machines (ties go to the
  smaller class index), identical to :meth:`sklearn.svm.SVC.predict`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from ._kernels import Kernel

__all__ = ["MULTICLASS", "PairwiseMachines", "ovr_decision", "predict_ddag",
           "predict_vote", "resolve_multiclass"]

#: Kernel entries per prediction block (bounds the temporary memory).
BLOCK_ELEMENTS = 1 << 22


def pair_index(m: int, device: torch.device | str | None = None) -> torch.Tensor:
    """Table ``(m, m)`` of machine indices in libsvm order (symmetric, -1 on the diagonal).

    Parameters
    ----------
    m : int
        Number of classes.
    device : torch.device, optional

    Returns
    -------
    LongTensor of shape (m, m)
    """
    pairs = torch.combinations(torch.arange(m, device=device), 2)
    tab = torch.full((m, m), -1, dtype=torch.long, device=device)
    idx = torch.arange(pairs.shape[0], device=device)
    tab[pairs[:, 0], pairs[:, 1]] = idx
    tab[pairs[:, 1], pairs[:, 0]] = idx
    return tab


class PairwiseMachines:
    """All one-vs-one machines of a fitted multi-class SVC, ready to evaluate.

    Parameters
    ----------
    kernel : Kernel
    support_vectors : Tensor of shape (n_SV, n_features)
        Grouped by class (scikit-learn's ``support_vectors_``).
    dual_coef : Tensor of shape (n_classes - 1, n_SV)
        libsvm's one-vs-one layout, before the binary sign flip.
    n_support : LongTensor of shape (n_classes,)
    intercept : Tensor of shape (n_pairs,)
        ``-rho`` per machine, before the binary sign flip.
    """

    def __init__(self, kernel: Kernel, support_vectors: torch.Tensor, dual_coef: torch.Tensor,
                 n_support: torch.Tensor, intercept: torch.Tensor) -> None:
        dev, dt = support_vectors.device, support_vectors.dtype
        # the layout is index work on small arrays: numpy, then one copy to the device
        ns = n_support.detach().cpu().numpy().astype(np.int64)
        dc = dual_coef.detach().cpu().numpy()
        m = int(ns.shape[0])
        self.kernel, self.m = kernel, m
        self.starts = (np.cumsum(ns) - ns).tolist()
        self.counts = ns.tolist()
        cls_of = np.repeat(np.arange(m), ns)
        # V[k, o]: libsvm keeps the coefficient of SV k (class c) in machine (c, o) in row
        # o - 1 of dual_coef when o > c, in row o when o < c
        o = np.arange(m)
        row = np.where(o[None, :] > cls_of[:, None], o[None, :] - 1, o[None, :])
        V = dc[np.minimum(row, max(m - 2, 0)), np.arange(cls_of.shape[0])[:, None]]
        V[np.arange(cls_of.shape[0]), cls_of] = 0.0
        pa, pb = np.triu_indices(m, 1)
        tab = np.full((m, m), -1, np.int64)
        tab[pa, pb] = tab[pb, pa] = np.arange(pa.shape[0])

        def put(a: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(a)).to(dev)

        self.pidx = put(tab)
        self.pairs = put(np.stack([pa, pb], 1).astype(np.int64))
        self.V = put(V).to(dt)
        self.b = intercept.to(device=dev, dtype=dt)
        self._sv_prep = kernel.prepare(support_vectors.to(device=dev, dtype=dt))

    def partial_sums(self, X: torch.Tensor):
        """Yield ``(start, S)`` for blocks of samples: ``S`` (B, m, m) as in the module
        docstring.

        Parameters
        ----------
        X : Tensor of shape (n_samples, n_features)
        """
        B = max(1, BLOCK_ELEMENTS // max(1, self.V.shape[0]))
        m = self.m
        for s in range(0, X.shape[0], B):
            Kb = self.kernel(self.kernel.prepare_left(X[s:s + B]), self._sv_prep, prepared=True)
            S = Kb.new_zeros(Kb.shape[0], m, m)
            for c, (k0, n) in enumerate(zip(self.starts, self.counts)):
                if n:
                    S[:, c] = Kb[:, k0:k0 + n] @ self.V[k0:k0 + n]
            yield s, S

    def decision_ovo(self, X: torch.Tensor) -> torch.Tensor:
        """Decision values of every machine.

        Parameters
        ----------
        X : Tensor of shape (n_samples, n_features)

        Returns
        -------
        Tensor of shape (n_samples, n_pairs)
            Column ``p`` is machine ``pairs[p] = (a, b)``; positive means ``a``.
        """
        pa, pb = self.pairs[:, 0], self.pairs[:, 1]
        out = X.new_empty(X.shape[0], self.pairs.shape[0])
        for s, S in self.partial_sums(X):
            out[s:s + S.shape[0]] = S[:, pa, pb] + S[:, pb, pa] + self.b
        return out


def ovr_decision(dec: torch.Tensor, m: int) -> torch.Tensor:
    """One-vs-rest shaped scores from one-vs-one values (as scikit-learn's SVC).

    Votes plus confidences squashed into ``(-1/3, 1/3)``, exactly as
    ``sklearn.utils.multiclass._ovr_decision_function(dec < 0, -dec, m)``.

    Parameters
    ----------
    dec : Tensor of shape (n_samples, n_pairs)
    m : int

    Returns
    -------
    Tensor of shape (n_samples, m)
    """
    pairs = torch.combinations(torch.arange(m, device=dec.device), 2)
    n = dec.shape[0]
    win = torch.where(dec > 0, pairs[:, 0], pairs[:, 1])
    votes = torch.zeros(n, m, dtype=dec.dtype, device=dec.device)
    votes.scatter_add_(1, win, torch.ones_like(dec))
    conf = torch.zeros(n, m, dtype=dec.dtype, device=dec.device)
    conf.index_add_(1, pairs[:, 0], dec)
    conf.index_add_(1, pairs[:, 1], -dec)
    return votes + conf / (3 * (conf.abs() + 1))


def predict_vote(machines: PairwiseMachines, X: torch.Tensor) -> torch.Tensor:
    """libsvm max-wins voting over all machines.

    Parameters
    ----------
    machines : PairwiseMachines
    X : Tensor of shape (n_samples, n_features)

    Returns
    -------
    LongTensor of shape (n_samples,)
        Class indices; ties go to the smallest index.
    """
    dec = machines.decision_ovo(X)
    pairs = machines.pairs
    win = torch.where(dec > 0, pairs[:, 0], pairs[:, 1])
    votes = torch.zeros(X.shape[0], machines.m, dtype=torch.long, device=X.device)
    votes.scatter_add_(1, win, torch.ones_like(win))
    return votes.argmax(1)   # first maximum, like libsvm


def predict_ddag(machines: PairwiseMachines, X: torch.Tensor) -> torch.Tensor:
    """Decision DAG: ``m - 1`` binary evaluations per sample.

    Parameters
    ----------
    machines : PairwiseMachines
    X : Tensor of shape (n_samples, n_features)

    Returns
    -------
    LongTensor of shape (n_samples,)
        Class indices.
    """
    m = machines.m
    bias = machines.b.index_select(0, machines.pidx.clamp_min(0).view(-1))   # (m * m,)
    out = torch.empty(X.shape[0], dtype=torch.long, device=X.device)
    for s, S in machines.partial_sums(X):
        B = S.shape[0]
        flat = S.reshape(B, m * m)
        lo = torch.zeros(B, dtype=torch.long, device=X.device)
        hi = torch.full((B,), m - 1, dtype=torch.long, device=X.device)
        for _ in range(m - 1):
            # machine (lo, hi): its two halves and its offset
            key = lo * m + hi
            d = (flat.gather(1, key[:, None]).squeeze(1) + flat.gather(1, (hi * m + lo)[:, None]).squeeze(1)
                 + bias.index_select(0, key))
            lo_wins = (d > 0).long()
            hi = hi - lo_wins
            lo = lo + 1 - lo_wins
        out[s:s + B] = lo
    return out


#: Registry of multi-class combination rules: name -> predict function.
MULTICLASS: dict[str, Callable[[PairwiseMachines, torch.Tensor], torch.Tensor]] = {
    "ddag": predict_ddag,
    "ovo": predict_vote,
}


def resolve_multiclass(name: str) -> Callable[[PairwiseMachines, torch.Tensor], torch.Tensor]:
    """Look up a combination rule.

    Parameters
    ----------
    name : str
        Key of :data:`MULTICLASS`.

    Raises
    ------
    ValueError
        If ``name`` is unknown; the message lists the valid names.
    """
    try:
        return MULTICLASS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"Unknown multiclass rule {name!r}; valid rules are {sorted(MULTICLASS)}."
        ) from None
