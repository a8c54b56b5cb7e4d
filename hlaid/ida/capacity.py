"""What the building survived, as evidence on its collapse law (:mod:`hlaid.model.capacity`).

:meth:`hlaid.clone.Clone.survived_drift` (``measured_only=True``) is the one reader of the clone's
record of what each event measured; :func:`law_posterior` conditions a collapse law on it for a
building prepared for an assessment.
"""

from __future__ import annotations

from ..clone import Clone
from ..model import Building
from ..model.capacity import CapacityPosterior, capacity_posterior
from ..model.collapse import CollapseModel, get_collapse_model
from ..systems import SYSTEMS


def chosen_law(model, collapse=None, notes: list[str] | None = None):
    """The literature collapse law of ``model`` (a Clone or Building) before any evidence:
    ``collapse`` where given, else the building's own, else its structural system's, else None."""
    system = model.system if isinstance(model, Clone) else None
    building = model.building if isinstance(model, Clone) else model
    if collapse is not None:
        return get_collapse_model(collapse)
    law = building.collapse
    if law is None and system is not None:
        law = SYSTEMS[system].collapse if system in SYSTEMS else None
        if law is not None and notes is not None:
            notes.append(f"collapse model {law.name!r} chosen for the clone's structural system {system!r}: "
                         f"strength loss as measured on such members ({law.source})")
    return law


def law_posterior(model: Clone | Building, law: CollapseModel, building: Building) -> CapacityPosterior:
    """The posterior of ``law``'s capping drift for ``building`` (prepared: its heights and ``dy``)
    given what ``model`` (a Clone; a Building records nothing) survived."""
    survived = model.survived_drift(measured_only=True) if isinstance(model, Clone) else None
    return capacity_posterior(law, dy=building.dy, height=building.height, survived=survived)


__all__ = ["capacity_record", "chosen_law", "law_posterior"]


def capacity_record(clone: Clone, building: Building, collapse=None) -> dict | None:
    """The posterior of the collapse law in force for ``clone`` prepared as ``building`` (its
    heights), as :meth:`~hlaid.model.capacity.CapacityPosterior.to_dict`; None: no law or no heights."""
    law = chosen_law(clone, collapse)
    if law is None or building.height is None:
        return None
    return law_posterior(clone, law, building).to_dict()
