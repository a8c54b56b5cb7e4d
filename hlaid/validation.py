"""Real-structure validation: identify a clone from one recorded event, predict the others.

The protocol of issue 7 (``docs/validation.md``, ``scripts/validate_real.py``). For every
structure of a :class:`ValidationConfig` and every identification event:

1. read the event (a reader of :data:`hlaid.io.MEASUREMENT_READERS`); no masses are given,
   so HLA and the clone are mass-normalised with the structure's ``mass_ratios``;
2. identify a clone with :func:`hlaid.identify.identify` (HLA, regressions, SVMs, replay
   refinement). When no story yielded (:class:`~hlaid.errors.NotIdentifiableError`) a
   nonlinear clone cannot be identified, and the protocol falls back, *labelled as such*, to
   a linear clone (``alpha = 1``): HLA's k0, fitted to the measured accelerations as the
   structure's ``fallback_fit`` says (:func:`linear_clone`);
3. save the clone JSON, load it back (:meth:`hlaid.clone.Clone.load`), and replay it under the
   ground motion of every prediction event (and of its own event, the self-replay);
4. compare per floor the predicted and measured displacement relative to the ground (measured
   displacements when the data hold them, else integrated accelerations; both band-passed
   alike): correlation ``R``, peak inter-story drift error, and the clone's elastic
   stiffness ke(t) against HLA's ke of that event (mean relative error over half cycles, the
   paper's 2.1 % metric).

Every number is in the package units, per unit of the (relative) masses when mass-normalised.
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from . import _progress
from .clone import Clone
from .config import config_from_dict, config_to_dict, load_config
from .errors import InputError, NotIdentifiableError
from .hla import HLAConfig, HLAResult, hla
from .hla import preprocess as pp
from .hla.analysis import floor_motion, resolved_band
from .identify import IdentifyConfig, identify, refine_replay
from .identify.replaycheck import corrcoef
from .io import MEASUREMENT_READERS, read_any
from .measurement import Measurement
from .model import Building, Damping
from .motions import GroundMotion
from .simulate import simulate

FALLBACK_FITS = ("scale+damping", "k0+damping", "k0", "damping", "none")
"""What the replay refinement fits of a linear clone (see :func:`linear_clone`)."""


# ---------------------------------------------------------------------------- config schema
@dataclass(frozen=True, kw_only=True)
class EventSpec:
    """One recorded event of a structure.

    Attributes
    ----------
    name : label used in ``identify_from`` / ``predict`` and in the tables
    path : data file or folder, relative to ``data_dir``
    options : reader options of this event (e.g. ``{event: 13}`` for the hotel)
    """

    name: str
    path: str
    options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, kw_only=True)
class StructureSpec:
    """A structure, its events, and how its clones are identified and compared.

    Attributes
    ----------
    name : short label (file names, tables); ``title`` a longer one
    reader : a :data:`hlaid.io.MEASUREMENT_READERS` name (null: detected from the file)
    options : reader options shared by every event
    events : the recorded events
    identify_from : events a clone is identified from
    predict : events every clone predicts (null: every event but its own); the clone's own
        event is always replayed too (self-replay, reported apart)
    identify_config : identification YAML (:class:`~hlaid.identify.IdentifyConfig`), relative
        to the validation config (null: the defaults)
    overrides : nested settings merged into it (e.g. ``{hla: {preprocess: {band_hz: [0.3, 2.5]}}}``)
    mass_ratios : relative floor masses (masses are unknown; null: equal)
    clone : ``"auto"``: the paper's identification, the fallback when no story yielded;
        ``"linear"``: the linear clone directly (for data known to be linear, where a yield
        flag of HLA would be an artefact)
    fallback : ``"linear"``: a labelled linear clone when no story yielded; ``"none"``: skip
    fallback_fit : what the replay fits of the linear clone, starting from HLA's k0 and the
        config's damping ratio (see :func:`linear_clone`)
    compare_band_hz : band [Hz] of the compared displacements and of the HLA of the predicted
        events (null: the HLA band that the identification config gives for each event)
    input_lowpass_hz : low-pass [Hz] of the ground motion the clone is driven by (null: the
        upper corner of the compared band)
    levels : names of the measured levels, bottom to top (null: floor 1, 2, ...)
    optional : run only when named (``structures=`` / ``--structures``), e.g. a sensitivity variant
    notes : what the data allow, printed with the tables
    """

    name: str
    title: str = ""
    reader: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    events: list[EventSpec]
    identify_from: list[str]
    predict: list[str] | None = None
    identify_config: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    mass_ratios: list[float] | None = None
    clone: Literal["auto", "linear"] = "auto"
    fallback: Literal["linear", "none"] = "linear"
    fallback_fit: Literal["scale+damping", "k0+damping", "k0", "damping", "none"] = "scale+damping"
    optional: bool = False
    compare_band_hz: tuple[float, float] | None = None
    input_lowpass_hz: float | None = None
    levels: list[str] | None = None
    notes: str = ""

    def __post_init__(self):
        names = [e.name for e in self.events]
        if len(set(names)) != len(names):
            raise InputError(f"structure {self.name!r}: event names must be unique, got {names}")
        for what, lst in (("identify_from", self.identify_from), ("predict", self.predict or [])):
            bad = [n for n in lst if n not in names]
            if bad:
                raise InputError(f"structure {self.name!r}: {what} names unknown events {bad}; expected some of {names}")
        if not self.identify_from:
            raise InputError(f"structure {self.name!r}: identify_from is empty")
        if self.reader is not None and self.reader not in MEASUREMENT_READERS:
            raise InputError(f"structure {self.name!r}: reader {self.reader!r} unknown; expected one of "
                             f"{', '.join(sorted(MEASUREMENT_READERS))}")
        if self.compare_band_hz is not None and not 0 <= self.compare_band_hz[0] < self.compare_band_hz[1]:
            raise InputError(f"structure {self.name!r}: compare_band_hz = {list(self.compare_band_hz)}; expected "
                             "[low, high] with 0 <= low < high")

    def event(self, name: str) -> EventSpec:
        return next(e for e in self.events if e.name == name)

    def targets_of(self, source: str) -> list[str]:
        return [e.name for e in self.events if e.name != source] if self.predict is None else \
            [n for n in self.predict if n != source]


@dataclass(frozen=True, kw_only=True)
class PaperTargets:
    """The paper's real-building results (E-Defense 3-story): replayed displacement
    ``R_corrcoef`` per floor and mean, and the stiffness-evolution error."""

    r_per_floor: list[float] = field(default_factory=lambda: [0.94, 0.92, 0.89])
    r_mean: float = 0.92
    stiffness_error: float = 0.021


@dataclass(frozen=True, kw_only=True)
class ValidationConfig:
    """``configs/validate_real.yaml``.

    Attributes
    ----------
    data_dir : folder of the datasets, relative to the config file
    cache_dir : classifier cache (null: ``~/.cache/hlaid/svm``; ``""``: none)
    structures : the structures
    targets : the paper's numbers the results are held against
    source : the config file (set by :func:`load_validation_config`)
    """

    data_dir: str = "."
    cache_dir: str | None = None
    structures: list[StructureSpec]
    targets: PaperTargets = field(default_factory=PaperTargets)
    source: str = ""

    def __post_init__(self):
        names = [s.name for s in self.structures]
        if len(set(names)) != len(names):
            raise InputError(f"structure names must be unique, got {names}")


def load_validation_config(path) -> ValidationConfig:
    """Load ``path`` (validated; FILE:LINE in every error) and resolve its relative paths
    against the config's folder."""
    cfg = load_config(path, ValidationConfig)
    base = Path(path).resolve().parent
    structures = [dataclasses.replace(s, identify_config=None if s.identify_config is None else
                                      str(base / s.identify_config)) for s in cfg.structures]
    return dataclasses.replace(cfg, data_dir=str(base / cfg.data_dir), structures=structures, source=str(path))


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def identify_config_of(spec: StructureSpec, *, source: str = "<validation>") -> IdentifyConfig:
    """The structure's :class:`IdentifyConfig`: its file, the overrides, the mass ratios."""
    base = load_config(spec.identify_config, IdentifyConfig) if spec.identify_config else IdentifyConfig()
    d = _merge(config_to_dict(base), spec.overrides)
    if spec.mass_ratios is not None:
        d = _merge(d, {"hla": {"force": {"mass_ratios": list(spec.mass_ratios)}}})
    return config_from_dict(IdentifyConfig, d, source=f"{source}: structure {spec.name!r} (identify config)")


