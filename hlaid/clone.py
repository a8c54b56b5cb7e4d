"""The digital clone file: an identified building, versioned JSON in N, mm, t, s.

Layout::

    {"format": "hlaid-clone", "version": 4,
     "units": {"force": "N", "length": "mm", "mass": "t", "time": "s", ...},
     "stories": [{"k0": ..., "alpha": ..., "p": ..., "dy": ..., "delta_eta": ..., "mass": ...,
                  "height": ... (optional), "gravity_load": ... (optional, N)}, ...],
     "damping": {"kind": "rayleigh", "ratio": 0.05, "modes": [1, 2]},
     "pdelta": null | true | false,
     "mass_normalised": false,
     "collapse": {"name": ..., "theta_p": ..., "theta_pc": ..., "kappa": ..., "theta_u": ...}
                 (optional: the strength-loss model IDA uses, see hlaid.model.collapse),
     "diagnostics": {...} (what the identification did, for the reader: hlaid never reads it back),
     "provenance": {...} (input files and digests, hlaid version, timings),
     "identification": {"laws": null | {...}, "start_rule": null | {...}, "parameters": null | [...],
                        "fit_replays": [...], "paper": null | {...}, "update_check": null | {...},
                        "fallbacks": [...]}
                       (version 4: the decisions later steps read, see hlaid.record),
     "settings": null | {"config": {...}, "choices": [...]}   (version 4, hlaid.record.Settings),
     "coupling": {"flexural": [...]} (optional: the linear floor coupling beside the story springs,
                 hlaid.model.coupling; absent: the shear chain),
     "modes": {...} (optional: the clone's modes at small amplitude beside the records', hlaid.model.modes),
     "linear": {...} (optional: which linear part the clone has and why, hlaid.record.LinearPart),
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
null: undamaged). Version 4 keeps the clone's decisions as types (:mod:`hlaid.record`): the
``identification`` block and the ``settings``; a version-3 file's ``diagnostics`` and
``provenance["config"]`` are converted into them on reading (:meth:`Clone.from_dict`, the one place
that reads those keys). Version 1 and 2 files (none of these) are still read, as undamaged clones.

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
from .model.modes import ModalCheck
from .model.schema import STATE_BOUNDS, check_damping_ratios, check_event, check_state
from .model.state import BuildingState
from .record import (
    STARTS,
    EventRecord,
    Fallback,
    FitReplay,
    LawChoice,
    LinearPart,
    PaperMethod,
    ParameterFlag,
    Settings,
    StartRule,
    UpdateCheck,
)
from .systems import SYSTEMS
from .units import UNITS_JSON

if TYPE_CHECKING:
    from .model.uncertainty import ParameterUncertainty

FORMAT = "hlaid-clone"
VERSION = 4
READS = (1, 2, 3, 4)
"""Clone file versions this hlaid reads (it writes :data:`VERSION`)."""
_STORY_KEYS = ("k0", "alpha", "p", "dy", "delta_eta", "mass")


@dataclass(frozen=True, eq=False)
class Clone:
    """An identified building with what is known about how it was identified.

    Attributes
    ----------
    building : the identified shear building
    mass_normalised : masses are relative (unknown absolute masses)
    diagnostics : what the identification did (errors, iterations, passes, ...), written for the
        reader; hlaid never reads it back (its decisions are the typed fields below)
    provenance : input file hash, package version, timings
    uncertainty : the identified parameters' uncertainty (None: a point estimate only)
    system : the structural system whose prior the identification used (None: none)
    events : the events the clone was identified from, oldest first (:class:`~hlaid.record.EventRecord`;
        mappings of its fields are converted)
    state : the state its last event left the building in (None: undamaged, at rest)
    laws : the laws its stories follow (None: not chosen, every entry free)
    start_rule : where its next replay starts under ``start="auto"`` (None: from the state it
        carries, at rest where it carries none)
    parameters : where each fitted parameter comes from (None: not said, a clone of the paper's
        method alone)
    fit_replays : the replay of each event its last fit saw (R per floor, stiffness error)
    paper : per story what the paper's method found (a clone of one record without a system)
    update_check : the check of its last update against the earlier events (None: not updated)
    fallbacks : the stages of its identification that failed numerically, and what was used instead
    settings : the settings its identification used (None: not kept)
    modes : its modes at small amplitude beside the records' (:class:`hlaid.model.modes.ModalCheck`;
        None: not assessed, a file from before)
    linear : which linear part the clone has, shear chain or coupled, and why
        (:class:`hlaid.record.LinearPart`; None: the shear chain, not chosen)
    """

    building: Building
    mass_normalised: bool = False
    diagnostics: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    uncertainty: ParameterUncertainty | None = None
    system: str | None = None
    events: tuple[EventRecord, ...] = ()
    state: BuildingState | None = None
    laws: LawChoice | None = None
    start_rule: StartRule | None = None
    parameters: tuple[ParameterFlag, ...] | None = None
    fit_replays: tuple[FitReplay, ...] = ()
    paper: PaperMethod | None = None
    update_check: UpdateCheck | None = None
    fallbacks: tuple[Fallback, ...] = ()
    settings: Settings | None = None

    def __post_init__(self) -> None:
        if any(not isinstance(e, EventRecord) for e in self.events):
            object.__setattr__(self, "events", tuple(e if isinstance(e, EventRecord) else EventRecord.from_dict(e)
                                                     for e in self.events))
        elif not isinstance(self.events, tuple):
            object.__setattr__(self, "events", tuple(self.events))

    def story_laws(self) -> tuple[str, ...] | None:
        """The law each story follows (None where the clone names none: every entry free)."""
        return None if self.laws is None else self.laws.laws(self.building.n_stories)
    modes: ModalCheck | None = None
    linear: LinearPart | None = None

    def survived_drift(self, *, measured_only: bool = False) -> np.ndarray | None:
        """``(story,)`` the largest drift of each story the building survived [mm]: the measured
        peak of each event it was identified from (``events[k].peak_drift``) and, unless
        ``measured_only``, the largest drifts of the state the clone carries (its replay of those
        events); None where neither is known."""
        n = self.building.n_stories
        peaks = [np.asarray(e.peak_drift, dtype=float) for e in self.events
                 if e.peak_drift is not None and len(e.peak_drift) == n]
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
            r = e.replay
            if r is None or not r.peak_drift_error:
                continue
            err = np.asarray(r.peak_drift_error, dtype=float)
            j = int(np.argmax(np.abs(err)))
            if worst is None or abs(err[j]) > abs(worst[0]):
                worst = (float(err[j]), j, e.label(k), (float(r.band_hz[0]), float(r.band_hz[1])))
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
                "system": self.system, "events": jsonable([e.to_dict() for e in self.events]),
                "state": None if self.state is None else self.state.to_dict(),
                "identification": jsonable(self.identification_dict()),
                "settings": None if self.settings is None else jsonable(self.settings.to_dict()),
                **({"modes": self.modes.to_dict()} if self.modes is not None else {}),
                **({"linear": self.linear.to_dict()} if self.linear is not None else {}),
                **({"collapse": b.collapse.to_dict()} if b.collapse is not None else {}),
                **({"coupling": b.coupling.to_dict()} if b.coupling is not None else {})}

    def identification_dict(self) -> dict:
        """The file's ``identification`` block: the decisions later steps read (:mod:`hlaid.record`)."""
        return {"laws": None if self.laws is None else self.laws.to_dict(),
                "start_rule": None if self.start_rule is None else self.start_rule.to_dict(),
                "parameters": None if self.parameters is None else [f.to_dict() for f in self.parameters],
                "fit_replays": [r.to_dict() for r in self.fit_replays],
                "paper": None if self.paper is None else self.paper.to_dict(),
                "update_check": None if self.update_check is None else self.update_check.to_dict(),
                "fallbacks": [f.to_dict() for f in self.fallbacks]}

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
                    + (("system", "events", "state", "modes", "linear") if version >= 3 else ())
                    + (("identification", "settings") if version >= 4 else ()), "", source)
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
        damping = _damping_block(d.get("damping", {}), source)
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
        typed = _typed(d, version, events, state, source)
        return cls(building=b, mass_normalised=d.get("mass_normalised", False), uncertainty=unc,
                   system=system, events=events, state=state, **_linear_part(d, source), **typed)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Clone:
        """Read and validate a clone JSON file."""
        return cls.from_dict(read_json(path), source=str(path))


