"""The joint estimator: one set of a clone's parameters fitted to several events at once.

- :mod:`.series`: the events replayed in time order, each from the state the one before left;
- :mod:`.compare`: what a replay is compared with (accelerations, displacements, story drifts);
- :mod:`.priors`, :mod:`.vector`: the structural systems' priors and the prior-unit vector (which
  owns its map onto the clone's parameters);
- :mod:`.laws`: the story laws a fit may hold a story to;
- :mod:`.fit`: the MAP fit of the parameters to all events (:func:`map_refine`, :class:`JointFit`);
- :mod:`.screen`: candidate story laws judged from the one joint fit;
- :mod:`.fallback`: a numerical stage beside the main fit that falls back with a note.

The clone's life (identify, update, predict) is in :mod:`hlaid.events`; it calls this room.
Names are imported on first use (PEP 562).
"""

from __future__ import annotations

from .._lazy import lazy_exports

_WHERE = {
    ".fit": ("JointFit", "map_refine"),
    ".priors": ("PRIORS", "StructuralPrior", "get_prior"),
}

__all__ = [name for names in _WHERE.values() for name in names]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