def read_event(spec: StructureSpec, event: str, data_dir: str) -> Measurement:
    """The measurement of ``event`` (reader options: the structure's, then the event's)."""
    ev = spec.event(event)
    return read_any(Path(data_dir) / ev.path, spec.reader, **{**spec.options, **ev.options})


# ---------------------------------------------------------------------------- identification
@dataclass(frozen=True, eq=False)
class IdentifiedClone:
    """A clone identified from one event.

    Attributes
    ----------
    structure, event : where it came from
    clone : the clone as loaded back from its JSON file
    kind : ``"nonlinear"`` (paper's method) or ``"linear"`` (fallback: no story yielded)
    reason : why the fallback was taken ("" for nonlinear clones)
    path : file name of the clone JSON written
    seconds : wall time of the identification
    """

    structure: str
    event: str
    clone: Clone
    kind: str
    reason: str
    path: str
    seconds: float

    def identification(self) -> dict:
        """Per story: identifiable or not, and the SVM test accuracies of the last pass
        (nonlinear clones only)."""
        d = self.clone.diagnostics
        if self.kind != "nonlinear" or "stories" not in d:
            return {}
        last = {}
        for pas in d.get("passes", []):
            for i, st in enumerate(pas.get("stories", [])):
                if st:
                    last[i] = {k: v.get("test_accuracy") for k, v in st.items()}
        return {"identifiable": [s["identifiable"] for s in d["stories"]],
                "svm_test_accuracy": [last.get(i) for i in range(len(d["stories"]))],
                "refine": d.get("refine")}

    def summary(self) -> dict:
        b = self.clone.building
        return {"structure": self.structure, "event": self.event, "kind": self.kind, "reason": self.reason,
                "identification": self.identification(),
                "mass_normalised": self.clone.mass_normalised, "mass": b.mass.tolist(),
                **{k: getattr(b, k).tolist() for k in ("k0", "alpha", "p", "dy", "delta_eta")},
                "damping_ratio": b.damping.ratio, "periods_s": b.periods().tolist(), "path": self.path,
                "seconds": self.seconds}


