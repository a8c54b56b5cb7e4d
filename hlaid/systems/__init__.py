"""Structural systems: one object per system, in one registry whose names every part of hlaid uses.

A clone's ``system`` (``identify.system`` in a config, ``--system`` on the command line) names
one entry of :data:`SYSTEMS`, a :class:`StructuralSystem` that holds all hlaid knows of it: the
identification's prior (:attr:`~StructuralSystem.prior`), the story law its stories follow
unless the records say otherwise (:attr:`~StructuralSystem.law`), the collapse law the IDA uses by
default (:attr:`~StructuralSystem.collapse`, a :class:`~hlaid.model.collapse.CollapseModel`), the
loss assessment's default component inventory (:attr:`~StructuralSystem.inventory`) and the
sources of its numbers. Each system is a module of this package (``steel_moment_frame.py``,
``rc_frame.py``, ``generic.py``): adding a system is adding one such module, which
:data:`SYSTEMS` finds. The tables by name that other parts read (:data:`hlaid.joint.priors.PRIORS`,
:data:`hlaid.loss.inventory.INVENTORIES`) are views of this registry. Light: reading it imports nothing heavy.
"""

from __future__ import annotations

import difflib
import importlib
import pkgutil

from ..errors import InputError
from .parts import Component, Inventory, Median, StructuralPrior, StructuralSystem


def _discovered() -> dict[str, StructuralSystem]:
    """The ``SYSTEM`` of each module of this package (``parts`` holds the types), by name: the
    named systems in the order of their modules' names, ``generic`` last."""
    found = []
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: (m.name == "generic", m.name)):
        if info.name != "parts":
            system = importlib.import_module(f"{__name__}.{info.name}").SYSTEM
            if not isinstance(system, StructuralSystem):
                raise TypeError(f"{__name__}.{info.name}.SYSTEM is not a StructuralSystem")
            found.append(system)
    return {s.name: s for s in found}


SYSTEMS: dict[str, StructuralSystem] = _discovered()
"""Structural systems by name: one per module of this package."""


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


__all__ = ["SYSTEMS", "Component", "Inventory", "Median", "StructuralPrior", "StructuralSystem", "get_system",
           "unknown_system"]
