"""Active-set refinement of pair problems that SMO has brought close to the optimum.

SMO spends most of its steps on the last digits: once the set of free
support vectors is (nearly) known, the optimum is the solution of one linear
system per pair problem.  :func:`refine` runs a primal-dual active-set method
(PDAS; Hintermüller, Ito & Kunisch 2003) on a batch of pair problems
restricted to given variables, all problems at once, starting from the SMO
iterate.  In the notation of :mod:`hlaid.svm._smo` (``beta = y * alpha`` in
``[lo, hi]``, ``sum beta = 0``, ``F = y - K beta``), the optimum is reached
when ``F_t = b`` on the free variables, ``F_t >= b`` at the upper bound and
``F_t <= b`` at the lower bound.  One iteration, for given sets of bounded
(``A``) and free (``I``) variables (first: those of the SMO iterate):

1. move the bounded variables onto their bound and solve for the free ones
   and ``b``: ``K_II d_I + b 1 = F_I - K_IA d_A``, ``1' d = 0`` (two
   Cholesky solves with ``K_II``, then ``b`` from the equality constraint);
2. ``beta += d``, ``F -= K d``;
3. free variables that left their box go to the bound they crossed, bounded
   variables whose ``F`` is on the wrong side of ``b`` are freed; only the
   violators within a fraction (:data:`SWITCH`, raised as the iterations go)
   of the largest violation switch, since switching them all (plain PDAS)
   oscillates on ill-conditioned kernels.

A problem is solved when the new point is feasible (free variables strictly
inside their box, ``sum beta`` unchanged) and libsvm's gap ``m - M`` on the
given variables is below ``tol``.  Problems whose ``K_II`` is not positive
definite, that stop switching without a solution, or that run out of
iterations are reported as failed and keep their input state; the caller
goes on with SMO.  Bounded values are set exactly (``hi``, ``lo``, 0), so the
support set is exact as in SMO.
"""

from __future__ import annotations

import math

import torch

from ._layout import compact

__all__ = ["refine"]

#: Diagonal jitter on ``K_II``, relative to its mean diagonal (float64).
JITTER = 1e-10
#: Only violators within this fraction of the largest violation switch sets
#: (doubled every 4 iterations, up to 0.5): plain PDAS switches all of them
#: and oscillates on ill-conditioned kernels.
SWITCH = 0.1