def linear_clone(meas: Measurement, cfg: IdentifyConfig, *, fit: str = "scale+damping", reason: str = "") -> Clone:
    """A linear (``alpha = 1``) clone: HLA's k0 and the config's damping ratio, then fitted to
    the measured floor accelerations (``fit``): ``"scale+damping"`` one factor on every k0 and
    the damping ratio (HLA's stiffness distribution kept); ``"k0+damping"``, ``"k0"``,
    ``"damping"`` by :func:`refine_replay`; ``"none"``: HLA's k0 as they are."""
    res = hla(meas, cfg.hla)
    n = res.n_stories
    peak = np.array([np.max(np.abs(s.drift)) for s in res.stories])
    b = Building(mass=res.mass, k0=res.k0, alpha=np.ones(n), p=np.full(n, 2.0), dy=np.maximum(1e3 * peak, 1.0),
                 delta_eta=np.zeros(n), height=meas.height, damping=Damping(ratio=cfg.damping_ratio),
                 pdelta=meas.pdelta_active if meas.height is not None else None, name=meas.name)
    if fit not in FALLBACK_FITS:
        raise InputError(f"linear clone fit {fit!r}; expected one of {', '.join(FALLBACK_FITS)}")
    diag = {"kind": "linear", "reason": reason, "k0_hla": res.k0.tolist(), "hla_band_hz": list(res.band_hz),
            "fit": fit, "refine": None}
    if fit == "scale+damping":
        b, diag["refine"] = _fit_scale_damping(b, meas, cfg.refine.band_hz, cfg.refine.max_iterations)
    elif fit != "none":
        rr = refine_replay(b, meas, parameters=("k0",) if fit.startswith("k0") else (), damping="damping" in fit,
                           band_hz=cfg.refine.band_hz, max_iterations=cfg.refine.max_iterations)
        b = rr.building
        diag["refine"] = {"cost_initial": rr.cost_initial, "cost_final": rr.cost_final, "nfev": rr.nfev,
                          "message": rr.message}
    prov = {"source": meas.source, "config": config_to_dict(cfg), "method": f"linear clone (HLA k0; fitted: {fit})"}
    return Clone(building=b, mass_normalised=res.mass_normalised, diagnostics=diag, provenance=prov)


