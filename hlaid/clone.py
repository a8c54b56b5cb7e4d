"""The digital clone file: an identified building, versioned JSON in N, mm, t, s.

Layout::

    {"format": "hlaid-clone", "version": 1,
     "units": {"force": "N", "length": "mm", "mass": "t", "time": "s", ...},
     "stories": [{"k0": ..., "alpha": ..., "p": ..., "dy": ..., "delta_eta": ..., "mass": ...,
                  "height": ... (optional), "gravity_load": ... (optional, N)}, ...],
     "damping": {"kind": "rayleigh", "ratio": 0.05, "modes": [1, 2]},
     "pdelta": null | true | false,
     "mass_normalised": false,
     "diagnostics": {...}, "provenance": {...}}

With ``mass_normalised`` true the masses are relative (ratios) and every stiffness is per
unit of that relative mass; responses (drifts, accelerations) are unaffected.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._fileio import read_text, write_json
from .errors import InputError
from .model import Building, Damping
from .units import UNITS_JSON

FORMAT = "hlaid-clone"
VERSION = 1
_STORY_KEYS = ("k0", "alpha", "p", "dy", "delta_eta", "mass")


@dataclass(frozen=True, eq=False)
class Clone:
    """An identified building with what is known about how it was identified.

    Attributes
    ----------
    building : the identified shear building
    mass_normalised : masses are relative (unknown absolute masses)
    diagnostics : identification diagnostics (errors, iterations, R per story, ...)
    provenance : input file hash, config, package version, timings
    """

    building: Building
    mass_normalised: bool = False
    diagnostics: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        b = self.building
        stories = []
        for i in range(b.n_stories):
            s = {k: float(getattr(b, k)[i]) for k in _STORY_KEYS}
            if b.height is not None:
                s["height"] = float(b.height[i])
            if b.gravity_load is not None:
                s["gravity_load"] = float(b.gravity_load[i])
            stories.append(s)
        return {"format": FORMAT, "version": VERSION, "units": UNITS_JSON, "name": b.name, "stories": stories,
                "damping": b.damping.to_dict(), "pdelta": b.pdelta, "mass_normalised": self.mass_normalised,
                "diagnostics": _jsonable(self.diagnostics), "provenance": _jsonable(self.provenance)}

    def save(self, path: str | os.PathLike, *, force: bool = True) -> Path:
        """Write the clone JSON atomically (never a half-written file)."""
        return write_json(path, self.to_dict(), force=force)

    @classmethod
    def from_dict(cls, d: dict, *, source: str | None = None) -> "Clone":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"not an hlaid clone (field 'format' should be {FORMAT!r})", source=source)
        if d.get("version") != VERSION:
            raise InputError(f"clone version {d.get('version')!r} is not supported; this hlaid reads version {VERSION}",
                             source=source)
        stories = d.get("stories")
        if not isinstance(stories, list) or not stories:
            raise InputError("field 'stories' must be a non-empty list", source=source)
        cols: dict[str, list] = {k: [] for k in _STORY_KEYS}
        heights, gravity = [], []
        for i, s in enumerate(stories):
            if not isinstance(s, dict):
                raise InputError(f"stories[{i}] must be a mapping", source=source)
            for k in _STORY_KEYS:
                v = s.get(k)
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise InputError(f"stories[{i}].{k} must be a finite number, got {v!r}", source=source)
                cols[k].append(float(v))
            heights.append(s.get("height"))
            gravity.append(s.get("gravity_load"))
        try:
            damping = Damping(**d.get("damping", {}))
            b = Building(**cols, height=None if None in heights else heights,
                         gravity_load=None if None in gravity else gravity, damping=damping,
                         pdelta=d.get("pdelta"), name=str(d.get("name", "")), source=source)
        except TypeError as err:
            raise InputError(f"invalid field in 'damping': {err}", source=source) from None
        except InputError as err:
            raise InputError(str(err).removeprefix(f"{source}: "), source=source) from None
        return cls(building=b, mass_normalised=bool(d.get("mass_normalised", False)),
                   diagnostics=d.get("diagnostics", {}) or {}, provenance=d.get("provenance", {}) or {})

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Clone":
        """Read and validate a clone JSON file."""
        src = str(path)
        try:
            d = json.loads(read_text(path))
        except json.JSONDecodeError as err:
            raise InputError(f"not valid JSON (line {err.lineno}: {err.msg})", source=src) from None
        return cls.from_dict(d, source=src)


def load_clone(path: str | os.PathLike) -> Clone:
    """Read a clone file (see :class:`Clone`)."""
    return Clone.load(path)


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return _jsonable(o.tolist())
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(o) else None
    if isinstance(o, (np.integer, np.bool_)):
        return o.item()
    return o
