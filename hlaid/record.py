"""The clone's record: each decision a clone carries, as a frozen dataclass.

A clone (:class:`hlaid.clone.Clone`) is a building and what is known about how it was identified.
What later steps read back (which law a story follows, where a replay starts, how the clone
replayed its events, which parameters the data hardly informed, the settings that were used) is
held here as types, one per decision, not as a mapping read back by string key:

- :class:`StoryLaw`: a law a story follows (elastic, non-degrading, degrading) and which of its
  entries the records may move; :data:`STORY_LAWS` is the one registry of them;
- :class:`LawChoice`: the laws a clone's stories follow, and why;
- :class:`StartRule`: where the clone's next replay starts (``"carried"`` or ``"undamaged"``:
  :data:`STARTS`, the one start vocabulary) and its evidence;
- :class:`StartScore`, :class:`Prequential`: how the clone before an event predicted it from each start;
- :class:`OwnReplay`: how the clone's full replay met one of its own events;
- :class:`FitReplay`: the replay of an event the last fit saw (R per floor, stiffness error);
- :class:`EventRecord`: an event the clone learnt from, its start, its replays;
- :class:`ParameterFlag`: where a parameter comes from, whether it sits at a search bound;
- :class:`PaperStory`, :class:`PaperMethod`: what the paper's method found of each story;
- :class:`UpdateCheck`: the check of an update against the earlier events;
- :class:`Fallback`: a stage that failed numerically and what was used instead;
- :class:`SettingChoice`, :class:`Settings`: the resolved settings and the choices made from the data.

Each type writes itself with ``to_dict`` and reads itself with ``from_dict`` (the layout of the
clone file, version 4); :meth:`hlaid.clone.Clone.from_dict` is the one place that reads the older
files' keys (``diagnostics``, ``provenance["config"]``) and converts them.

Adding a field
--------------
A new decision the clone carries is a frozen dataclass here (or in the module that makes it,
when it needs more than numbers and text), with ``to_dict`` returning plain JSON values and a
``from_dict`` classmethod that reads that mapping back; then a field of
:class:`hlaid.clone.Clone` with a default (``None`` or ``()``, so that every existing constructor
call keeps working), its key written in :meth:`~hlaid.clone.Clone.to_dict` and read in
:meth:`~hlaid.clone.Clone.from_dict` (added to the keys it allows), and a line in the clone's
module docstring. A file that lacks the key reads as the default. A new field of an existing
record gets a default too, so that a file written before it keeps loading.

Light: numbers and text only (no numpy, no torch).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from .errors import InputError

# ----------------------------------------------------------------------------- story laws
ENTRIES = ("k0", "alpha", "p", "cy", "delta_eta")
"""A story's entries in prior units (:mod:`hlaid.joint.vector`: ``log k0, logit(alpha / 0.95),
log(p - 1), log Cy, log delta_eta``), in this order."""


@dataclass(frozen=True)
class StoryLaw:
    """A law a story follows: which of its entries (:data:`ENTRIES`) the records may move.

    Attributes
    ----------
    name : ``"elastic"``, ``"nondegrading"`` or ``"degrading"``
    held : the entries held at fixed values (:func:`hlaid.joint.laws.with_laws` says which:
        ``alpha`` and ``p`` the system's medians, ``cy`` far beyond any drift, ``delta_eta`` no
        degradation); the others are free
    title : in words
    """

    name: str
    held: tuple[str, ...]
    title: str

    @property
    def free(self) -> tuple[bool, ...]:
        """Per entry of :data:`ENTRIES`, whether the records may move it."""
        return tuple(e not in self.held for e in ENTRIES)


STORY_LAWS: dict[str, StoryLaw] = {law.name: law for law in (
    StoryLaw("elastic", ("alpha", "p", "cy", "delta_eta"), "elastic: only k0 moves"),
    StoryLaw("nondegrading", ("delta_eta",), "non-degrading Bouc-Wen: no degradation"),
    StoryLaw("degrading", (), "degrading Bouc-Wen: every entry moves (the paper's law)"),
)}
"""The story laws, nested: each one's free entries are a subset of the next one's."""


def story_law(name: str) -> StoryLaw:
    """The law called ``name`` (InputError naming the known ones otherwise)."""
    try:
        return STORY_LAWS[name]
    except (KeyError, TypeError):
        raise InputError(f"story law {name!r} is unknown; expected one of {', '.join(STORY_LAWS)}") from None


@dataclass(frozen=True)
class LawChoice:
    """The laws a clone's stories follow and why.

    Attributes
    ----------
    chosen : one law name per story (None: the clone names none, every entry free)
    default : the structural system's laws (None: not said)
    reason : why, in words
    kept : set where an update kept the laws its clone was identified with (why, in words)
    tie_log_units, screen_margin : the margins the choice used (None: not said)
    candidates : what was compared (laws, log evidence, seconds, how judged), for the reader
    """

    chosen: tuple[str, ...] | None
    default: tuple[str, ...] | None = None
    reason: str = ""
    kept: str | None = None
    tie_log_units: float | None = None
    screen_margin: float | None = None
    candidates: tuple[Mapping, ...] = ()

    def laws(self, n_stories: int) -> tuple[str, ...] | None:
        """The chosen laws where they are ``n_stories`` known ones, else None."""
        c = self.chosen
        if c is not None and len(c) == n_stories and all(law in STORY_LAWS for law in c):
            return c
        return None

    @classmethod
    def kept_by_update(cls, old: LawChoice | None, n_stories: int) -> LawChoice:
        """The laws record of a clone updated from one whose record is ``old``: its laws where they
        are one known law per story (said to be kept), else none (every entry free)."""
        old = old or cls(chosen=None)
        laws = old.laws(n_stories)
        if laws is None:
            return replace(old, chosen=None, reason="the clone names no story laws: every entry free (degrading)")
        return replace(old, chosen=laws, kept="an update keeps the laws its clone was identified with")

    def to_dict(self) -> dict:
        return {"chosen": _list(self.chosen), "default": _list(self.default), "reason": self.reason,
                **({"kept": self.kept} if self.kept is not None else {}),
                "tie_log_units": self.tie_log_units, "screen_margin": self.screen_margin,
                "candidates": [dict(c) for c in self.candidates]}

    @classmethod
    def from_dict(cls, d: Mapping) -> LawChoice:
        return cls(chosen=_strs(d.get("chosen")), default=_strs(d.get("default")), reason=str(d.get("reason") or ""),
                   kept=None if d.get("kept") is None else str(d["kept"]),
                   tie_log_units=_num(d.get("tie_log_units")), screen_margin=_num(d.get("screen_margin")),
                   candidates=tuple(dict(c) for c in d.get("candidates") or () if isinstance(c, Mapping)))


# ----------------------------------------------------------------------------- where a replay starts
STARTS = ("carried", "undamaged")
"""Where a replay of a clone starts: from the state its events left (``carried``) or at rest
(``undamaged``). ``"auto"`` asks the clone's :class:`StartRule`."""