def _fit_scale_damping(b: Building, meas: Measurement, band_hz, max_iterations: int) -> tuple[Building, dict]:
    """Least squares of the replayed against the measured floor accelerations (band-passed, as
    :func:`refine_replay`) over one common factor on every story's k0 and the damping ratio:
    HLA's distribution of stiffness over the stories is kept."""
    from scipy.optimize import least_squares

    dt = meas.dt
    hi = min(band_hz[1], 0.45 / dt)
    ground = GroundMotion(dt=dt, acc=pp.bandpass(np.asarray(meas.ground_acc), dt, (0.0, hi)), name=meas.name)
    target = pp.bandpass(np.asarray(meas.floor_acc), dt, (band_hz[0], hi))
    rms = np.sqrt(np.mean(target**2, axis=0))
    d = b.damping

    def make(x):
        return b.replace(k0=b.k0 * np.exp(x[0]), damping=Damping(kind=d.kind, ratio=float(x[1]), modes=d.modes))

    def fun(x):
        r = simulate(make(x), ground)
        if r.status[0] != 0:
            return np.full(target.size, 1e3)
        return ((pp.bandpass(np.nan_to_num(r.acc[0]), dt, (band_hz[0], hi)) - target) / rms).ravel()

    sol = least_squares(fun, [0.0, d.ratio], bounds=([-1.0, 0.0], [1.0, 0.5]), x_scale=[0.05, 0.01],
                        max_nfev=max_iterations)
    return make(sol.x), {"k0_factor": float(np.exp(sol.x[0])), "cost_final": float(sol.cost),
                         "nfev": int(sol.nfev), "message": str(sol.message)}


def identify_event(spec: StructureSpec, event: str, meas: Measurement, cfg: IdentifyConfig, out_dir: Path,
                   cache_dir: str | None = None) -> IdentifiedClone | None:
    """Identify a clone from ``meas``; the linear fallback when no story yielded (None when
    the structure's ``fallback`` is ``"none"``). The clone is written to
    ``out_dir/<structure>_<event>.json`` and read back."""
    t0 = time.perf_counter()
    kind, reason = "nonlinear", ""
    try:
        if spec.clone == "linear":
            raise NotIdentifiableError("the config asks for a linear clone (clone: linear)")
        clone = identify(meas, cfg, cache_dir=cache_dir).clone
    except NotIdentifiableError as err:
        reason = str(err).removeprefix(f"{meas.source}: ")
        if spec.fallback == "none" and spec.clone != "linear":
            _progress.warn(f"{spec.name}/{event}: not identifiable, skipped ({reason})")
            return None
        _progress.info(f"[validate] {spec.name}/{event}: linear clone ({reason})")
        kind = "linear"
        clone = linear_clone(meas, cfg, fit=spec.fallback_fit, reason=reason)
    path = out_dir / f"{spec.name}_{event}.json"
    clone.save(path, force=True)  # clone_dir is rewritten on every run
    loaded = Clone.load(path)
    return IdentifiedClone(structure=spec.name, event=event, clone=loaded, kind=kind, reason=reason, path=path.name,
                           seconds=time.perf_counter() - t0)