_TYPED = ("laws", "start_rule", "parameters", "update_check", "fallbacks")
"""The keys of a version-3 ``diagnostics`` that are the clone's typed fields from version 4 on."""

LAST_EVENT_UNDAMAGED = ("its last event was explained better from an undamaged start: the building recovered between "
                        "its events")
"""The start rule of a clone made before the prequential rule whose last update chose an undamaged start."""


def _damping_block(damping: object, source: str | None) -> dict:
    """A clone file's ``damping`` block, checked (its keys, kind, ratios and mode numbers)."""
    if not isinstance(damping, dict):
        raise InputError(f"field 'damping' must be a mapping, got {kind_of(damping)}", source=source)
    _no_unknown(damping, ("kind", "ratio", "modes", "ratio2", "higher"), "damping.", source)
    if "kind" in damping and not isinstance(damping["kind"], str):
        raise InputError(f"damping.kind must be a string, got {kind_of(damping['kind'])}", source=source)
    if "ratio" in damping:
        _number(damping["ratio"], "damping.ratio", source)
    check_damping_ratios(damping, source)
    modes = damping.get("modes", [1, 2])
    if not (isinstance(modes, list) and all(isinstance(m, int) and not isinstance(m, bool) for m in modes)):
        raise InputError("damping.modes must be a list of two mode numbers such as [1, 2]", source=source)
    return damping


