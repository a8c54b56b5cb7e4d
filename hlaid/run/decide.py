"""The one assessment step behind every decision command: a clone, its IDA and the building's
recorded events in, a typed :class:`Decision` out.

``hlaid ida``, ``hlaid run`` and ``hlaid fleet`` call :func:`decide`; ``hlaid demands`` and
``hlaid loss`` read the same figures from the same functions (:mod:`hlaid.ida.ownevent`,
:func:`hlaid.ida.basis.ida_events`). A decision holds, per recorded event, both questions under
their names (the clone replaying the event's own motion; the fragility at its intensity), the
collapse law's capping drift conditioned on what the building survived, and every flag its
figures carry: the identification's (stiffness-evolution error, parameters at a limit or from the
prior, implausible parameters, unknown masses) and the basis's (survival, extrapolation, assumed
heights, the replay's errors).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

from ..ida.basis import AtEvent, DecisionBasis, decision_basis


@dataclass(frozen=True)
class Decision:
    """What a clone's decision rests on and the flags its figures carry.

    Attributes
    ----------
    basis : the figures at every recorded event and what they rest on (:class:`DecisionBasis`)
    identification_flags : the identification's and plausibility flags of the clone
    """

    basis: DecisionBasis
    identification_flags: tuple[str, ...] = ()

    @property
    def flags(self) -> tuple[str, ...]:
        """Every flag: the identification's, then the basis's."""
        return self.identification_flags + tuple(self.basis.flags())

    @property
    def at_intensity(self) -> tuple[AtEvent, ...]:
        """P(collapse | another record of each recorded event's intensity)."""
        return self.basis.events

    @property
    def own_motion(self) -> tuple:
        """P(collapse | each recorded event's own motion), the replay beside the record."""
        return self.basis.own_motion

    def at(self, name: str) -> tuple[AtEvent | None, object | None]:
        """Both figures at the event ``name`` (None where not reported)."""
        a = next((e for e in self.at_intensity if e.name == name), None)
        o = next((c for c in self.own_motion if c.name == name), None)
        return a, o

    def to_dict(self) -> dict:
        return {"basis": self.basis.to_dict(), "identification_flags": list(self.identification_flags),
                "flags": list(self.flags)}


def decide(clone, ida, cfg, *, extra: Sequence = (), at_hand: Sequence = (), n_ensemble: int | None = None,
           seed: int = 0,
           heights_given: Sequence[float] | None = None, demand_ratio: float | None = None,
           stiffness_error: Sequence[float] | None = None, ensemble_events: dict | None = None) -> Decision:
    """The decision of ``clone`` from its IDA ``ida`` (:class:`~hlaid.ida.IDAResult`, run with the
    IDA settings ``cfg``) at every recorded event: the clone's own (read again from their files)
    and ``extra`` (measurement files or Measurements of later events); ``at_hand``: measurements of
    the clone's events in hand (used instead of reading their files again).

    ``n_ensemble``: members replaying each event's own motion (None: the default ensemble where the
    clone has an uncertainty, else 0); ``heights_given``: story heights assumed (None: ``cfg``'s);
    ``demand_ratio``: the decision's median peak drift ratio (extrapolation); ``stiffness_error``:
    per story (None: the clone's replay diagnostics); ``ensemble_events``: ``{event: mapping}`` of
    an ensemble assessment's figures at the events (:func:`hlaid.ida.assess`'s ``events``): their
    band beside the identified clone's figure, and their figure where the clone's IDA fitted none.
    """
    from ..ida.basis import ida_events
    from ..ida.capacity import capacity_record
    from ..loss.ownmotion import event_checks, recorded_events
    from ..uncertainty.config import N_ENSEMBLE
    from .decision import identification_flags

    heights = ida.building.height
    assumed = heights_given if heights_given is not None else cfg.heights_mm
    events = recorded_events(clone, extra, at_hand=at_hand)
    n_ens = n_ensemble if n_ensemble is not None else (N_ENSEMBLE if clone.uncertainty is not None else 0)
    law = ida.building.collapse
    own_cfg = cfg.replace(collapse=law.to_dict() if law is not None else "none")
    checks = event_checks(clone, events, ida_config=own_cfg, heights=heights, heights_assumed=assumed is not None,
                          n_ensemble=n_ens, seed=seed)
    cap = capacity_record(clone, ida.building, cfg.collapse)
    at = ida_events(clone, ida, [(n, None if m is None else m.ground_motion(name=n)) for n, m, _, _ in events])
    if cap is not None and cap.get("informative") and not cap.get("consistent"):
        at = tuple(replace(e, p_collapse=None, source="not assessed: the collapse law contradicts the records")
                   for e in at)
    if ensemble_events:
        at = tuple(_with_ensemble(e, ensemble_events.get(e.name)) for e in at)
    basis = decision_basis(clone, events=at, heights=heights, heights_assumed=assumed is not None,
                           demand_ratio=demand_ratio, drift_limit=cfg.drift_limit, own_motion=checks, capacity=cap)
    return Decision(basis=basis, identification_flags=tuple(identification_flags(clone, stiffness_error)))


def _with_ensemble(e: AtEvent, ens: dict | None) -> AtEvent:
    """The figure ``e`` with the ensemble's band beside it (the ensemble's figure where ``e`` has none)."""
    if not ens:
        return e
    band = ens.get("p_collapse_band")
    band = None if band is None else (float(band[0]), float(band[1]))
    if e.p_collapse is None and ens.get("p_collapse") is not None:
        return replace(e, p_collapse=float(ens["p_collapse"]), p_collapse_band=band,
                       source=f"the ensemble's mean ({e.source or 'the identified clone fitted no fragility'})")
    return replace(e, p_collapse_band=band, source=f"{e.source}; 90 % band over the ensemble")


__all__ = ["Decision", "decide"]
