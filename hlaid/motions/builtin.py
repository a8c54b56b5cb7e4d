"""Real records shipped inside hlaid, addressable as ``builtin:NAME``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from importlib import resources

from ..errors import InputError
from .at2 import read_at2
from .record import GroundMotion

SUITE = "builtin-suite"
"""Name of the built-in far-field record suite used by the demo's IDA."""


@dataclass(frozen=True)
class BuiltinRecord:
    name: str
    file: str
    description: str
    source: str
    suite: bool


@cache
def builtin_records() -> dict[str, BuiltinRecord]:
    """The records shipped with hlaid, by name."""
    text = resources.files("hlaid").joinpath("data/records/manifest.json").read_text()
    return {k: BuiltinRecord(name=k, **v) for k, v in json.loads(text).items()}


def load_builtin(name: str) -> GroundMotion:
    """Load ``builtin:NAME`` as a :class:`GroundMotion` [mm/s^2]."""
    recs = builtin_records()
    if name not in recs:
        raise InputError(f"unknown built-in record {name!r}; available: {', '.join(sorted(recs))} "
                         f"(run 'hlaid records')", source=f"builtin:{name}")
    with resources.as_file(resources.files("hlaid").joinpath(f"data/records/{recs[name].file}")) as p:
        gm = read_at2(p, name=name)
    return GroundMotion(dt=gm.dt, acc=gm.acc, name=name, source=f"builtin:{name}")


def builtin_suite() -> list[GroundMotion]:
    """The built-in far-field suite (FEMA P695 components), for quick IDA runs."""
    return [load_builtin(r.name) for r in builtin_records().values() if r.suite]
