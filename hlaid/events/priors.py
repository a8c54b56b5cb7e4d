"""What is known of a structural system before its records speak: the identification's prior.

A record that stays nearly elastic says much about a building's stiffness and damping and little
about its yield strength, loop shape or degradation; a first-mode-dominated record constrains a
few combinations of a story's five parameters. Where the data say little, the refinement falls
back on the structural system (maximum a posteriori; :mod:`hlaid.events.fit`): a Gaussian in
transformed parameters ("prior units", :mod:`hlaid.events.vector`), one entry of :data:`PRIORS` per
structural system (:data:`hlaid.systems.SYSTEMS`).

Per story ``i`` the transformed parameters are ::

    log k0_i,  logit(alpha_i / 0.95),  log(p_i - 1),  log Cy_i,  log delta_eta_i      (and log zeta)

with ``Cy_i = k0_i dy_i / (g sum_{j>=i} m_j)`` the story's yield shear over the weight above it
(a strength coefficient: independent of the units of the masses, so mass-normalised clones have
one too). The prior holds

- each shape parameter of a story near the building's own value (``story_spread``): the stories
  of one building follow one design and one material. For ``Cy`` the building's value is that of
  its base story times the ELF distribution of story shear (ASCE 7-22 section 12.8.3 with k = 1,
  equal story heights when they are unknown);
- the building's values near the system's medians (``beta`` in prior units);
- k0 near its start (HLA's, or the previous clone's) with ``k0_beta``: the data always constrain
  the stiffness, this only keeps a story the record hardly moved from running away.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..systems import get_system, unknown_system
from ..units import G_MM_S2

ALPHA_MAX = 0.95
"""Upper limit of ``alpha`` (the refinement's and the uncertainty's bound)."""

@dataclass(frozen=True, kw_only=True)
class Median:
    """A parameter's prior: median (natural units) and standard deviation in prior units."""

    median: float
    beta: float


@dataclass(frozen=True, kw_only=True)
class StructuralPrior:
    """Prior of one structural system.

    Attributes
    ----------
    name : the structural system (:data:`hlaid.systems.SYSTEMS`; ``identify.system`` in a config)
    cy : base-story yield shear coefficient ``Cy = k0 dy / W`` (lognormal)
    alpha : post-yield stiffness ratio (``beta`` in logit units of ``alpha / 0.95``)
    p : loop smoothness (lognormal in ``p - 1``)
    delta_eta : degradation [s^2/m^2] (lognormal)
    damping : Rayleigh damping ratio (lognormal)
    story_spread : standard deviation of a story's shape parameter around the building's, in
        prior units
    k0_beta : log standard deviation of k0 around its start
    sources : where the values come from
    """

    name: str
    cy: Median
    alpha: Median
    p: Median
    delta_eta: Median
    damping: Median
    story_spread: float = 0.25
    k0_beta: float = 0.5
    sources: tuple[str, ...] = field(default_factory=tuple)

    def to_dict(self) -> dict:
        return {"name": self.name, "title": get_system(self.name).title,
                "collapse": get_system(self.name).collapse, "story_spread": self.story_spread, "k0_beta": self.k0_beta,
                **{k: {"median": getattr(self, k).median, "beta": getattr(self, k).beta}
                   for k in ("cy", "alpha", "p", "delta_eta", "damping")}}