@dataclass(frozen=True)
class StartRule:
    """Where a clone's next replay starts (``start="auto"``) and why.

    Attributes
    ----------
    choice : ``"carried"`` or ``"undamaged"``
    reason : why, in words
    rule : ``"prequential"`` (the events already predicted decide, :mod:`hlaid.events.prequential`)
        or ``"last event"`` (a clone made before the rule: how its last event was explained)
    n : events the rule scored
    margin : by how much the carried start's mean R must beat the undamaged one's
    carried_minus_undamaged : the mean R of the carried start less the undamaged one's (None: none scored)
    """

    choice: str
    reason: str = ""
    rule: str = "prequential"
    n: int = 0
    margin: float | None = None
    carried_minus_undamaged: float | None = None

    def __post_init__(self) -> None:
        if self.choice not in STARTS:
            raise InputError(f"start rule choice {self.choice!r}; expected one of {', '.join(STARTS)}")

    def to_dict(self) -> dict:
        return {"rule": self.rule, "choice": self.choice, "reason": self.reason, "n": self.n, "margin": self.margin,
                "carried_minus_undamaged": self.carried_minus_undamaged}

    @classmethod
    def from_dict(cls, d: Mapping) -> StartRule:
        return cls(choice=str(d.get("choice")), reason=str(d.get("reason") or ""),
                   rule=str(d.get("rule") or "prequential"), n=int(d.get("n") or 0), margin=_num(d.get("margin")),
                   carried_minus_undamaged=_num(d.get("carried_minus_undamaged")))


