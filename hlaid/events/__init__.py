"""The clone through a building's events.

A building under monitoring records one earthquake after another; its clone learns from all of
them and carries what each left behind into the next:

- :mod:`.start`: where a replay starts (``auto``, ``carried``, ``undamaged``), resolved once;
- :mod:`.identify`: :func:`identify_clone`, one record or several in time order;
- :mod:`.evidence`, :mod:`.guard`, :mod:`.prequential`, :mod:`.replay`: what the events
  survived, the update's check, the prequential start rule and the clone's own replays;
- :mod:`.update`: :func:`update_clone`, one more event (sequential updating);
- :mod:`.predict`: :func:`predict_event`, the next event predicted and compared
  (:class:`Prediction`).

The state an event leaves is :class:`hlaid.model.state.BuildingState` (with the model); the
joint fit of one set of parameters to several events lives in :mod:`hlaid.joint`. Both are
re-exported here for convenience. Names are imported on first use (PEP 562).
"""

from __future__ import annotations

from .._lazy import lazy_exports

_WHERE = {
    "..model.state": ("BuildingState", "settle_time"),
    ".start": ("START_STATES", "Start", "resolve_start"),
    ".identify": ("identify_clone", "check_series", "event_record"),
    "..joint.fit": ("JointFit", "map_refine"),
    "..joint.priors": ("PRIORS", "StructuralPrior", "get_prior"),
    ".update": ("update_clone",),
    ".predict": ("Prediction", "PredictiveBand", "HLACheck", "predict_event"),
}

__all__ = [name for names in _WHERE.values() for name in names]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
