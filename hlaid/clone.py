"""The digital clone file: an identified building, versioned JSON in N, mm, t, s.

Layout::

    {"format": "hlaid-clone", "version": 3,
     "units": {"force": "N", "length": "mm", "mass": "t", "time": "s", ...},
     "stories": [{"k0": ..., "alpha": ..., "p": ..., "dy": ..., "delta_eta": ..., "mass": ...,
                  "height": ... (optional), "gravity_load": ... (optional, N)}, ...],
     "damping": {"kind": "rayleigh", "ratio": 0.05, "modes": [1, 2]},
     "pdelta": null | true | false,
     "mass_normalised": false,
     "collapse": {"name": ..., "theta_p": ..., "theta_pc": ..., "kappa": ..., "theta_u": ...}
                 (optional: the strength-loss model IDA uses, see hlaid.model.collapse),
     "coupling": {"flexural": [...]} (optional: the linear floor coupling beside the story springs,
                 hlaid.model.coupling; absent: the shear chain),
     "diagnostics": {...}, "provenance": {...},
     "uncertainty": null | {...},                          (version 2 and later)
     "system": null | "steel-moment-frame" | ...,          (version 3)
     "events": [{"name": ..., "source": ..., "sha256": ..., "pga_g": ..., "duration_s": ...,
                 "prequential": {...} (optional: how the clone before it predicted it),
                 "peak_drift": [...] (optional: the measured peak story drifts [mm]),
                 "replay": {"band_hz": [lo, hi], "peak_drift_error": [...], "drift_r": [...]}
                           (optional: how the clone's full replay met this event)}, ...],
     "state": null | {"drift": [...], "z": [...], "work": [...], "peak_positive": [...],
                      "peak_negative": [...], "events": [...]},
     "modes": {"clone": [{"frequency_hz": ..., "damping_ratio": ..., "shape": [...]}, ...],
               "records": [...], "damping_max": ..., "system": ...}   (optional, version 3)}

Version 2 adds the optional ``uncertainty`` block: the identified
parameters' Gaussian in log space (per parameter: name, story, transform, value, std and a
90 % interval; the covariance), see :class:`hlaid.uncertainty.ParameterUncertainty`.
Version 3 adds what the clone learnt from: its structural ``system`` (the prior of
:mod:`hlaid.joint.priors`), the ``events`` it was identified from in time order, and the
``state`` the last of them left the building in (:class:`hlaid.model.state.BuildingState`;
null: undamaged). Version 1 and 2 files (none of these) are still read, as undamaged clones.

With ``mass_normalised`` true the masses are relative (ratios) and every stiffness is per
unit of that relative mass; responses (drifts, accelerations) are unaffected.

Reading is strict: an unknown field (top level, story or damping), a ``units`` block other than
the one above (it may be left out), or a field of the wrong type (``"pdelta": "yes"``) is an
:class:`~hlaid.errors.InputError` naming the file and the field.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ._fileio import write_json
from ._inputs import read_json
from .errors import InputError, escape_controls, kind_of
from .model import Building, Damping
from .model.schema import STATE_BOUNDS, check_event, check_state
from .model.state import BuildingState
from .systems import SYSTEMS
from .units import UNITS_JSON

if TYPE_CHECKING:
    from .events.coupled import LinearPart
    from .model.modes import ModalCheck
    from .model.uncertainty import ParameterUncertainty

FORMAT = "hlaid-clone"
VERSION = 3
READS = (1, 2, 3)
"""Clone file versions this hlaid reads (it writes :data:`VERSION`)."""
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
    uncertainty : the identified parameters' uncertainty (None: a point estimate only)
    system : the structural system whose prior the identification used (None: none)
    events : the events the clone was identified from, oldest first (name, source, sha256,
        pga_g, duration_s)
    state : the state its last event left the building in (None: undamaged, at rest)
    modes : its modes at small amplitude beside the records' (:class:`hlaid.model.modes.ModalCheck`;
        None: not assessed, a file from before)
    linear : which linear part the clone has, shear chain or coupled, and why
        (:class:`hlaid.events.coupled.LinearPart`; None: the shear chain, not chosen)
    """

    building: Building
    mass_normalised: bool = False
    diagnostics: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    uncertainty: ParameterUncertainty | None = None
    system: str | None = None
    events: tuple[dict, ...] = ()
    state: BuildingState | None = None
    modes: ModalCheck | None = None
    linear: LinearPart | None = None

    def survived_drift(self, *, measured_only: bool = False) -> np.ndarray | None:
        """``(story,)`` the largest drift of each story the building survived [mm]: the measured
        peak of each event it was identified from (``events[k]["peak_drift"]``) and, unless
        ``measured_only``, the largest drifts of the state the clone carries (its replay of those
        events); None where neither is known."""
        n = self.building.n_stories
        peaks = [np.asarray(e["peak_drift"], dtype=float) for e in self.events
                 if isinstance(e.get("peak_drift"), list) and len(e["peak_drift"]) == n]
        if self.state is not None and not measured_only:
            peaks.append(np.maximum(self.state.peak_positive, self.state.peak_negative))
        if not peaks:
            return None
        out = np.max(peaks, axis=0)
        return out if np.all(np.isfinite(out)) and np.any(out > 0) else None

    def own_replay_miss(self) -> tuple[float, int, str, tuple[float, float]] | None:
        """The worst miss of the clone's full replay of its own events: ``(error, story, event,
        band_hz)`` with ``error`` the signed peak-drift error of largest size (a fraction), from the
        ``replay`` record kept with each event; None where no event holds one (not assessed)."""
        worst = None
        for k, e in enumerate(self.events):
            r = e.get("replay")
            if not isinstance(r, dict) or not r.get("peak_drift_error"):
                continue
            err = np.asarray(r["peak_drift_error"], dtype=float)
            j = int(np.argmax(np.abs(err)))
            if worst is None or abs(err[j]) > abs(worst[0]):
                lo, hi = (float(x) for x in (r.get("band_hz") or (float("nan"), float("nan"))))
                worst = (float(err[j]), j, str(e.get("name") or f"event {k + 1}"), (lo, hi))
        return worst

    def with_state(self, state: BuildingState | None) -> Clone:
        """The same clone left in ``state``."""
        return dataclasses.replace(self, state=state)

    def member(self, building: Building) -> Clone:
        """A clone of ``building`` drawn from this one's uncertainty: the same mass normalisation
        and structural system (its collapse law), nothing else."""
        return Clone(building=building, mass_normalised=self.mass_normalised, system=self.system)

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
        return {"format": FORMAT, "version": VERSION, "units": dict(UNITS_JSON), "name": b.name, "stories": stories,
                "damping": b.damping.to_dict(), "pdelta": b.pdelta, "mass_normalised": self.mass_normalised,
                "diagnostics": jsonable(self.diagnostics), "provenance": jsonable(self.provenance),
                "uncertainty": None if self.uncertainty is None else jsonable(self.uncertainty.to_dict()),
                "system": self.system, "events": jsonable(list(self.events)),
                "state": None if self.state is None else self.state.to_dict(),
                **({"modes": self.modes.to_dict()} if self.modes is not None else {}),
                **({"linear": self.linear.to_dict()} if self.linear is not None else {}),
                **({"collapse": b.collapse.to_dict()} if b.collapse is not None else {}),
                **({"coupling": b.coupling.to_dict()} if b.coupling is not None else {})}

    def save(self, path: str | os.PathLike, *, force: bool = False) -> Path:
        """Write the clone JSON atomically (never a half-written file); an existing file is
        replaced only with ``force``."""
        return write_json(path, self.to_dict(), force=force)

    @classmethod
    def from_dict(cls, d: dict, *, source: str | None = None) -> Clone:
        """Validate a clone mapping strictly: unknown fields, a ``units`` block other than hlaid's,
        and fields of the wrong type (``pdelta: "yes"``) are each an :class:`InputError` naming the field."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"not an hlaid clone (field 'format' should be {FORMAT!r})", source=source)
        version = d.get("version")
        if isinstance(version, bool) or version not in READS:
            raise InputError(f"clone version {_show(version)} is not supported; this hlaid reads versions "
                             f"{', '.join(map(str, READS))}", source=source)
        _no_unknown(d, _TOP_KEYS + (("uncertainty",) if version >= 2 else ())
                    + (("system", "events", "state", "modes", "linear") if version >= 3 else ()), "", source)
        _check_units(d.get("units"), source)
        stories = d.get("stories")
        if not isinstance(stories, list) or not stories:
            raise InputError("field 'stories' must be a non-empty list", source=source)
        cols: dict[str, Any] = {k: [] for k in _STORY_KEYS}
        heights, gravity = [], []
        for i, s in enumerate(stories):
            if not isinstance(s, dict):
                raise InputError(f"stories[{i}] must be a mapping", source=source)
            _no_unknown(s, _STORY_KEYS + _STORY_OPTIONAL, f"stories[{i}].", source)
            for k in _STORY_KEYS:
                if k not in s:
                    raise InputError(f"stories[{i}].{k} is missing", source=source)
                cols[k].append(_number(s[k], f"stories[{i}].{k}", source))
            heights.append(None if s.get("height") is None else _number(s["height"], f"stories[{i}].height", source))
            gravity.append(None if s.get("gravity_load") is None
                           else _number(s["gravity_load"], f"stories[{i}].gravity_load", source))
        for key, values in (("height", heights), ("gravity_load", gravity)):
            if None in values and any(v is not None for v in values):
                i = values.index(None)
                raise InputError(f"stories[{i}].{key} is missing; give {key} for every story or for none",
                                 source=source)
        damping = d.get("damping", {})
        if not isinstance(damping, dict):
            raise InputError(f"field 'damping' must be a mapping, got {kind_of(damping)}", source=source)
        _no_unknown(damping, ("kind", "ratio", "modes", "ratio2", "higher"), "damping.", source)
        if "kind" in damping and not isinstance(damping["kind"], str):
            raise InputError(f"damping.kind must be a string, got {kind_of(damping['kind'])}", source=source)
        if "ratio" in damping:
            _number(damping["ratio"], "damping.ratio", source)
        modes = damping.get("modes", [1, 2])
        if not (isinstance(modes, list) and all(isinstance(m, int) and not isinstance(m, bool) for m in modes)):
            raise InputError("damping.modes must be a list of two mode numbers such as [1, 2]", source=source)
        for key, kinds, what in (("pdelta", (bool, type(None)), "true, false or null"),
                                 ("mass_normalised", (bool,), "true or false"),
                                 ("name", (str, type(None)), "a string"),
                                 ("diagnostics", (dict, type(None)), "a mapping"),
                                 ("provenance", (dict, type(None)), "a mapping")):
            if key in d and not isinstance(d[key], kinds):
                raise InputError(f"field '{key}' must be {what}, got {kind_of(d[key])}", source=source)
        try:
            # the story lists become arrays in Building
            b = Building(**cols, height=None if None in heights else cast("np.ndarray", heights),
                         gravity_load=None if None in gravity else cast("np.ndarray", gravity),
                         damping=_damping(damping, source), pdelta=d.get("pdelta"), coupling=_coupling(d, source),
                         collapse=_collapse_block(d.get("collapse"), source), name=d.get("name") or "", source=source)
        except InputError as err:
            raise InputError(str(err).removeprefix(f"{escape_controls(source)}: "), source=source) from None
        unc = None
        if d.get("uncertainty") is not None:
            from .model.uncertainty import ParameterUncertainty

            unc = ParameterUncertainty.from_dict(d["uncertainty"], source=source)
            if any(i >= b.n_stories for n, i in unc.slots):
                raise InputError(f"uncertainty names a story beyond the clone's {b.n_stories}", source=source)
        system, events, state = _history(d, b.n_stories, source)
        if state is not None:
            _checked(check_state, state.z, b.dy, drift=state.drift, height=b.height, source=source,
                     peaks=(("peak_positive", state.peak_positive), ("peak_negative", state.peak_negative)))
        modes = None
        if d.get("modes") is not None:
            from .model.modes import ModalCheck

            modes = ModalCheck.from_dict(d["modes"], source=source)
        linear = None
        if d.get("linear") is not None:
            from .events.coupled import LinearPart

            linear = LinearPart.from_dict(d["linear"], source=source)
        return cls(building=b, mass_normalised=d.get("mass_normalised", False),
                   diagnostics=d.get("diagnostics") or {}, provenance=d.get("provenance") or {}, uncertainty=unc,
                   system=system, events=events, state=state, modes=modes, linear=linear)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Clone:
        """Read and validate a clone JSON file."""
        return cls.from_dict(read_json(path), source=str(path))


def _history(d: dict, n: int, source: str | None) -> tuple[str | None, tuple[dict, ...], BuildingState | None]:
    """The version-3 fields ``system``, ``events`` and ``state`` (absent: none, undamaged)."""
    system = d.get("system")
    if system is not None and system not in SYSTEMS:
        raise InputError(f"field 'system' must be one of {', '.join(SYSTEMS)} or null", source=source)
    events = d.get("events") or []
    if not isinstance(events, list) or not all(isinstance(e, dict) for e in events):
        raise InputError("field 'events' must be a list of mappings", source=source)
    for i, e in enumerate(events):
        _no_unknown(e, _EVENT_KEYS, f"events[{i}].", source)
        _checked(check_event, e, i, source=source)
        if e.get("start") not in (None, "carried", "undamaged"):
            raise InputError(f"field 'events[{i}].start' must be 'carried' or 'undamaged'", source=source)
        if e.get("prequential") is not None and not isinstance(e["prequential"], dict):
            raise InputError(f"field 'events[{i}].prequential' must be a mapping", source=source)
        pk = e.get("peak_drift")
        bound = STATE_BOUNDS["peak_positive"]
        if pk is not None and not (isinstance(pk, list) and len(pk) == n and all(bound.contains(v) for v in pk)):
            raise InputError(f"field 'events[{i}].peak_drift' must be {n} drifts [mm] in {bound.lo:g}..{bound.hi:g}, "
                             "one per story", source=source)
    state = None
    if d.get("state") is not None:
        st = d["state"]
        if not isinstance(st, dict):
            raise InputError(f"field 'state' must be a mapping, got {kind_of(st)}", source=source)
        _no_unknown(st, ("drift", "z", "work", "peak_positive", "peak_negative", "events"), "state.", source)
        try:
            state = BuildingState.from_dict(st)
        except InputError as err:
            raise InputError(str(err), source=source) from None
        if state.n_stories != n:
            raise InputError(f"state has {state.n_stories} stories; the clone has {n}", source=source)
    return system, tuple(events), state


_EVENT_KEYS = ("name", "source", "sha256", "ground_sha256", "pga_g", "duration_s", "dt", "n_floors", "recorded",
               "start", "prequential", "peak_drift", "replay",
               "ground_profile")  # the ground record's RMS in equal windows (hlaid.measurement.ground_profile)


def _checked(check, *args, source: str | None, **kw) -> None:
    """``check(*args, **kw)``, its InputError said of ``source``."""
    try:
        check(*args, **kw)
    except InputError as err:
        raise InputError(str(err), source=source) from None


_TOP_KEYS = ("format", "version", "units", "name", "stories", "damping", "pdelta", "mass_normalised",
             "diagnostics", "provenance", "collapse", "coupling")


def _damping(damping: dict, source: str | None) -> Damping:
    """The ``damping`` block (its ``higher`` ratios a list of numbers)."""
    higher = damping.get("higher", [])
    if not (isinstance(higher, list) and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in higher)):
        raise InputError("damping.higher must be a list of damping ratios", source=source)
    return Damping(**{**damping, **({"higher": tuple(higher)} if higher else {})})


def _coupling(d: dict, source: str | None):
    """The optional ``coupling`` block (absent: the shear chain, the coupling at zero)."""
    if d.get("coupling") is None:
        return None
    from .model.coupling import Coupling

    try:
        return Coupling.from_dict(d["coupling"])
    except InputError as err:
        raise InputError(str(err), source=source) from None
_STORY_OPTIONAL = ("height", "gravity_load")


def _show(v) -> str:
    """A short JSON scalar as written, anything else by its kind."""
    if isinstance(v, (bool, int, float)) or v is None or (isinstance(v, str) and len(v) <= 20 and v.isprintable()):
        return repr(v)
    return kind_of(v)


def _collapse_block(c, source: str | None):
    """The optional ``collapse`` block: a mapping of a :class:`~hlaid.model.collapse.CollapseModel`."""
    if c is None:
        return None
    if not isinstance(c, dict):
        raise InputError(f"field 'collapse' must be a mapping of theta_p, theta_pc, kappa, theta_u, got {kind_of(c)}",
                         source=source)
    for k, v in c.items():
        if k not in ("name", "source"):
            _number(v, f"collapse.{k}", source)
    return c


def _number(v, field: str, source: str | None) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"{field} must be a finite number, got {_show(v)}", source=source)
    return float(v)


def _no_unknown(d: dict, allowed, prefix: str, source: str | None) -> None:
    unknown = [k for k in d if k not in allowed]
    if unknown:
        k = unknown[0]
        name = repr(prefix + k) if len(k) <= 40 and k.isprintable() else f"{prefix}<{len(k)} characters>"
        raise InputError(f"unknown field {name} (a typo, or a file of another program?); expected "
                         f"{', '.join(allowed)}", source=source)


def _check_units(units, source: str | None) -> None:
    """A clone's ``units`` block, when present, must be hlaid's (N, mm, t, s): values in other units
    would be taken as hlaid's silently."""
    if units is None:
        return
    if not isinstance(units, dict):
        raise InputError(f"field 'units' must be a mapping, got {kind_of(units)}", source=source)
    for key, want in UNITS_JSON.items():
        if units.get(key) != want:
            got = "missing" if key not in units else _show(units[key])
            raise InputError(f"units.{key} is {got}; hlaid clones are in {want!r} (N, mm, t, s): convert the "
                             "values and the units block", source=source)
    _no_unknown(units, tuple(UNITS_JSON), "units.", source)


def load_clone(path: str | os.PathLike) -> Clone:
    """Read a clone file (see :class:`Clone`)."""
    return Clone.load(path)


def jsonable(o):
    """``o`` with numpy arrays and scalars turned into lists and numbers (dict keys as text)."""
    if isinstance(o, dict):
        return {str(k): jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return jsonable(o.tolist())
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(o) else None
    if isinstance(o, (np.integer, np.bool_)):
        return o.item()
    return o