@dataclass(frozen=True)
class StartScore:
    """How a clone predicted an event from one start: mean floor R, mean story-drift R and the
    peak-drift error per story (a fraction)."""

    r: float
    drift_r: float | None = None
    pde: tuple[float, ...] = ()

    def to_dict(self) -> dict:
        return {"r": self.r, "drift_r": self.drift_r, "pde": list(self.pde)}

    @classmethod
    def from_dict(cls, d: Mapping) -> StartScore:
        return cls(r=_real(d.get("r")), drift_r=_num(d.get("drift_r")), pde=_nums(d.get("pde")))


@dataclass(frozen=True)
class Prequential:
    """How the clone of the events before one predicted it, from each start.

    Attributes
    ----------
    clone_of : the events that clone learnt from
    carried : from the state they left (None: that clone carried none)
    undamaged : from rest
    prefix : how that clone was made (``{"by": "newton" | "fit", ...}``), for the reader
    """

    clone_of: tuple[str, ...] = ()
    carried: StartScore | None = None
    undamaged: StartScore | None = None
    prefix: Mapping | None = None

    def scored(self) -> tuple[float, float] | None:
        """``(R carried, R undamaged)`` where both are finite numbers, else None."""
        if self.carried is None or self.undamaged is None:
            return None
        rc, ru = self.carried.r, self.undamaged.r
        return (rc, ru) if math.isfinite(rc) and math.isfinite(ru) else None

    def to_dict(self) -> dict:
        return {"clone_of": list(self.clone_of),
                **({"carried": self.carried.to_dict()} if self.carried is not None else {}),
                **({"undamaged": self.undamaged.to_dict()} if self.undamaged is not None else {}),
                **({"prefix": dict(self.prefix)} if self.prefix is not None else {})}

    @classmethod
    def from_dict(cls, d: Mapping) -> Prequential:
        def score(key: str) -> StartScore | None:
            v = d.get(key)
            return StartScore.from_dict(v) if isinstance(v, Mapping) else None
        return cls(clone_of=_strs(d.get("clone_of")) or (), carried=score("carried"), undamaged=score("undamaged"),
                   prefix=dict(d["prefix"]) if isinstance(d.get("prefix"), Mapping) else None)


# ----------------------------------------------------------------------------- replays
@dataclass(frozen=True)
class OwnReplay:
    """How the clone's full replay of one of its own events met the records, in the band they
    hold: per story the signed peak-drift error (a fraction: +0.1 is 10 % high) and the
    story-drift correlation R (:func:`hlaid.events.replay.own_replay`)."""

    band_hz: tuple[float, float]
    peak_drift_error: tuple[float, ...]
    drift_r: tuple[float, ...] = ()

    def to_dict(self) -> dict:
        return {"band_hz": list(self.band_hz), "peak_drift_error": list(self.peak_drift_error),
                "drift_r": list(self.drift_r)}

    @classmethod
    def from_dict(cls, d: Mapping) -> OwnReplay:
        band = _nums(d.get("band_hz")) or (math.nan, math.nan)
        return cls(band_hz=(band[0], band[1]), peak_drift_error=_nums(d.get("peak_drift_error")),
                   drift_r=_nums(d.get("drift_r")))


