"""The parameter space shared by the output-error identifiers (gradient, UKF).

What is known from the measurement (masses or mass ratios, P-Delta, 5 % Rayleigh damping
assumed as for every identifier) is kept apart from the unknown story parameters
``k0, alpha, p, dy, delta_eta``. The unknowns live in an unconstrained space so that any
value of the optimiser's or filter's coordinates is a valid building:

    k0        = k0_ref * exp(t)        > 0       (log, scaled by a reference stiffness)
    alpha     = sigmoid(t)             in (0, 1)
    p         = 1 + softplus(t)        > 1
    dy        = dy_ref * exp(t)        > 0       (log, scaled by a reference drift)
    delta_eta = softplus(t)            > 0

Coordinates are ``(..., 5, story)`` tensors in the order of :data:`FIELDS`. The same
prepared data (ground motion low-passed like :func:`hlaid.identify.refine_replay`, floor
accelerations) feed every identifier of this family.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ..hla import HLAConfig, run_hla
from ..hla.analysis import floor_masses
from ..measurement import Measurement
from ..model import Building, BuildingTensors, Damping
from ..model import structure as S

FIELDS = ("k0", "alpha", "p", "dy", "delta_eta")
"""Unknown story parameters, in the order of the unconstrained coordinates."""


@dataclass(frozen=True, eq=False)
class KnownPart:
    """What the identifiers take as known, from the measurement.

    Attributes
    ----------
    mass : (story,) floor masses [t], or mass ratios summing to 1 when ``mass_normalised``
    mass_normalised : masses unknown: stiffnesses are per unit total mass (as HLA)
    height : (story,) story heights [mm] or None
    pdelta : P-Delta as the measurement says
    damping : the assumed damping (Rayleigh 5 % on modes 1 and 2 by default)
    kg : (story,) P-Delta stiffness ``P/h`` [N/mm] (zeros when inactive)
    name : a label for the clone
    """

    mass: np.ndarray
    mass_normalised: bool
    height: np.ndarray | None
    pdelta: bool | None
    damping: Damping
    kg: np.ndarray
    name: str

    @property
    def n_stories(self) -> int:
        return int(self.mass.shape[0])

    def building(self, values: dict[str, np.ndarray]) -> Building:
        """The :class:`~hlaid.model.Building` of one set of story values ``(story,)``."""
        stories: dict[str, Any] = {k: np.asarray(values[k], dtype=float) for k in FIELDS}
        return Building(mass=self.mass, height=self.height, pdelta=self.pdelta, damping=self.damping,
                        name=self.name, **stories)

    def tensors(self, values: dict[str, torch.Tensor]) -> BuildingTensors:
        """Batched, differentiable module parameters of ``(batch, story)`` story values; the
        Rayleigh damping follows ``k0`` as in :meth:`Building.damping_matrix`."""
        k0 = values["k0"]
        mass = torch.tensor(self.mass, dtype=k0.dtype).expand_as(k0)
        d = self.damping
        a0, a1 = S.rayleigh_coefficients(k0, mass, d.kind, d.ratio, d.modes, d.ratio2)
        kg = torch.tensor(self.kg, dtype=k0.dtype).expand_as(k0)
        return BuildingTensors(mass=mass, k0=k0, alpha=values["alpha"], p=values["p"], dy=values["dy"],
                               delta_eta=values["delta_eta"], kg=kg, damping=S.damping_matrix(k0, mass, a0, a1))


def known_part(meas: Measurement, damping_ratio: float = 0.05, hla_config: HLAConfig | None = None) -> KnownPart:
    """Masses (or HLA's mass ratios when unknown), heights, P-Delta and damping of ``meas``."""
    mass, normalised = floor_masses(meas, hla_config or HLAConfig())
    pdelta = meas.pdelta_active if meas.height is not None else None
    b = Building(mass=mass, k0=np.ones_like(mass), alpha=np.zeros_like(mass), p=np.ones_like(mass),
                 dy=np.ones_like(mass), delta_eta=np.zeros_like(mass), height=meas.height, pdelta=pdelta)
    return KnownPart(mass=np.asarray(mass, dtype=float), mass_normalised=bool(normalised), height=meas.height,
                     pdelta=pdelta, damping=Damping(ratio=damping_ratio), kg=b.geometric_stiffness(),
                     name=meas.name)


# ---------------------------------------------------------------------- reparameterisation
def _softplus_inv(y):
    y = np.maximum(np.asarray(y, dtype=float), 1e-12)
    return np.where(y > 30.0, y, np.log(np.expm1(np.minimum(y, 30.0))))


def to_unconstrained(values: dict[str, np.ndarray], k0_ref: np.ndarray, dy_ref: np.ndarray) -> np.ndarray:
    """Coordinates ``(..., 5, story)`` of story values ``(..., story)`` (inverse of
    :func:`from_unconstrained`); values on a boundary are nudged inside."""
    a = np.clip(np.asarray(values["alpha"], dtype=float), 1e-6, 1 - 1e-6)
    cols = [np.log(np.asarray(values["k0"], dtype=float) / k0_ref), np.log(a / (1 - a)),
            _softplus_inv(np.asarray(values["p"], dtype=float) - 1.0),
            np.log(np.asarray(values["dy"], dtype=float) / dy_ref), _softplus_inv(values["delta_eta"])]
    return np.stack(cols, axis=-2)


def from_unconstrained(theta: torch.Tensor, k0_ref, dy_ref) -> dict[str, torch.Tensor]:
    """Story values ``(..., story)`` of coordinates ``theta`` ``(..., 5, story)`` (differentiable)."""
    k0_ref = torch.tensor(np.asarray(k0_ref), dtype=theta.dtype)
    dy_ref = torch.tensor(np.asarray(dy_ref), dtype=theta.dtype)
    sp = torch.nn.functional.softplus
    t = theta.unbind(-2)
    return {"k0": k0_ref * torch.exp(t[0]), "alpha": torch.sigmoid(t[1]), "p": 1.0 + sp(t[2]),
            "dy": dy_ref * torch.exp(t[3]), "delta_eta": sp(t[4])}


def values_numpy(values: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
    return {k: v.detach().cpu().numpy() for k, v in values.items()}


def hla_scales(meas: Measurement) -> tuple[np.ndarray, np.ndarray]:
    """HLA's ``k0`` and each story's peak |drift| [mm], ``(story,)`` each: the scales that place
    the starting values of the output-error identifiers (``init="hla"``)."""
    res = run_hla(meas)
    return res.k0, np.array([np.max(np.abs(s.drift)) for s in res.stories])


def draw_starts(n: int, *, k0, dy_scale, rng: np.random.Generator, alpha_range=(0.02, 0.5), p_range=(1.0, 3.0),
                dy_range=(0.1, 0.6), delta_eta_range=(0.0, 2.0), k0_spread: float = 0.0) -> dict[str, np.ndarray]:
    """``n`` starting points ``(n, story)``: the first at the middle of every range, the others
    uniform in the ranges (``dy`` as a fraction of ``dy_scale``, ``k0`` within ``+-k0_spread``
    (relative, log-uniform) of ``k0``)."""
    k0, dy_scale = np.asarray(k0, dtype=float), np.asarray(dy_scale, dtype=float)
    ns = k0.shape[0]

    def draw(lo_hi):
        lo, hi = lo_hi
        v = rng.uniform(lo, hi, size=(n, ns))
        v[0] = 0.5 * (lo + hi)
        return v

    spread = np.exp(rng.uniform(-1, 1, size=(n, ns)) * np.log1p(k0_spread))
    spread[0] = 1.0
    return {"k0": k0 * spread, "alpha": draw(alpha_range), "p": draw(p_range),
            "dy": dy_scale * draw(dy_range), "delta_eta": draw(delta_eta_range)}
