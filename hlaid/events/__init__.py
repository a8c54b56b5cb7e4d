"""The clone through a building's events.

A building under monitoring records one earthquake after another; its clone learns from all of
them and carries what each left behind into the next:

- :mod:`.state`: :class:`BuildingState`, the state an event leaves (the one owner of the
  simulator's state-vector layout);
- :mod:`.start`: where a replay starts (``auto``, ``carried``, ``undamaged``), resolved once;
- :mod:`.identify`: :func:`identify_clone`, one record or several in time order;
- :mod:`.series`, :mod:`.fit`: the events replayed in order and the MAP fit of one set of
  parameters to all of them;
- :mod:`.priors`, :mod:`.vector`: the structural systems' priors and the prior-unit vector
  (which owns its map onto the clone's parameters);
- :mod:`.update`: :func:`update_clone`, one more event (sequential updating);
- :mod:`.predict`: :func:`predict_event`, the next event predicted and compared
  (:class:`Prediction`).

Names are imported on first use (PEP 562).
"""

from __future__ import annotations

from .._lazy import lazy_exports

_WHERE = {
    ".state": ("BuildingState", "settle_time"),
    ".start": ("START_STATES", "Start", "resolve_start"),
    ".identify": ("identify_clone", "check_series", "event_record"),
    ".fit": ("JointFit", "map_refine"),
    ".priors": ("PRIORS", "StructuralPrior", "get_prior"),
    ".update": ("update_clone",),
    ".predict": ("Prediction", "PredictiveBand", "HLACheck", "predict_event"),
}

__all__ = [name for names in _WHERE.values() for name in names]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
