"""Structural systems: the one registry of the names every part of hlaid uses for them.

A clone's ``system`` (``identify.system`` in a config, ``--system`` on the command line) names
one entry of :data:`SYSTEMS`. Each part of hlaid keeps what it knows of a system under the same
name: the identification's prior (:data:`hlaid.events.priors.PRIORS`), the collapse law the IDA
uses by default (:attr:`StructuralSystem.collapse`, a name of
:data:`hlaid.model.COLLAPSE_MODELS`) and the loss assessment's default component inventory
(:data:`hlaid.loss.inventory.INVENTORIES`). Light: reading it imports nothing heavy.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from .errors import InputError


@dataclass(frozen=True, kw_only=True)
class StructuralSystem:
    """A structural system.

    Attributes
    ----------
    name : registry key
    title : the system, in words
    collapse : its collapse law, a name of :data:`hlaid.model.COLLAPSE_MODELS` (``"none"``: the
        Bouc-Wen law alone, no strength loss)
    """

    name: str
    title: str
    collapse: str


SYSTEMS: dict[str, StructuralSystem] = {
    "steel-moment-frame": StructuralSystem(name="steel-moment-frame", title="steel moment-resisting frame",
                                           collapse="steel-mrf"),
    "rc-frame": StructuralSystem(name="rc-frame", title="reinforced-concrete moment frame", collapse="rc-frame"),
    "generic": StructuralSystem(name="generic", title="unknown structural system", collapse="none"),
}
"""Structural systems by name."""


def get_system(name: str, what: str = "structural system") -> StructuralSystem:
    """The system called ``name``; an unknown name is an InputError listing the known ones (and
    the closest, where one is close)."""
    try:
        return SYSTEMS[name]
    except (KeyError, TypeError):
        raise InputError(unknown_system(name, SYSTEMS, what)) from None


def unknown_system(name, known, what: str = "structural system") -> str:
    """The message for a system name that is not among ``known``."""
    close = difflib.get_close_matches(str(name), list(known), n=1, cutoff=0.5) if isinstance(name, str) else []
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    shown = repr(name) if isinstance(name, str) and len(name) <= 40 and name.isprintable() else "the name given"
    return f"{what} {shown} is unknown{hint}; expected one of {', '.join(map(repr, known))}"


__all__ = ["SYSTEMS", "StructuralSystem", "get_system", "unknown_system"]
