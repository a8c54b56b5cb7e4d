"""What is known of a structural system before its records speak: the identification's prior.

A record that stays nearly elastic says much about a building's stiffness and damping and little
about its yield strength, loop shape or degradation; a first-mode-dominated record constrains a
few combinations of a story's five parameters. Where the data say little, the refinement falls
back on the structural system (maximum a posteriori; :mod:`hlaid.joint.fit`): a Gaussian in
transformed parameters ("prior units", :mod:`hlaid.joint.vector`), each structural system's own
(:attr:`hlaid.systems.StructuralSystem.prior`; :data:`PRIORS` by name).

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

import numpy as np

from ..errors import InputError
from ..systems import SYSTEMS, StructuralPrior, get_system, unknown_system
from ..units import G_MM_S2

ALPHA_MAX = 0.95
"""Upper limit of ``alpha`` (the refinement's and the uncertainty's bound)."""

PRIORS: dict[str, StructuralPrior] = {name: system.prior for name, system in SYSTEMS.items()}
"""Priors by structural system (``identify.system``; the wide ``generic`` one where none is named)."""


def get_prior(name: str) -> StructuralPrior:
    """The prior of the structural system ``name`` (InputError listing the names for an unknown one)."""
    if isinstance(name, str) and name in PRIORS:
        return PRIORS[name]
    raise InputError(unknown_system(name, PRIORS))


def prior_record(prior: StructuralPrior) -> dict:
    """``prior`` as a clone records it: its system (name, title, collapse law) and its numbers."""
    system = get_system(prior.name)
    return {"name": prior.name, "title": system.title,
            "collapse": system.collapse_name, "story_spread": prior.story_spread, "k0_beta": prior.k0_beta,
            **{k: {"median": getattr(prior, k).median, "beta": getattr(prior, k).beta}
               for k in ("cy", "alpha", "p", "delta_eta", "damping")}}


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