# ---------------------------------------------------------------------------- prediction
@dataclass(frozen=True, eq=False)
class Prediction:
    """A clone replayed under one event, against what was measured.

    Attributes
    ----------
    structure, identified_from, event, kind : which clone, which event
    self_replay : the event the clone was identified from
    pga_g : peak ground acceleration of the event [g]
    band_hz : band of the compared displacements [Hz]
    r : (floor,) correlation of predicted and measured displacement relative to the ground
    r_broadband : (floor,) the same with the band's upper corner raised to 20 Hz (below 0.45
        of the sampling rate): what the measured displacement holds above the compared band
        counts against the clone
    peak_drift_measured, peak_drift_predicted : (story,) peak inter-story drift [mm] (band-passed)
    peak_drift_error : (story,) ``predicted / measured - 1``
    stiffness_error : (story,) mean over HLA half cycles of ``|ke_clone / ke_HLA - 1|`` (NaN
        when HLA of the event failed)
    status : simulator status (0 ok, 2 diverged)
    time, disp_measured, disp_predicted : (time,), (time, floor) [s, mm] (not serialised)
    drift_predicted, force_predicted, ke_clone : (time, story) clone drift, spring force, ke(t)
    hla : the HLA of the event (None when it failed)
    """

    structure: str
    identified_from: str
    event: str
    kind: str
    self_replay: bool
    pga_g: float
    band_hz: tuple[float, float]
    r: np.ndarray
    r_broadband: np.ndarray
    peak_drift_measured: np.ndarray
    peak_drift_predicted: np.ndarray
    peak_drift_error: np.ndarray
    stiffness_error: np.ndarray
    status: int
    time: np.ndarray = field(repr=False)
    disp_measured: np.ndarray = field(repr=False)
    disp_predicted: np.ndarray = field(repr=False)
    drift_predicted: np.ndarray = field(repr=False)
    force_predicted: np.ndarray = field(repr=False)
    ke_clone: np.ndarray = field(repr=False)
    hla: HLAResult | None = field(default=None, repr=False)

    def summary(self) -> dict:
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in
                (("structure", self.structure), ("identified_from", self.identified_from), ("event", self.event),
                 ("kind", self.kind), ("self_replay", self.self_replay), ("pga_g", self.pga_g),
                 ("band_hz", list(self.band_hz)), ("r", self.r), ("r_mean", float(np.mean(self.r))),
                 ("r_broadband", self.r_broadband),
                 ("peak_drift_measured", self.peak_drift_measured), ("peak_drift_predicted", self.peak_drift_predicted),
                 ("peak_drift_error", self.peak_drift_error), ("stiffness_error", self.stiffness_error),
                 ("stiffness_error_mean", _nanmean(self.stiffness_error)), ("status", self.status))}


def _nanmean(x) -> float | None:
    x = np.asarray(x, dtype=float)
    return float(np.nanmean(x)) if np.isfinite(x).any() else None


def _with_band(cfg: HLAConfig, band) -> HLAConfig:
    return cfg if band is None else dataclasses.replace(
        cfg, preprocess=dataclasses.replace(cfg.preprocess, band_hz=tuple(band)))