def _linear_part(d: dict, source: str | None) -> dict:
    """The clone file's ``modes`` and ``linear`` blocks as the Clone's fields (absent: None)."""
    modes = None
    if d.get("modes") is not None:
        modes = ModalCheck.from_dict(d["modes"], source=source)
    linear = None if d.get("linear") is None else LinearPart.from_dict(d["linear"], source=source)
    return {"modes": modes, "linear": linear}


def _typed(d: dict, version: int, events: tuple[EventRecord, ...], state: BuildingState | None,
           source: str | None) -> dict:
    """The clone's typed fields (:mod:`hlaid.record`) and its write-only ``diagnostics`` and
    ``provenance``: a version-4 file's ``identification`` and ``settings`` blocks, or converted
    from the keys of an older file (``diagnostics``, ``provenance["config"]`` and ``["choices"]``)."""
    diag, prov = dict(d.get("diagnostics") or {}), dict(d.get("provenance") or {})
    where = "identification" if version >= 4 else "diagnostics"
    try:
        if version >= 4:
            block = d.get("identification") or {}
            if not isinstance(block, dict):
                raise InputError(f"field 'identification' must be a mapping, got {kind_of(block)}")
            _no_unknown(block, _BLOCK_KEYS, "identification.", None)
            st = d.get("settings")
            out = _records(block, block.get("fit_replays") or (), block.get("paper"))
            out["settings"] = None if st is None else Settings.from_dict(_mapping(st, "settings"))
        else:
            out = _records({**diag, "start_rule": _old_rule(diag.get("start_rule"))}, _old_fit_replays(diag),
                           _old_paper(diag), strict=False)
            out["settings"] = (Settings.from_dict(prov) if isinstance(prov.get("config"), dict) or prov.get("choices")
                               else None)
            if out["start_rule"] is None and state is not None and events and events[-1].start == "undamaged":
                out["start_rule"] = StartRule("undamaged", LAST_EVENT_UNDAMAGED, rule="last event")
            diag = {k: v for k, v in diag.items() if k not in _TYPED}
            prov = {k: v for k, v in prov.items() if k not in ("config", "choices")}
    except InputError as err:
        raise InputError(str(err), source=source) from None
    except (TypeError, ValueError, KeyError, AttributeError, OverflowError) as err:
        raise InputError(f"field '{where}' is not a clone's record ({err})", source=source) from None
    return {**out, "diagnostics": diag, "provenance": prov}


