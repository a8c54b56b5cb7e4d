"""Where a replay of a clone starts: the one place a ``start`` is resolved.

A clone carries the state its last event left the building in (:class:`~hlaid.model.state.BuildingState`).
A prediction, an IDA or a demand replay starts from it (``"carried"``), at rest (``"undamaged"``),
or as the clone itself says (``"auto"``): its start rule's choice (``clone.start_rule``, a
:class:`~hlaid.record.StartRule`; :mod:`hlaid.events.prequential`: carried only where the carried
state predicted the events already seen better than from rest, else from rest); a clone that
keeps no rule: the carried state, unless it carries none. The words are :data:`hlaid.record.STARTS`
and ``"auto"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..model.state import BuildingState
from ..record import STARTS

if TYPE_CHECKING:
    from ..clone import Clone

START_STATES = ("auto", *STARTS)
"""The starts a replay may be asked for."""


@dataclass(frozen=True)
class Start:
    """A resolved start.

    Attributes
    ----------
    name : ``"carried"`` or ``"undamaged"``
    state : the carried state (None: at rest)
    reason : why, in words
    """

    name: str
    state: BuildingState | None
    reason: str

    def vector(self, collapse: bool = False) -> np.ndarray | None:
        """The simulator's initial state (:meth:`BuildingState.vector`; None: at rest)."""
        return None if self.state is None else self.state.vector(collapse=collapse)


def resolve_start(clone: Clone | object, start: str = "auto") -> Start:
    """The start ``start`` names for ``clone`` (a :class:`~hlaid.clone.Clone`, or a building,
    which carries no state). ``"carried"`` on a clone that carries no state is an InputError."""
    if start not in START_STATES:
        raise InputError(f"start = {start!r}; expected one of {', '.join(map(repr, START_STATES))}")
    state = getattr(clone, "state", None)
    if start == "undamaged":
        return Start("undamaged", None, "asked for: every replay from rest")
    if start == "carried":
        if state is None:
            source = getattr(getattr(clone, "building", clone), "source", None)
            raise InputError("start: carried needs a clone that carries the state its last event left it in (a clone "
                             "of hlaid identify or hlaid update); use start undamaged or auto", source=source)
        return Start("carried", state, "asked for: the state the clone's events left")
    if state is None:
        return Start("undamaged", None, "the clone carries no state")
    rule = getattr(clone, "start_rule", None)
    if rule is not None:
        reason = f"the clone's start rule ({rule.rule}): {rule.reason}".rstrip(": ")
        return Start("carried", state, reason) if rule.choice == "carried" else Start("undamaged", None, reason)
    return Start("carried", state, "the state the clone's events left")


__all__ = ["START_STATES", "Start", "resolve_start"]