def predict_event(clone: Clone, meas: Measurement, hla_config: HLAConfig, *, compare_band_hz=None,
                  input_lowpass_hz: float | None = None, labels: tuple[str, str, str, str] = ("", "", "", ""),
                  self_replay: bool = False) -> Prediction:
    """Replay ``clone`` under ``meas``'s ground motion and compare with what was measured.

    Parameters
    ----------
    clone : the clone (its masses must be the ones ``hla_config`` gives ``meas``)
    meas : the event
    hla_config : HLA settings of the structure (mass ratios, damping handling, band)
    compare_band_hz : band of the comparison and of the event's HLA (None: HLA's band)
    input_lowpass_hz : low-pass of the ground motion (None: the band's upper corner)
    labels : ``(structure, identified_from, event, kind)``
    """
    cfg = _with_band(hla_config, compare_band_hz)
    dt = meas.dt
    try:
        res = hla(meas, cfg)
        band = tuple(res.band_hz)
    except InputError as err:  # too weak or too short for HLA: no stiffness comparison
        _progress.warn(f"{labels[0]}/{labels[2]}: HLA failed ({err}); no stiffness comparison")
        res, band = None, tuple(resolved_band(meas, cfg))
        cfg = _with_band(cfg, band)
    hi_in = min(input_lowpass_hz or band[1], 0.45 / dt)
    ground = GroundMotion(dt=dt, acc=pp.bandpass(np.asarray(meas.ground_acc), dt, (0.0, hi_in), cfg.preprocess.order),
                          name=meas.name)
    sim = simulate(clone.building, ground)
    # the clone's response goes through what the measured one went through: its displacement
    # band-passed when the data hold displacements, else its accelerations integrated
    integrated = cfg.preprocess.displacement == "integrate" or (cfg.preprocess.displacement == "auto" and
                                                               meas.floor_disp is None)
    twin = dataclasses.replace(meas, ground_acc=ground.acc, floor_acc=np.nan_to_num(sim.acc[0]), floor_disp=None,
                               truth=None, mass=None)

    def compare(b):
        c = _with_band(cfg, b)
        _, _, _, dm = floor_motion(meas, c)
        dp = floor_motion(twin, c)[3] if integrated else pp.bandpass(np.nan_to_num(sim.disp[0]), dt, b, c.preprocess.order)
        return dm, dp

    disp_meas, dp = compare(band)
    r = corrcoef(dp, disp_meas)
    r_broad = corrcoef(*compare((band[0], max(band[1], min(20.0, 0.45 / dt)))))
    xm, xp = pp.story_drift(disp_meas), pp.story_drift(dp)
    pm, pk = np.max(np.abs(xm), axis=0), np.max(np.abs(xp), axis=0)
    ke = clone.building.elastic_stiffness(np.nan_to_num(sim.eta[0], nan=1.0))
    err = np.full(clone.building.n_stories, np.nan)
    if res is not None:
        for i, s in enumerate(res.stories):
            hc = s.half_cycles
            if len(hc):
                err[i] = float(np.mean(np.abs(ke[hc.start, i] / hc.ke - 1.0)))
    return Prediction(structure=labels[0], identified_from=labels[1], event=labels[2], kind=labels[3],
                      self_replay=self_replay, pga_g=float(np.max(np.abs(meas.ground_acc)) / 9806.65), band_hz=band,
                      r=r, r_broadband=r_broad, peak_drift_measured=pm, peak_drift_predicted=pk, peak_drift_error=pk / pm - 1.0,
                      stiffness_error=err, status=int(sim.status[0]), time=meas.time, disp_measured=disp_meas,
                      disp_predicted=dp, drift_predicted=xp, force_predicted=np.nan_to_num(sim.force[0]), ke_clone=ke,
                      hla=res)


# ---------------------------------------------------------------------------- the protocol
@dataclass(frozen=True, eq=False)
class ValidationResult:
    """Clones and predictions of a validation run.

    Attributes
    ----------
    clones : one per (structure, identification event) that gave a clone
    predictions : self-replays and cross-event predictions
    targets : the paper's numbers
    notes : per structure, what the data allow
    seconds : wall time
    """

    clones: list[IdentifiedClone]
    predictions: list[Prediction]
    targets: PaperTargets
    notes: dict[str, str]
    seconds: float

    def structure_summary(self) -> list[dict]:
        """Per structure: mean and worst R and mean stiffness error over the cross-event
        predictions (and the self-replays apart)."""
        out = []
        for name in dict.fromkeys(p.structure for p in self.predictions):
            row = {"structure": name}
            for tag, sel in (("cross", False), ("self", True)):
                ps = [p for p in self.predictions if p.structure == name and p.self_replay == sel]
                if not ps:
                    continue
                r = np.array([p.r for p in ps])
                se = np.array([p.stiffness_error for p in ps])
                pe = np.abs(np.array([p.peak_drift_error for p in ps]))
                row[tag] = {"n": len(ps), "r_mean": float(r.mean()), "r_worst": float(r.min()),
                            "r_mean_per_floor": r.mean(axis=0).tolist(),
                            "peak_drift_error_mean": float(pe.mean()), "peak_drift_error_worst": float(pe.max()),
                            "stiffness_error_mean": _nanmean(se)}
            out.append(row)
        return out

    def to_dict(self) -> dict:
        return {"format": "hlaid-validation", "version": 1, "seconds": self.seconds,
                "targets": config_to_dict(self.targets), "notes": self.notes,
                "clones": [c.summary() for c in self.clones],
                "predictions": [p.summary() for p in self.predictions],
                "summary": self.structure_summary()}