_BLOCK_KEYS = ("laws", "start_rule", "parameters", "fit_replays", "paper", "update_check", "fallbacks")
"""The keys of a version-4 file's ``identification`` block."""


def _mapping(v, name: str) -> dict:
    if not isinstance(v, dict):
        raise InputError(f"field '{name}' must be a mapping, got {kind_of(v)}")
    return v


def _records(block: dict, fit_replays, paper, *, strict: bool = True) -> dict:
    """The typed records of a block holding ``laws``, ``start_rule``, ``parameters`` and ``update_check``
    (not ``strict``: a version-3 start rule of no known choice is none, as it was read then)."""
    rule = block.get("start_rule")
    if not strict and not (isinstance(rule, dict) and rule.get("choice") in STARTS):
        rule = None
    rows = block.get("parameters")
    laws, check = block.get("laws"), block.get("update_check")
    return {"laws": LawChoice.from_dict(laws) if isinstance(laws, dict) else None,
            "start_rule": None if rule is None else StartRule.from_dict(_mapping(rule, "start_rule")),
            "parameters": (None if not isinstance(rows, list) else
                           tuple(ParameterFlag.from_dict(r) for r in rows if isinstance(r, dict))),
            "fit_replays": tuple(FitReplay.from_dict(_mapping(r, "fit_replays[]")) for r in fit_replays),
            "paper": None if paper is None else PaperMethod.from_dict(_mapping(paper, "paper")),
            "update_check": UpdateCheck.from_dict(check) if isinstance(check, dict) else None,
            "fallbacks": tuple(Fallback.from_dict(f) for f in block.get("fallbacks") or () if isinstance(f, dict))}


def _old_rule(rule):
    """A version-3 start rule in version 4's words (``rest``: ``undamaged``)."""
    if not isinstance(rule, dict):
        return rule
    out = {k: v for k, v in rule.items() if k != "carried_minus_rest"}
    if "carried_minus_rest" in rule:
        out["carried_minus_undamaged"] = rule["carried_minus_rest"]
    return {**out, "choice": "undamaged"} if rule.get("choice") == "rest" else out


def _old_event(e: dict) -> dict:
    """A version-3 event record in version 4's words (its prequential record's ``rest``: ``undamaged``)."""
    pq = e.get("prequential")
    if not isinstance(pq, dict) or "rest" not in pq:
        return e
    return {**e, "prequential": {**{k: v for k, v in pq.items() if k != "rest"}, "undamaged": pq["rest"]}}


def _old_fit_replays(diag: dict) -> list:
    """A version-3 clone's replays of the events its last fit saw: the joint fit's per event, else
    the paper's method's one."""
    found = [e for e in ((diag.get("joint") or {}).get("events") or []) if isinstance(e, dict)]
    if not found and isinstance(diag.get("replay"), dict):
        found = [diag["replay"]]
    return found


def _old_paper(diag: dict) -> dict | None:
    """A version-3 clone's stories of the paper's method (None: not a clone of it)."""
    stories = diag.get("stories")
    if not isinstance(stories, list) or not all(isinstance(s, dict) and "identifiable" in s for s in stories):
        return None
    last: dict[int, dict] = {}
    for pas in diag.get("passes") or []:
        for i, st in enumerate(pas.get("stories", []) if isinstance(pas, dict) else []):
            if st:
                last[i] = {k: v.get("test_accuracy") for k, v in st.items()}
    return {"stories": [{**s, "story": s.get("story", i + 1), "svm_test_accuracy": last.get(i)}
                        for i, s in enumerate(stories)], "refine": diag.get("refine")}


def _history(d: dict, n: int, source: str | None) -> tuple[str | None, tuple[EventRecord, ...], BuildingState | None]:
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
    try:
        old = d.get("version") in (1, 2, 3)
        records = tuple(EventRecord.from_dict(_old_event(e) if old else e) for e in events)
    except InputError as err:
        raise InputError(str(err), source=source) from None
    except (TypeError, ValueError, OverflowError) as err:
        raise InputError(f"field 'events' is not a list of event records ({err})", source=source) from None
    return system, records, state


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