PRIORS: dict[str, StructuralPrior] = {
    "steel-moment-frame": StructuralPrior(
        name="steel-moment-frame",
        cy=Median(median=0.3, beta=0.6), alpha=Median(median=0.1, beta=0.7), p=Median(median=2.0, beta=0.7),
        delta_eta=Median(median=0.1, beta=1.0), damping=Median(median=0.025, beta=0.5),
        sources=("Cy: FEMA P695 (2009) / NIST GCR 10-917-8 (2010) steel SMF archetypes, static overstrength "
                 "1.6-3.3 over Cs 0.044-0.125 (Vmax/W about 0.1-0.4); the E-Defense steel frame of Table 1 of "
                 "the paper: 0.31 (base story)",
                 "alpha: story hardening of steel frames 3-10 % of the elastic stiffness (FEMA P-440A 2009; "
                 "Ibarra, Medina & Krawinkler 2005: 3 %), Table 1: 0.12-0.23",
                 "p: Table 1: 1.5-2.5 (a near-bilinear loop, p > 3, is as likely as a round one, p < 1.5)",
                 "delta_eta: steel members keep their unloading stiffness (Lignos & Krawinkler 2011, J. Struct. "
                 "Eng. 137(11): unloading-stiffness deterioration of steel beams negligible)",
                 "damping: 2-3 % for steel buildings (ATC-72-1 2010; PEER TBI 2017: 2.5 %)")),
    "rc-frame": StructuralPrior(
        name="rc-frame",
        cy=Median(median=0.2, beta=0.6), alpha=Median(median=0.05, beta=0.7), p=Median(median=1.3, beta=0.7),
        delta_eta=Median(median=1.0, beta=1.0), damping=Median(median=0.05, beta=0.5),
        sources=("Cy: FEMA P695 (2009) RC SMF archetypes (Haselton & Deierlein 2007): Vmax/W about 0.1-0.35",
                 "alpha: post-yield hardening of RC members 2-5 % (Haselton, Liel, Taylor Lange & Deierlein "
                 "2016, ACI Struct. J. 113(6))",
                 "p: round loops of RC members, n about 1-1.5 (Oh, Kim & Song 2023, IJNLM 148:104263)",
                 "delta_eta: unloading stiffness of RC falls with ductility (Takeda, Sozen & Nielsen 1970: "
                 "k_u = k_y (d_max/d_y)^-0.4)",
                 "damping: 5 % (ASCE 7-22; ASCE 41-17 for concrete)")),
    "generic": StructuralPrior(
        name="generic",
        cy=Median(median=0.3, beta=1.0), alpha=Median(median=0.1, beta=1.0), p=Median(median=2.0, beta=1.0),
        delta_eta=Median(median=0.3, beta=1.5), damping=Median(median=0.04, beta=0.7),
        sources=("the union of the steel and RC entries, widened",)),
}
"""Priors by structural system (``identify.system``; the wide ``generic`` one where none is named)."""


def get_prior(name: str) -> StructuralPrior:
    """The prior of the structural system ``name`` (InputError listing the names for an unknown one)."""
    if isinstance(name, str) and name in PRIORS:
        return PRIORS[name]
    raise InputError(unknown_system(name, PRIORS))


def weight_above(building) -> np.ndarray:
    """``(story,)`` the weight carried by each story, ``g sum_{j>=i} m_j`` [N]."""
    m = np.asarray(building.mass, dtype=float)
    return G_MM_S2 * np.cumsum(m[::-1])[::-1]


def elf_profile(building) -> np.ndarray:
    """``(story,)`` story shear coefficient over the base's under the ELF distribution (ASCE 7-22
    section 12.8.3, k = 1): ``(sum_{j>=i} m_j h_j / sum m_j h_j) / (sum_{j>=i} m_j / sum m_j)``,
    ``h_j`` the floor's height above the ground (equal story heights when unknown)."""
    m = np.asarray(building.mass, dtype=float)
    h = np.cumsum(np.ones_like(m) if building.height is None else np.asarray(building.height, dtype=float))
    mh = m * h
    return (np.cumsum(mh[::-1])[::-1] / mh.sum()) / (np.cumsum(m[::-1])[::-1] / m.sum())


def system_residuals(prior: StructuralPrior, u: np.ndarray, log_zeta: float | None, k0_ref: np.ndarray,
                     elf: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
    """Residuals of the system prior (each a standard normal under it) for ``u`` ``(story, 5)``:
    per shape parameter the stories around the building's value (``story_spread``) and the
    building's value around the system's median (``beta``); k0 around ``k0_ref``; the damping
    ratio around its median (when ``log_zeta`` is not None). ``elf``: the story shear profile of
    :func:`elf_profile` (``Cy`` is compared after dividing by it). ``free``: ``(story, 5)`` which
    entries the stories' laws leave free (None: all); a shape parameter is held over the stories
    where it is free only, and left out where no story has it free."""
    med = (np.log(prior.alpha.median / ALPHA_MAX / (1 - prior.alpha.median / ALPHA_MAX)),
           np.log(prior.p.median - 1.0), np.log(prior.cy.median), np.log(prior.delta_eta.median))
    betas = (prior.alpha.beta, prior.p.beta, prior.cy.beta, prior.delta_eta.beta)
    out = [(u[:, 0] - np.log(k0_ref)) / prior.k0_beta]
    for col, mu, beta in zip((1, 2, 3, 4), med, betas):
        f = np.ones(u.shape[0], dtype=bool) if free is None else np.asarray(free, dtype=bool)[:, col]
        if not f.any():
            continue
        v = u[f, col] - (np.log(elf[f]) if col == 3 else 0.0)
        centre = float(np.mean(v))
        if free is None or f.sum() > 1:
            out.append((v - centre) / prior.story_spread)
        out.append(np.atleast_1d((centre - mu) / beta))
    if log_zeta is not None:
        out.append(np.atleast_1d((log_zeta - np.log(prior.damping.median)) / prior.damping.beta))
    return np.concatenate(out)