def run_validation(cfg: ValidationConfig, *, clone_dir: str | None = None, structures: list[str] | None = None,
                   cache_dir: str | None = None) -> ValidationResult:
    """Run the protocol over the structures of ``cfg`` (or the named ``structures``).

    Parameters
    ----------
    cfg : the validation config (:func:`load_validation_config`)
    clone_dir : where the clone JSON files are written (default: a temporary folder)
    structures : names of the structures to run (default all)
    cache_dir : classifier cache (overrides ``cfg.cache_dir``)
    """
    t0 = time.perf_counter()
    names = [s.name for s in cfg.structures]
    for n in structures or []:
        if n not in names:
            raise InputError(f"unknown structure {n!r}; expected one of {names}", source=cfg.source or None)
    cache = cache_dir if cache_dir is not None else cfg.cache_dir
    clones, preds = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(clone_dir) if clone_dir else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        for spec in cfg.structures:
            if (structures and spec.name not in structures) or (not structures and spec.optional):
                continue
            icfg = identify_config_of(spec, source=cfg.source or "<validation>")
            meas = {}

            def get(ev, spec=spec, meas=meas):
                if ev not in meas:
                    meas[ev] = read_event(spec, ev, cfg.data_dir)
                return meas[ev]

            for src in spec.identify_from:
                _progress.info(f"[validate] {spec.name}: identifying a clone from {src}")
                ic = identify_event(spec, src, get(src), icfg, out, cache)
                if ic is None:
                    continue
                clones.append(ic)
                for ev in [src] + spec.targets_of(src):
                    preds.append(predict_event(ic.clone, get(ev), icfg.hla, compare_band_hz=spec.compare_band_hz,
                                               input_lowpass_hz=spec.input_lowpass_hz, self_replay=ev == src,
                                               labels=(spec.name, src, ev, ic.kind)))
                    p = preds[-1]
                    _progress.info(f"[validate] {spec.name}: {src} -> {ev}: R {np.round(p.r, 3)}, "
                                   f"stiffness error {_fmt_pct(_nanmean(p.stiffness_error))}")
    return ValidationResult(clones=clones, predictions=preds, targets=cfg.targets,
                            notes={s.name: s.notes for s in cfg.structures
                                   if (s.name in structures if structures else not s.optional)},
                            seconds=time.perf_counter() - t0)


def _fmt_pct(x) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{100 * x:.1f} %"


# ---------------------------------------------------------------------------- tables
def _f(x, fmt="{:.3f}") -> str:
    return "-" if x is None or not np.isfinite(x) else fmt.format(x)


def _pct(x) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{100 * x:+.0f}"


def _met(ok: bool | None) -> str:
    return "-" if ok is None else ("yes" if ok else "**no**")