@dataclass(frozen=True)
class FitReplay:
    """The replay of an event the clone's last fit saw, in the fit's band
    (:class:`hlaid.identify.replaycheck.ReplayCheck`): per floor the correlation R with the
    measured displacements (and with the true ones of a simulation), per story the
    stiffness-evolution error."""

    name: str | None
    r_measured: tuple[float, ...]
    stiffness_error: tuple[float, ...] = ()
    r_true: tuple[float, ...] | None = None

    def to_dict(self) -> dict:
        return {"name": self.name, "r_measured": list(self.r_measured), "stiffness_error": list(self.stiffness_error),
                "r_true": _list(self.r_true)}

    @classmethod
    def from_dict(cls, d: Mapping) -> FitReplay:
        return cls(name=None if d.get("name") is None else str(d["name"]), r_measured=_nums(d.get("r_measured")),
                   stiffness_error=_nums(d.get("stiffness_error")),
                   r_true=None if d.get("r_true") is None else _nums(d["r_true"]))


# ----------------------------------------------------------------------------- events
@dataclass(frozen=True)
class EventRecord:
    """An event a clone learnt from.

    Attributes
    ----------
    name, source : its name and file
    sha256, ground_sha256 : digests of the file and of its ground record
    pga_g, duration_s, dt, n_floors, recorded : what it was
    ground_profile : the ground record's RMS in equal windows (:func:`hlaid.measurement.ground_profile`)
    start : where its fit's replay started (``"carried"`` or ``"undamaged"``), where an update chose
    prequential : how the clone before it predicted it
    peak_drift : the largest story drifts measured [mm] (what the building survived)
    replay : how the clone's full replay met it
    """

    name: str | None = None
    source: str | None = None
    sha256: str | None = None
    ground_sha256: str | None = None
    pga_g: float | None = None
    duration_s: float | None = None
    dt: float | None = None
    n_floors: int | None = None
    recorded: str | None = None
    ground_profile: tuple[float, ...] | None = None
    start: str | None = None
    prequential: Prequential | None = None
    peak_drift: tuple[float, ...] | None = None
    replay: OwnReplay | None = None

    def __post_init__(self) -> None:
        if self.start is not None and self.start not in STARTS:
            raise InputError(f"event start {self.start!r}; expected one of {', '.join(STARTS)}")

    def label(self, k: int) -> str:
        """Its name, or ``event k+1``."""
        return self.name or f"event {k + 1}"

    def to_dict(self) -> dict:
        out: dict[str, Any] = {"name": self.name, "source": self.source, "sha256": self.sha256,
                               "ground_sha256": self.ground_sha256, "pga_g": self.pga_g, "duration_s": self.duration_s,
                               "dt": self.dt, "n_floors": self.n_floors, "ground_profile": _list(self.ground_profile)}
        for key in ("recorded", "start"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        if self.peak_drift is not None:
            out["peak_drift"] = list(self.peak_drift)
        if self.prequential is not None:
            out["prequential"] = self.prequential.to_dict()
        if self.replay is not None:
            out["replay"] = self.replay.to_dict()
        return {k: v for k, v in out.items() if v is not None or k in ("name", "source", "sha256")}

    @classmethod
    def from_dict(cls, d: Mapping) -> EventRecord:
        pq, rp = d.get("prequential"), d.get("replay")
        return cls(name=_str(d.get("name")), source=_str(d.get("source")), sha256=_str(d.get("sha256")),
                   ground_sha256=_str(d.get("ground_sha256")), pga_g=_num(d.get("pga_g")),
                   duration_s=_num(d.get("duration_s")), dt=_num(d.get("dt")),
                   n_floors=None if d.get("n_floors") is None else int(d["n_floors"]), recorded=_str(d.get("recorded")),
                   ground_profile=None if d.get("ground_profile") is None else _nums(d["ground_profile"]),
                   start=_str(d.get("start")),
                   prequential=Prequential.from_dict(pq) if isinstance(pq, Mapping) else None,
                   peak_drift=None if d.get("peak_drift") is None else _nums(d["peak_drift"]),
                   replay=OwnReplay.from_dict(rp) if isinstance(rp, Mapping) and rp.get("peak_drift_error") else None)


# ----------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class ParameterFlag:
    """Where one identified parameter comes from.

    Attributes
    ----------
    name : ``k0``, ``alpha``, ``p``, ``dy``, ``delta_eta``, ``damping``, ``damping2`` or ``mass``
    story : its story (1-based; None: a building-wide one, the damping)
    value : its value
    source : ``"data"``, or where the data hardly informed it, whose value it keeps (``"prior"``:
        the structural system's; ``"earlier events"``: an update's)
    informed : how much the data narrowed it (None: not said)
    at_limit : it sits at a bound the search uses (:func:`hlaid.joint.vector.at_limit`)
    implausible : the structural system's prior makes it implausible
    """

    name: str
    story: int | None
    value: float
    source: str = "data"
    informed: float | None = None
    at_limit: bool = False
    implausible: bool = False

    def label(self) -> str:
        """``name[story]`` (the name alone for a building-wide one)."""
        return f"{self.name}[{self.story}]" if self.story else self.name

    def to_dict(self) -> dict:
        return {"name": self.name, "story": self.story, "value": self.value, "source": self.source,
                "informed": self.informed, "at_limit": self.at_limit, "implausible": self.implausible}

    @classmethod
    def from_dict(cls, d: Mapping) -> ParameterFlag:
        return cls(name=str(d["name"]), story=None if d.get("story") is None else int(d["story"]),
                   value=_real(d.get("value")), source=str(d.get("source") or "data"),
                   informed=_num(d.get("informed")), at_limit=bool(d.get("at_limit")),
                   implausible=bool(d.get("implausible")))


@dataclass(frozen=True)
class PaperStory:
    """What the paper's method found of one story (a clone of one record without a system).

    Attributes
    ----------
    story : 1-based
    identifiable : it yielded enough for its hysteresis parameters to be identified
    k0_hla : HLA's elastic stiffness [N/mm]
    reason : why not identifiable ("" where it is)
    svm_test_accuracy : per classifier, its test accuracy in the last pass (None: not said)
    """

    story: int
    identifiable: bool
    k0_hla: float | None = None
    reason: str = ""
    svm_test_accuracy: Mapping[str, float | None] | None = None

    def to_dict(self) -> dict:
        return {"story": self.story, "identifiable": self.identifiable, "k0_hla": self.k0_hla, "reason": self.reason,
                "svm_test_accuracy": None if self.svm_test_accuracy is None else dict(self.svm_test_accuracy)}

    @classmethod
    def from_dict(cls, d: Mapping) -> PaperStory:
        acc = d.get("svm_test_accuracy")
        return cls(story=int(d["story"]), identifiable=bool(d.get("identifiable")), k0_hla=_num(d.get("k0_hla")),
                   reason=str(d.get("reason") or ""), svm_test_accuracy=dict(acc) if isinstance(acc, Mapping) else None)


@dataclass(frozen=True)
class PaperMethod:
    """What the paper's method found (a clone of one record without a system): per story
    (:class:`PaperStory`), and the summary of the refinement after it (None: none)."""

    stories: tuple[PaperStory, ...]
    refine: Mapping | None = None

    def to_dict(self) -> dict:
        return {"stories": [s.to_dict() for s in self.stories],
                "refine": None if self.refine is None else dict(self.refine)}

    @classmethod
    def from_dict(cls, d: Mapping) -> PaperMethod:
        ref = d.get("refine")
        return cls(stories=tuple(PaperStory.from_dict(s) for s in d.get("stories") or ()),
                   refine=dict(ref) if isinstance(ref, Mapping) else None)


@dataclass(frozen=True)
class UpdateCheck:
    """The check of an update against the clone's earlier events (:mod:`hlaid.events.guard`).

    Attributes
    ----------
    events : earlier events checked (or that would have been)
    misfit_change : their log misfit's change, exact (None: not computed)
    gaussian : the change the posterior predicted
    excess, limit : by how much it exceeded that, and the limit
    refit : the update forgot them (the events are fitted jointly again)
    refitted : the joint refit was made
    missing : the earlier records not at hand
    note : a note where the check was not made
    """

    events: int = 0
    misfit_change: float | None = None
    gaussian: float | None = None
    excess: float | None = None
    limit: float | None = None
    refit: bool = False
    refitted: bool = False
    missing: tuple[str, ...] = ()
    note: str | None = None

    def to_dict(self) -> dict:
        return {"events": self.events, "misfit_change": self.misfit_change, "gaussian": self.gaussian,
                "excess": self.excess, "limit": self.limit, "refit": self.refit, "refitted": self.refitted,
                "missing": list(self.missing), "note": self.note}

    @classmethod
    def from_dict(cls, d: Mapping) -> UpdateCheck:
        return cls(events=int(d.get("events") or 0), misfit_change=_num(d.get("misfit_change")),
                   gaussian=_num(d.get("gaussian")), excess=_num(d.get("excess")), limit=_num(d.get("limit")),
                   refit=bool(d.get("refit")), refitted=bool(d.get("refitted")),
                   missing=tuple(str(m) for m in d.get("missing") or ()), note=_str(d.get("note")))


@dataclass(frozen=True)
class Fallback:
    """A stage of the identification that failed numerically and what was used instead
    (:func:`hlaid.joint.fallback.run_stage`)."""

    stage: str
    error: str
    used: str

    def to_dict(self) -> dict:
        return {"stage": self.stage, "error": self.error, "used": self.used}

    @classmethod
    def from_dict(cls, d: Mapping) -> Fallback:
        return cls(stage=str(d.get("stage") or ""), error=str(d.get("error") or ""), used=str(d.get("used") or ""))


# ----------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class SettingChoice:
    """A setting chosen from the data: its key (``"hla.preprocess.band_hz"``), value and evidence."""

    setting: str
    value: Any
    reason: str

    def to_dict(self) -> dict:
        return {"setting": self.setting, "value": self.value, "reason": self.reason}

    @classmethod
    def from_dict(cls, d: Mapping) -> SettingChoice:
        return cls(setting=str(d["setting"]), value=d.get("value"), reason=str(d.get("reason") or ""))


@dataclass(frozen=True)
class Settings:
    """The settings an identification used.

    Attributes
    ----------
    config : the resolved identification config as written (:func:`hlaid.config.config_to_dict`:
        no ``"auto"`` left where it was resolved)
    choices : the settings chosen from the data, with their evidence
    given : the config as it was given, its ``"auto"`` settings still so (None: not kept)
    """

    config: Mapping = field(default_factory=dict)
    choices: tuple[SettingChoice, ...] = ()
    given: Mapping | None = None

    def value(self, key: str, default: Any = None) -> Any:
        """The setting ``key`` (dotted: ``"refine.band_hz"``), ``default`` where it is not kept."""
        d: Any = self.config
        for part in key.split("."):
            if not isinstance(d, Mapping) or part not in d:
                return default
            d = d[part]
        return d

    def choice(self, key: str) -> SettingChoice | None:
        """The choice made for ``key`` (None: none)."""
        return next((c for c in self.choices if c.setting == key), None)

    def to_dict(self) -> dict:
        return {"config": dict(self.config), "choices": [c.to_dict() for c in self.choices],
                "given": None if self.given is None else dict(self.given)}

    @classmethod
    def from_dict(cls, d: Mapping) -> Settings:
        cfg, given = d.get("config"), d.get("given")
        return cls(config=dict(cfg) if isinstance(cfg, Mapping) else {},
                   choices=tuple(SettingChoice.from_dict(c) for c in d.get("choices") or () if isinstance(c, Mapping)),
                   given=dict(given) if isinstance(given, Mapping) else None)


# ----------------------------------------------------------------------------- helpers
def _num(v) -> float | None:
    return None if v is None or isinstance(v, bool) else float(v)


def _real(v) -> float:
    """A number, NaN where it is not given."""
    return math.nan if v is None or isinstance(v, bool) else float(v)


def _nums(v) -> tuple[float, ...]:
    if v is None:
        return ()
    if isinstance(v, (str, bytes, Mapping)) or not isinstance(v, Sequence):
        raise TypeError(f"expected a list of numbers, got {type(v).__name__}")
    return tuple(math.nan if x is None else float(x) for x in v)


def _strs(v) -> tuple[str, ...] | None:
    if v is None:
        return None
    if isinstance(v, (str, bytes, Mapping)) or not isinstance(v, Sequence):
        raise TypeError(f"expected a list of names, got {type(v).__name__}")
    return tuple(str(x) for x in v)


def _str(v) -> str | None:
    return None if v is None else str(v)


def _list(v) -> list | None:
    return None if v is None else list(v)


FORMS = ("shear", "coupled")
"""The linear parts a clone may have."""


@dataclass(frozen=True)
class LinearPart:
    """Which linear part the clone has and why (a typed field of the clone: ``Clone.linear``).

    Attributes
    ----------
    form : ``"shear"`` (the shear chain) or ``"coupled"`` (:mod:`hlaid.model.coupling`)
    log_evidence : per form tried, its Laplace log evidence (a common ``n_eff``), None where
        it was not fitted
    reason : one sentence
    record : the record the records' modes were identified from
    """

    form: str = "shear"
    log_evidence: tuple[tuple[str, float | None], ...] = ()
    reason: str = ""
    record: str = ""

    def __post_init__(self):
        if self.form not in FORMS:
            raise InputError(f"field 'linear.form' must be one of {', '.join(FORMS)}, got {self.form!r}")

    def to_dict(self) -> dict:
        return {"form": self.form, "log_evidence": {k: v for k, v in self.log_evidence}, "reason": self.reason,
                "record": self.record}

    @classmethod
    def from_dict(cls, d, *, source: str | None = None) -> LinearPart:
        try:
            if not isinstance(d, Mapping) or not set(d) <= {"form", "log_evidence", "reason", "record"}:
                raise InputError("field 'linear' must be a mapping of form, log_evidence, reason and record")
            ev = d.get("log_evidence") or {}
            if not isinstance(ev, Mapping) or not all(
                    k in FORMS and (v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)))
                    for k, v in ev.items()):
                raise InputError("field 'linear.log_evidence' must map shear/coupled to numbers")
            if not all(isinstance(d.get(k, ""), str) for k in ("form", "reason", "record")):
                raise InputError("fields 'linear.form', 'linear.reason' and 'linear.record' must be strings")
            return cls(d.get("form", "shear"), tuple((k, None if v is None else float(v)) for k, v in ev.items()),
                       d.get("reason", ""), d.get("record", ""))
        except InputError as e:
            raise InputError(str(e), source=source) from None


__all__ = ["FORMS", "LinearPart", "ENTRIES", "STORY_LAWS", "STARTS", "EventRecord", "Fallback", "FitReplay",
           "LawChoice", "OwnReplay",
           "PaperMethod", "PaperStory", "ParameterFlag", "Prequential", "SettingChoice", "Settings", "StartRule",
           "StartScore", "StoryLaw", "UpdateCheck", "story_law"]
