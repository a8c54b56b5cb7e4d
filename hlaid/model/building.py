"""The degrading Bouc-Wen shear building as a torch module.

State layout (documented here once): ``y`` is ``(batch, 4*story)``, the concatenation

    y = [u, v, z, e]      each (batch, story)

``u`` floor displacement relative to the ground [mm], ``v`` its velocity [mm/s], ``z`` the
hysteretic displacement of each story [mm], ``e = integral(z dx)`` the signed hysteretic
work of each story per unit (1-alpha) k0 [mm^2]. The ground acceleration is applied to
every floor mass (``-M 1 ag``).

With a collapse model (:mod:`hlaid.model.collapse`) the state is ``(batch, 6*story)``,

    y = [u, v, z, e, xp, xn]

``xp`` and ``xn`` the largest past drift of each story in the positive and the negative
direction [mm] (>= 0, the strength-loss memory). The width of the state switches the collapse
law on; a 4-story-wide state runs the paper's law exactly as without a collapse model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, cast

import torch
from torch import nn

from . import _equations as eq
from .params import Building, BuildingTensors


def _below(a: torch.Tensor) -> torch.Tensor:
    """The value on the floor below each floor (zero under the first)."""
    return nn.functional.pad(a, (1, 0))[..., :-1]


def _above(a: torch.Tensor) -> torch.Tensor:
    """The value of the story above each story (zero above the roof)."""
    return nn.functional.pad(a, (0, 1))[..., 1:]


class BoucWenBuilding(nn.Module):
    """Right-hand side ``dy/dt = forward(t, y)`` of a batch of shear buildings (with their linear
    floor coupling where they have one: :mod:`hlaid.model.coupling`).

    One definition serves the batch simulator (checked against it to 1e-8), the torchdiffeq
    replay and gradient-based identification (it is differentiable in its parameters).

    Parameters
    ----------
    params : BuildingTensors
        Batched parameters, each ``(batch, story)``.
    ground_acc : (batch, time) tensor, optional
        Ground acceleration samples [mm/s^2] for :meth:`forward`; linearly interpolated,
        zero after the last sample.
    dt : float
        Sample interval of ``ground_acc`` [s].
    """

    def __init__(self, params: BuildingTensors, ground_acc: torch.Tensor | None = None, dt: float = 0.01):
        super().__init__()
        self.params = params
        self.n_stories = int(params.mass.shape[-1])
        self.dt = float(dt)
        self.ground_acc = ground_acc

    @classmethod
    def from_buildings(cls, buildings: Building | Sequence[Building], ground_acc=None, dt: float = 0.01,
                       dtype=torch.float64, device=None) -> BoucWenBuilding:
        if isinstance(buildings, Building):
            buildings = [buildings]
        return cls(BuildingTensors.stack(buildings, dtype=dtype, device=device), ground_acc, dt)

    # ------------------------------------------------------------------ dynamics
    @property
    def state_size(self) -> int:
        """``6*story`` with a collapse model, else ``4*story``."""
        return (6 if self.params.has_collapse else 4) * self.n_stories

    def initial_state(self) -> torch.Tensor:
        """At rest: ``(batch, state_size)`` zeros."""
        m = self.params.mass
        return torch.zeros(m.shape[0], self.state_size, dtype=m.dtype, device=m.device)

    def ground_at(self, t: torch.Tensor) -> torch.Tensor:
        """Ground acceleration at time ``t`` [mm/s^2], ``(batch,)``, linear between samples."""
        g = self.ground_acc
        if g is None:
            raise RuntimeError("BoucWenBuilding.forward needs ground_acc; give it to the constructor")
        s = torch.as_tensor(t, dtype=g.dtype) / self.dt
        k = int(torch.floor(s).clamp(0, g.shape[-1] - 1))
        if k >= g.shape[-1] - 1:
            return g[:, -1] * (s <= g.shape[-1] - 1)
        frac = s - k
        return g[:, k] + (g[:, k + 1] - g[:, k]) * frac

    def forward(self, t: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """``dy/dt`` at time ``t`` for state ``y`` ``(batch, 4*story)`` (torchdiffeq signature)."""
        return self.rates(y, self.ground_at(t))

    def rates(self, y: torch.Tensor, ag: torch.Tensor) -> torch.Tensor:
        """``dy/dt`` for state ``y`` ``(batch, 4*story)`` (or ``6*story``: collapse law) and ground
        acceleration ``ag`` ``(batch,)``."""
        P = self.params
        n = self.n_stories
        if y.shape[-1] == 6 * n:
            u, v, z, e, xp, xn = y.split(n, dim=-1)
        else:
            (u, v, z, e), xp, xn = y.split(n, dim=-1), None, None
        x, xd = u - _below(u), v - _below(v)
        eta = eq.degradation(e, P.alpha, P.k0, P.mass, P.delta_eta)
        zd = eq.hysteretic_rate(xd, z, P.dy, P.p, eta)
        acc = _absolute_acceleration(P, x, v, z, xp, xn, u) - ag[:, None]
        if xp is None:
            return torch.cat([v, acc, zd, z * xd], dim=-1)
        return torch.cat([v, acc, zd, z * xd, eq.peak_rate(x, xd, xp), eq.peak_rate(-x, -xd, xn)], dim=-1)

    def update_peaks(self, y: torch.Tensor) -> torch.Tensor:
        """After a step: the collapse memory set to ``max(xp, x)``, ``max(xn, -x)`` (no-op for 4*story)."""
        n = self.n_stories
        if y.shape[-1] != 6 * n:
            return y
        u = y[..., :n]
        x = u - _below(u)
        return torch.cat([y[..., :4 * n], torch.maximum(y[..., 4 * n:5 * n], x),
                          torch.maximum(y[..., 5 * n:], -x)], dim=-1)

    def rk4_sample(self, y: torch.Tensor, ag0: torch.Tensor, ag1: torch.Tensor, dt, substeps: int) -> torch.Tensor:
        """Advance ``y`` ``(batch, 4*story)`` over one record sample of length ``dt`` (a number or
        ``(batch, 1)``) by ``substeps`` classical RK4 steps, the ground acceleration linear from
        ``ag0`` to ``ag1`` ``(batch,)`` over the sample (the scheme of the compiled simulator)."""
        h = dt / substeps
        da = ag1 - ag0
        for s in range(substeps):
            k1 = self.rates(y, ag0 + da * (s / substeps))
            k2 = self.rates(y + 0.5 * h * k1, ag0 + da * ((s + 0.5) / substeps))
            k3 = self.rates(y + 0.5 * h * k2, ag0 + da * ((s + 0.5) / substeps))
            k4 = self.rates(y + h * k3, ag0 + da * ((s + 1.0) / substeps))
            y = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            if y.shape[-1] != 4 * self.n_stories:
                y = self.update_peaks(y)
        return y

    # ------------------------------------------------------------------ responses
    def responses(self, states: torch.Tensor) -> dict[str, torch.Tensor]:
        """Response quantities from a state history.

        Parameters
        ----------
        states : (batch, time, 4*story) or (batch, time, 6*story) (collapse law)

        Returns
        -------
        dict of (batch, time, story) tensors: ``disp``, ``vel``, ``acc`` (absolute floor
        acceleration), ``drift``, ``force`` (Bouc-Wen spring force), ``z``, ``eta``,
        ``energy`` (hysteretic work ``(1-alpha) k0 integral(z dx)`` [N mm]). With the collapse law
        ``force`` is the story force with its strength loss (P-Delta excluded).
        """
        fields: dict[str, Any] = {f.name: None if getattr(self.params, f.name) is None
                                  else getattr(self.params, f.name)[:, None] for f in dataclasses.fields(self.params)}
        P = BuildingTensors(**fields)
        n = self.n_stories
        if states.shape[-1] == 6 * n:
            u, v, z, e, xp, xn = states.split(n, dim=-1)
        else:
            (u, v, z, e), xp, xn = states.split(n, dim=-1), None, None
        x = u - _below(u)
        return {"disp": u, "vel": v, "acc": _absolute_acceleration(P, x, v, z, xp, xn, u), "drift": x,
                "force": _story_force(P, x, z, xp, xn), "z": z,
                "eta": eq.degradation(e, P.alpha, P.k0, P.mass, P.delta_eta),
                "energy": (1.0 - P.alpha) * P.k0 * e}


def _story_force(P: BuildingTensors, x, z, xp=None, xn=None):
    """Story spring force [N]: the paper's law, or the collapse law when the memory is given."""
    if xp is None:
        return eq.spring_force(x, z, P.alpha, P.k0)
    c = cast(torch.Tensor, P.collapse)  # the collapse memory (xp) is carried only with a collapse model
    return eq.collapse_spring_force(x, z, xp, xn, P.alpha, P.k0, *(c[..., j] for j in range(c.shape[-1])))


def _absolute_acceleration(P: BuildingTensors, x, v, z, xp=None, xn=None, u=None):
    """Absolute floor acceleration ``-(R(x, z) + K_c u + C v) / m`` [mm/s^2]; fields of ``P``
    broadcast; the coupling ``K_c`` (:mod:`hlaid.model.coupling`) where ``P`` has one."""
    f = _story_force(P, x, z, xp, xn) - P.kg * x  # story shear, P-Delta included
    fd = torch.einsum("...ij,...j->...i", P.damping, v)
    if P.coupling is not None:
        fd = fd + torch.einsum("...ij,...j->...i", P.coupling, u)
    return -(f - _above(f) + fd) / P.mass