def refine(F: torch.Tensor, beta: torch.Tensor, hi: torch.Tensor, lo: torch.Tensor,
           valid: torch.Tensor, K: torch.Tensor, *, tol: float,
           max_iter: int = 30) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Primal-dual active-set solve of ``R`` pair problems (batched).

    Parameters
    ----------
    F, beta : Tensor of shape (R, N)
        Current gradient ``y - K beta`` and signed coefficients (feasible).
    hi, lo : Tensor of shape (R, N)
        Bounds of ``beta``.
    valid : BoolTensor of shape (R, N)
        Variables to optimise; the others are kept as they are (padding, or
        variables that shrinking fixed at a bound).
    K : Tensor of shape (R, N, N)
        Kernel among the ``N`` variables of each problem (working dtype).
    tol : float
        libsvm's stopping tolerance on ``m - M``.
    max_iter : int
        Active-set iterations.

    Returns
    -------
    F, beta : Tensor of shape (R, N)
        The solution where ``ok``, else the input values.
    ok : BoolTensor of shape (R,)
        Problems solved to ``tol`` (on the given variables).
    n_iter : LongTensor of shape (R,)
        Iterations used per problem.
    """
    R, N = F.shape
    dev, dt = F.device, F.dtype
    inf = math.inf
    eye = torch.eye(N, dtype=dt, device=dev)
    eps = max(JITTER, 100.0 * torch.finfo(dt).eps) * float(K.diagonal(dim1=1, dim2=2).mean())
    slack = 1024.0 * torch.finfo(dt).eps * float(hi.abs().amax()) * N
    arN = torch.arange(N, device=dev)
    arR = torch.arange(R, device=dev)
    F_out, beta_out = F.clone(), beta.clone()
    ok = torch.zeros(R, dtype=torch.bool, device=dev)
    n_iter = torch.zeros(R, dtype=torch.long, device=dev)

    # state of the problems still running (rows ``idx`` of the input)
    idx = torch.arange(R, device=dev)
    Fc, bc, beta0, hi_, lo_, v_, K_ = F, beta, beta, hi, lo, valid, K
    m = torch.where(v_ & (bc < hi_), Fc, -inf).amax(1)
    M = torch.where(v_ & (bc > lo_), Fc, inf).amin(1)
    b = torch.where(torch.isfinite(m) & torch.isfinite(M), (m + M) / 2, torch.zeros_like(m))
    at_hi = v_ & (bc >= hi_)                  # start from SMO's bounded and free variables
    at_lo = v_ & ~at_hi & (bc <= lo_)
    run = torch.ones(R, dtype=torch.bool, device=dev)
    for k in range(max_iter):
        r = idx.shape[0]
        n_iter.index_add_(0, idx, run.long())
        free = v_ & ~(at_hi | at_lo)
        target = torch.where(at_hi, hi_, torch.where(at_lo, lo_, bc))
        dA = target - bc                                   # 0 on free and fixed variables
        # 1. free variables first (padded with identity rows): K_II, then b and d_I
        nI = free.sum(1)
        Nm = max(1, int(nI.max()))
        order = compact(free)[:, :Nm]
        Im = arN[None, :Nm] < nI[:, None]
        Imf = Im.to(dt)
        rows = (order + (arR[:r] * N)[:, None]).view(-1)
        Krows = K_.view(r * N, N).index_select(0, rows).view(r, Nm, N)
        KII = torch.where(Im[:, :, None] & Im[:, None, :],
                          Krows.gather(2, order[:, None, :].expand(r, Nm, Nm)), eye[:Nm, :Nm])
        KII.diagonal(dim1=1, dim2=2).add_(Imf, alpha=eps)
        chol, info = torch.linalg.cholesky_ex(KII)
        rI = (Fc.gather(1, order) - torch.bmm(Krows, dA[:, :, None]).squeeze(2)).mul_(Imf)
        u, v = torch.cholesky_solve(torch.stack([Imf, rI], 2), chol).unbind(2)
        b_new = torch.where(nI > 0, (v.sum(1) + dA.sum(1)) / u.sum(1), b)
        good = (info == 0) & torch.isfinite(b_new)
        # 2. new point: bounded values exact, F updated with all moves
        d = dA.scatter_add(1, order, (v - b_new[:, None] * u).mul_(Imf))
        beta_n = torch.where(free, bc + d, target)
        F_n = Fc - torch.bmm(K_, d[:, :, None]).squeeze(2)
        m = torch.where(v_ & (beta_n < hi_), F_n, -inf).amax(1)
        M = torch.where(v_ & (beta_n > lo_), F_n, inf).amin(1)
        vp = torch.where(free, torch.maximum(beta_n - hi_, lo_ - beta_n), -inf)   # >= 0: out
        moved = torch.where(v_, beta_n - beta0, 0.0).sum(1).abs()                 # sum beta kept
        solved = run & good & (vp.amax(1) < 0) & (moved <= slack) & ((m - M) < tol)
        if bool(solved.any()):
            sidx = idx[solved]
            F_out.index_copy_(0, sidx, F_n[solved])
            beta_out.index_copy_(0, sidx, beta_n[solved])
            ok.index_fill_(0, sidx, True)
        # 3. the worst primal violators (free variables outside the box) go to
        # their bound, the worst dual violators (bounded variables whose F is on
        # the wrong side of b) are freed
        vd = torch.where(at_hi, b_new[:, None] - F_n,
                         torch.where(at_lo, F_n - b_new[:, None], -inf))
        frac = min(0.5, SWITCH * 2 ** (k // 4))          # more conservative as it goes
        mp = (vp >= 0) & (vp >= frac * vp.amax(1, keepdim=True))
        md = (vd > 0) & (vd >= frac * vd.amax(1, keepdim=True))
        run = run & ~solved & good & (mp | md).any(1)      # else solved or stuck: stop
        n_run = int(run.sum())
        if n_run == 0:
            break
        Fc, bc, b = F_n, beta_n, b_new
        at_hi = (at_hi & ~md) | (mp & (beta_n >= hi_))
        at_lo = (at_lo & ~md) | (mp & (beta_n <= lo_))
        if n_run <= (3 * r) // 4:                         # drop the finished problems
            keep = run.nonzero().squeeze(1)
            idx, Fc, bc, b, beta0, hi_, lo_, v_, K_, at_hi, at_lo, run = (
                t.index_select(0, keep) for t in (idx, Fc, bc, b, beta0, hi_, lo_, v_, K_,
                                                   at_hi, at_lo, run))
    return F_out, beta_out, ok, n_iter