def _row(*cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _rule(n: int) -> str:
    return "|" + "---|" * n


def _joined(values, fmt: str) -> str:
    return " / ".join(fmt.format(v) for v in values)


def _clone_table(result: ValidationResult) -> list[str]:
    out = [_row("structure", "identified from", "clone", "k0 per story [N/mm per unit mass]", "alpha", "p", "dy [mm]",
                "delta_eta", "damping", "f1 [Hz]", "time [s]"), _rule(11)]
    for c in result.clones:
        b, lin = c.clone.building, c.kind == "linear"
        shape = ["-"] * 4 if lin else [_joined(b.alpha, "{:.2f}"), _joined(b.p, "{:.2f}"), _joined(b.dy, "{:.1f}"),
                                       _joined(b.delta_eta, "{:.2f}")]
        out.append(_row(c.structure, c.event, "linear (fallback)" if lin else "nonlinear", _joined(b.k0, "{:.4g}"),
                        *shape, f"{b.damping.ratio:.3f}", f"{1.0 / b.periods()[0]:.2f}", f"{c.seconds:.0f}"))
    reasons = {f"{c.structure}/{c.event}": c.reason for c in result.clones if c.reason}
    if reasons:
        out += ["", "Linear clones, why: " + "; ".join(f"{k}: {v}" for k, v in reasons.items()) + "."]
    return out


def _prediction_table(ps: list[Prediction], tg: PaperTargets) -> list[str]:
    n = ps[0].r.shape[0]
    rt = tg.r_per_floor if n == len(tg.r_per_floor) else None
    against = f" against the paper's {' / '.join(map(str, rt))}" if rt else ""
    out = [(f"Band {ps[0].band_hz[0]:.3g}-{ps[0].band_hz[1]:.3g} Hz. R per floor{against}, mean against {tg.r_mean}; "
            f"stiffness error against {100 * tg.stiffness_error:.1f} %. Peak-drift and stiffness errors in % per story."),
           "", _row("clone from", "event", "PGA [g]", *[f"R {i + 1}" for i in range(n)], "R mean", "floors met",
                    "mean met", "R broadband", "peak drift error", "stiffness error", "mean", "met"),
           _rule(n + 11)]
    for p in ps:
        r_mean, se = float(np.mean(p.r)), _nanmean(p.stiffness_error)
        floors = "-" if rt is None else f"{sum(r >= t for r, t in zip(p.r, rt))}/{n}"
        out.append(_row(f"{p.identified_from} ({p.kind})", f"{p.event} (self)" if p.self_replay else p.event,
                        f"{p.pga_g:.3f}", *[_f(r) for r in p.r], _f(r_mean), floors, _met(r_mean >= tg.r_mean),
                        _f(float(np.mean(p.r_broadband))), " / ".join(_pct(e) for e in p.peak_drift_error),
                        " / ".join(_f(100 * e, "{:.1f}") for e in p.stiffness_error),
                        _f(None if se is None else 100 * se, "{:.1f}"),
                        _met(None if se is None else se <= tg.stiffness_error)))
    return out


def _summary_rows(name: str, ps: list[Prediction], tg: PaperTargets) -> list[str]:
    """One row per clone, and with several clones: all of them, and the predictions of
    stronger events (PGA above the clone's own event) only."""
    groups = [(src, [p for p in ps if p.identified_from == src]) for src in dict.fromkeys(p.identified_from for p in ps)]
    own_pga = {p.identified_from: p.pga_g for p in ps if p.self_replay}
    cross_all = [p for p in ps if not p.self_replay]
    stronger = [p for p in cross_all if p.pga_g > own_pga.get(p.identified_from, np.inf)]
    rows = list(groups)
    if len(groups) > 1:
        rows.append(("all", ps))
        if 0 < len(stronger) < len(cross_all):
            rows.append(("all, stronger events only", stronger))
    out = []
    for src, g in rows:
        cross = [p for p in g if not p.self_replay]
        own = [p for p in g if p.self_replay]
        r_self = _f(float(np.mean([np.mean(p.r) for p in own]))) if own else "-"
        if not cross:
            out.append(_row(name, src, 0, *["-"] * 7, r_self))
            continue
        r = np.array([p.r for p in cross])
        se = _nanmean(np.array([p.stiffness_error for p in cross]))
        pe = float(np.mean(np.abs([p.peak_drift_error for p in cross])))
        out.append(_row(name, src, len(cross), f"{r.mean():.3f}", f"{r.min():.3f}", _met(r.mean() >= tg.r_mean),
                        f"{np.mean([p.r_broadband for p in cross]):.3f}", f"{100 * pe:.0f} %",
                        f"{_f(None if se is None else 100 * se, '{:.1f}')} %",
                        _met(None if se is None else se <= tg.stiffness_error), r_self))
    return out


def format_tables(result: ValidationResult) -> str:
    """Markdown tables of a validation run: clones, predictions per structure, summary (every
    number, each held against the paper's targets)."""
    tg = result.targets
    out = ["### Clones", "", *_clone_table(result)]
    names = list(dict.fromkeys(p.structure for p in result.predictions))
    for name in names:
        out += ["", f"### {name}", "", *_prediction_table([p for p in result.predictions if p.structure == name], tg)]
    out += ["", "### Summary (cross-event predictions; self-replays apart)", "",
            _row("structure", "clone from", "predictions", "mean R", "worst R", f"mean R >= {tg.r_mean}",
                 "mean R broadband", "mean abs peak-drift error", "mean stiffness error",
                 f"<= {100 * tg.stiffness_error:.1f} %", "self-replay R"), _rule(11)]
    for name in names:
        out += _summary_rows(name, [p for p in result.predictions if p.structure == name], tg)
    return "\n".join(out) + "\n"
