"""Which law each story follows: elastic, non-degrading or degrading Bouc-Wen.

A story's law (:class:`hlaid.record.StoryLaw`, the registry :data:`hlaid.record.STORY_LAWS`) says
which of its entries in prior units (:mod:`hlaid.joint.vector`: ``log k0, logit(alpha / 0.95),
log(p - 1), log Cy, log delta_eta``) the records may move; the others are held at fixed values
(:data:`HELD`):

- ``elastic``: only ``k0`` moves; the yield shear coefficient is :data:`ELASTIC_CY` (``dy`` far
  beyond any drift), ``alpha`` and ``p`` the system's medians, no degradation;
- ``nondegrading``: ``k0, alpha, p, Cy`` move, ``delta_eta`` is :data:`NO_DEGRADATION`;
- ``degrading``: every entry moves (the paper's law).

The laws of a building are chosen by the Laplace evidence of the joint fit of its records
(:func:`choose_laws`): the candidates are the three laws for every story, and each of them for the
first story under another for the stories above (an isolation layer, a soft first story); the
structural system's own law (:attr:`hlaid.systems.StructuralSystem.law`) is kept unless another is better by more than
:data:`TIE_LOG_UNITS` (an entry the records say nothing about costs no evidence, so a tie says
nothing either way).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..model import Building
from ..record import STORY_LAWS
from ..systems import SYSTEMS
from .priors import StructuralPrior, weight_above

LAWS = tuple(STORY_LAWS)
"""Story law names, nested: each one's free entries are a subset of the next one's (a view of
:data:`hlaid.record.STORY_LAWS`)."""

ELASTIC_CY = 5.0
"""Yield shear coefficient of an elastic story: ``dy = 5 W_above / k0``, far beyond any drift."""

NO_DEGRADATION = 1e-8
"""``delta_eta`` of a story that does not degrade [s^2/m^2] (the model's lower bound is 0)."""

TIE_LOG_UNITS = 2.0
"""Another law replaces the system's only where its log evidence is higher by more than this."""

HELD = {"alpha": "the system's median", "p": "the system's median",
        "cy": f"{ELASTIC_CY:g} (dy far beyond any drift)", "delta_eta": f"{NO_DEGRADATION:g} (no degradation)"}
"""What a held entry is set to (:func:`with_laws`)."""


def check_laws(laws: Sequence[str], n_stories: int) -> tuple[str, ...]:
    """``laws`` as a tuple, one known law per story (InputError otherwise)."""
    laws = tuple(laws)
    bad = [law for law in laws if law not in LAWS]
    if bad or len(laws) != n_stories:
        raise InputError(f"story laws {list(laws)}: expected {n_stories} of {', '.join(LAWS)}")
    return laws


def law_mask(laws: Sequence[str]) -> np.ndarray:
    """``(story, 5)`` which of ``log k0, logit alpha, log(p - 1), log Cy, log delta_eta`` are free."""
    return np.array([STORY_LAWS[law].free for law in laws], dtype=bool).reshape(len(laws), 5)


def default_laws(system: StructuralPrior | str, n_stories: int) -> tuple[str, ...]:
    """The structural system's law for every story."""
    name = system if isinstance(system, str) else system.name
    found = SYSTEMS.get(name)
    return (found.law.name if found is not None else "degrading",) * n_stories


def with_laws(building: Building, laws: Sequence[str], prior: StructuralPrior) -> Building:
    """``building`` with each story's fixed entries set by its law (elastic: ``Cy`` =
    :data:`ELASTIC_CY`, the system's ``alpha`` and ``p``, no degradation; non-degrading: no
    degradation; degrading: its values)."""
    laws = check_laws(laws, building.n_stories)
    alpha, p, dy, de = (np.array(getattr(building, k), dtype=float) for k in ("alpha", "p", "dy", "delta_eta"))
    w = weight_above(building)
    for i, law in enumerate(laws):
        held = STORY_LAWS[law].held
        if "alpha" in held:
            alpha[i] = prior.alpha.median
        if "p" in held:
            p[i] = prior.p.median
        if "cy" in held:
            dy[i] = min(ELASTIC_CY * w[i] / building.k0[i], 1e5)
        if "delta_eta" in held:
            de[i] = NO_DEGRADATION
    return building.replace(alpha=alpha, p=p, dy=dy, delta_eta=de)


def candidates(n_stories: int) -> list[tuple[str, ...]]:
    """The laws tried: each law for every story, then each law for the first story under each
    other law for the stories above (one story unlike the others: an isolation layer, a soft
    first story)."""
    out = [(law,) * n_stories for law in LAWS]
    if n_stories > 1:
        out += [(a,) + (b,) * (n_stories - 1) for a in LAWS for b in LAWS if a != b]
    return out


def choose_laws(evidence: Sequence[tuple[tuple[str, ...], float]], default: tuple[str, ...]
                ) -> tuple[tuple[str, ...], str]:
    """The laws kept among ``evidence`` (candidate laws and their log evidence, common ``n_eff``)
    and why: the structural system's ``default`` unless another is better by more than
    :data:`TIE_LOG_UNITS`; a candidate whose evidence could not be computed (not finite) is left out."""
    ok = [(laws, z) for laws, z in evidence if np.isfinite(z)]
    if not ok:
        return default, "no candidate's evidence could be computed: the structural system's law"
    best, zb = max(ok, key=lambda c: c[1])
    zd = next((z for laws, z in ok if laws == default), None)
    if zd is None:
        return best, f"{_show(best)} has the highest evidence ({zb:.1f}); the system's law could not be fitted"
    if best == default or zb - zd <= TIE_LOG_UNITS:
        return default, (f"the structural system's law ({_show(default)}): no other is better by more than "
                         f"{TIE_LOG_UNITS:g} log units (best {_show(best)}, {zb - zd:+.1f})")
    return best, f"{_show(best)}: log evidence {zb - zd:+.1f} over the system's law ({_show(default)})"


def _show(laws: Sequence[str]) -> str:
    if len(set(laws)) == 1:
        return f"{laws[0]} x {len(laws)}"
    return " / ".join(laws)


__all__ = ["LAWS", "ELASTIC_CY", "NO_DEGRADATION", "HELD", "TIE_LOG_UNITS", "check_laws", "law_mask",
           "default_laws", "with_laws", "candidates", "choose_laws"]
