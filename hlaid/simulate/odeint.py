"""Replay with torchdiffeq: integrate :class:`~hlaid.model.BoucWenBuilding` with ``odeint``.

Fixed-step solvers take a step of ``dt / substeps``; adaptive solvers are told the record's
sample times as step points (``options={"step_t": ...}``), because the ground acceleration
has a kink at every sample and ``sign()`` makes the field non-smooth.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
import torchdiffeq

from ..errors import InputError
from ..model import BoucWenBuilding, Building, BuildingTensors
from ..motions import GroundMotion
from .batch import SimulationResult, result_from_states

FIXED_STEP = ("rk4", "euler", "midpoint", "explicit_adams", "implicit_adams")
ADAPTIVE = ("dopri5", "dopri8", "bosh3", "fehlberg2", "adaptive_heun")
SOLVERS = FIXED_STEP + ADAPTIVE
"""torchdiffeq methods that :func:`replay` accepts."""


def replay(buildings: Building | Sequence[Building] | BuildingTensors, motion: GroundMotion, *,
           method: str = "rk4", substeps: int = 4, rtol: float = 1e-7, atol: float = 1e-6,
           adjoint: bool = False, y0: torch.Tensor | None = None, scale: float = 1.0) -> SimulationResult:
    """Integrate buildings under one ground motion with torchdiffeq.

    Parameters
    ----------
    buildings : one or more buildings (batched), or batched tensors (e.g. with gradients)
    motion : the ground motion; the response is returned at its sample times
    method : a torchdiffeq method in :data:`SOLVERS`
    substeps : fixed-step solvers take ``dt / substeps`` steps
    rtol, atol : tolerances of adaptive solvers
    adjoint : use ``odeint_adjoint`` (memory-light gradients)
    y0 : (batch, 4*story) initial state; None starts at rest
    scale : factor applied to the motion

    Returns
    -------
    SimulationResult with histories ``(batch, time, story)``.
    """
    if method not in SOLVERS:
        raise InputError(f"unknown replay method {method!r}; expected one of {list(SOLVERS)}")
    model = replay_module(buildings, motion, scale=scale)
    states = integrate_module(model, motion, method=method, substeps=substeps, rtol=rtol, atol=atol,
                              adjoint=adjoint, y0=y0).detach().numpy()
    B, T = states.shape[:2]
    return result_from_states(model.params, states, final_state=states[:, -1], dt=np.full(B, motion.dt),
                              n_time=np.full(B, T), building_index=np.arange(B), motion_index=np.zeros(B, int),
                              scale=np.full(B, float(scale)),
                              status=np.where(np.isfinite(states[:, -1]).all(1), 0, 2))


def replay_module(buildings, motion: GroundMotion, scale: float = 1.0) -> BoucWenBuilding:
    """The module of ``buildings`` driven by ``motion``, ready for ``odeint``."""
    if isinstance(buildings, BuildingTensors):
        params = buildings
    else:
        params = BuildingTensors.stack([buildings] if isinstance(buildings, Building) else list(buildings))
    g = torch.as_tensor(motion.acc * scale, dtype=params.mass.dtype, device=params.mass.device)
    return BoucWenBuilding(params, g.expand(params.batch_size, -1), motion.dt)


def integrate_module(model: BoucWenBuilding, motion: GroundMotion, *, method: str = "rk4", substeps: int = 4,
                     rtol: float = 1e-7, atol: float = 1e-6, adjoint: bool = False,
                     y0: torch.Tensor | None = None) -> torch.Tensor:
    """Differentiable state history ``(batch, time, 4*story)`` at the motion's sample times."""
    dtype, device = model.params.mass.dtype, model.params.mass.device
    t = torch.arange(motion.npts, dtype=dtype, device=device) * motion.dt
    y0 = model.initial_state() if y0 is None else y0
    options: dict[str, float | torch.Tensor]
    if method in FIXED_STEP:
        options = {"step_size": motion.dt / substeps}
    else:
        options = {"step_t": t}
    solve = torchdiffeq.odeint_adjoint if adjoint else torchdiffeq.odeint
    kwargs = {"adjoint_params": tuple(p for p in vars(model.params).values() if p.requires_grad)} if adjoint else {}
    ys = solve(model, y0, t, method=method, rtol=rtol, atol=atol, options=options, **kwargs)
    return ys.movedim(0, 1)
