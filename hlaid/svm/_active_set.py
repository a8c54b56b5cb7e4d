"""Active-set refinement of pair problems that SMO has brought close to the optimum.

SMO spends most of its steps on the last digits: once the set of free
support vectors is (nearly) known, the optimum is the solution of one linear
system per pair problem.  :func:`refine` runs the primal-dual active-set
method (PDAS; Hintermüller, Ito & Kunisch 2003) on a batch of pair problems
restricted to given variables, all problems at once, starting from the SMO
iterate.  In the notation of :mod:`hlaid.svm._smo` (``beta = y * alpha`` in
``[lo, hi]``, ``sum beta = 0``, ``F = y - K beta``), the optimum is reached
when ``F_t = b`` on the free variables, ``F_t >= b`` at the upper bound and
``F_t <= b`` at the lower bound.  One iteration:

1. predict the bounds from ``z = beta + (F - b)``: ``z >= hi`` -> upper
   bound, ``z <= lo`` -> lower bound, the others are free (``I``);
2. move the bounded variables onto their bound and solve for the free ones
   and ``b``: ``K_II d_I + b 1 = F_I - K_IA d_A``, ``1' d = 0`` (two
   Cholesky solves with ``K_II``, then ``b`` from the equality constraint);
3. ``beta += d``, ``F -= K d``.

A problem is solved when the new point is feasible (free variables strictly
inside their box, ``sum beta = 0``) and libsvm's gap ``m - M`` on the given
variables is below ``tol``.  Problems whose ``K_II`` is not positive definite,
whose active set stops changing without a solution, or which run out of
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
#: After the first iteration, only violators within this fraction of the
#: largest violation switch sets (plain PDAS switches all of them and tends
#: to oscillate on these problems).
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
    eye = torch.eye(N, dtype=dt, device=dev).expand(R, N, N)
    eps = max(JITTER, 100.0 * torch.finfo(dt).eps) * float(K.diagonal(dim1=1, dim2=2).mean())
    slack = 1024.0 * torch.finfo(dt).eps * float(hi.abs().amax()) * N

    def gap_of(Fc: torch.Tensor, bc: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        m = torch.where(valid & (bc < hi), Fc, -inf).amax(1)
        M = torch.where(valid & (bc > lo), Fc, inf).amin(1)
        return m, M

    m, M = gap_of(F, beta)
    b = torch.where(torch.isfinite(m) & torch.isfinite(M), (m + M) / 2, torch.zeros_like(m))
    Fc, bc = F, beta
    # first prediction of the bounds: z = beta + (F - b) beyond the box
    z = bc + (Fc - b[:, None])
    at_hi = valid & (z >= hi)
    at_lo = valid & ~at_hi & (z <= lo)
    F_out, beta_out = F.clone(), beta.clone()
    ok = torch.zeros(R, dtype=torch.bool, device=dev)
    dead = torch.zeros_like(ok)
    n_iter = torch.zeros(R, dtype=torch.long, device=dev)
    arN = torch.arange(N, device=dev)
    for _ in range(max_iter):
        run = ~(ok | dead)
        n_iter += run
        free = valid & ~at_hi & ~at_lo
        target = torch.where(at_hi, hi, torch.where(at_lo, lo, bc))
        dA = target - bc                                   # 0 on free and invalid
        # free variables first, padded with identity rows
        nI = free.sum(1)
        Nm = max(1, int(nI.max()))
        order = compact(free)[:, :Nm]
        Im = arN[None, :Nm] < nI[:, None]
        Krows = K.gather(1, order[:, :, None].expand(R, Nm, N))             # (R, Nm, N)
        KII = torch.where(Im[:, :, None] & Im[:, None, :],
                          Krows.gather(2, order[:, None, :].expand(R, Nm, Nm)), eye[:, :Nm, :Nm])
        KII.diagonal(dim1=1, dim2=2).add_(Im.to(dt), alpha=eps)
        chol, info = torch.linalg.cholesky_ex(KII)
        rI = torch.where(Im, Fc.gather(1, order) - torch.bmm(Krows, dA[:, :, None]).squeeze(2), 0.0)
        sol = torch.cholesky_solve(torch.stack([Im.to(dt), rI], 2), chol)
        u, v = sol[:, :, 0], sol[:, :, 1]
        su = u.sum(1)
        good = (info == 0) & (su > 0) & torch.isfinite(su) & torch.isfinite(v).all(1)
        b_new = torch.where(nI > 0, (v.sum(1) + dA.sum(1)) / torch.where(su > 0, su, 1.0), b)
        dI = torch.where(Im, v - b_new[:, None] * u, 0.0)
        # new point: bounded values exact, F updated with all moves
        d = dA.scatter_add(1, order, dI)
        beta_n = torch.where(free, bc + d, target)
        F_n = Fc - torch.bmm(K, d[:, :, None]).squeeze(2)
        inside = ~free | ((beta_n > lo) & (beta_n < hi))
        moved = torch.where(valid, beta_n - beta, 0.0).sum(1)     # sum beta stays 0
        feasible = good & inside.all(1) & (moved.abs() <= slack)
        m, M = gap_of(F_n, beta_n)
        solved = run & feasible & ((m - M) < tol)
        F_out = torch.where(solved[:, None], F_n, F_out)
        beta_out = torch.where(solved[:, None], beta_n, beta_out)
        ok |= solved
        dead |= run & ~solved & ~good
        if bool((ok | dead).all()):
            break
        # next bounds: the worst primal violators (free variables outside the
        # box) go to their bound, the worst dual violators (bounded variables
        # whose F is on the wrong side of b) are freed
        vp = torch.where(free, torch.maximum(beta_n - hi, lo - beta_n), -inf)
        vd = torch.where(at_hi, b_new[:, None] - F_n, torch.where(at_lo, F_n - b_new[:, None], -inf))
        mp = (vp >= 0) & (vp >= SWITCH * vp.amax(1, keepdim=True))
        md = (vd > 0) & (vd >= SWITCH * vd.amax(1, keepdim=True))
        dead |= run & ~solved & ~(mp | md).any(1)          # PDAS fixed point, not optimal
        Fc = torch.where(good[:, None], F_n, Fc)
        bc = torch.where(good[:, None], beta_n, bc)
        b = torch.where(good, b_new, b)
        at_hi = (at_hi & ~md) | (mp & (beta_n >= hi))
        at_lo = (at_lo & ~md) | (mp & (beta_n <= lo))
    return F_out, beta_out, ok, n_iter
