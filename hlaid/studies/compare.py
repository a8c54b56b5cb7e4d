"""Comparison studies: every identifier on the same simulated cases.

A case is a structure (the paper's Table 1 or a random shear building), a real record
scaled to a PGA and resampled, a noise level and a noise seed. Every identifier of
:data:`hlaid.baselines.IDENTIFIERS` fits the same simulated measurement; each outcome records the parameter
errors against the truth, the replay correlation ``R`` of floor displacements with the
truth on the identification record and on an unseen record, the peak-drift error on the
unseen record, the wall and CPU time of ``fit``, and whether it failed (an exception, a
non-finite parameter, a replay that diverges, or ``R`` below ``failure_r`` on the
identification record), with the reason.

``scripts/compare_identifiers.py --config configs/compare.yaml`` runs a study and writes its
tables, plots and TensorBoard logs.
"""

from __future__ import annotations

import dataclasses
import os
import resource
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np

from .. import _progress
from ..baselines.registry import IDENTIFIERS, get_identifier
from ..config import load_config
from ..errors import InputError, one_line
from ..estimators import BaseIdentifier
from ..identify import IdentifyConfig
from ..identify.replaycheck import corrcoef
from ..model import Building
from ..motions import GroundMotion
from ..simulate import simulate_response
from ..specs import MotionSpec
from ..synthetic import load_simulation_config, simulate_measurement

PARAMETERS = ("k0", "alpha", "p", "dy", "delta_eta")

LABELS = {"hlasvm": "HLA+SVM (paper)", "hlasvm_replay": "HLA+SVM + refinement", "gradient": "Gradient LS (AD)",
          "ukf": "UKF"}


@dataclass(frozen=True, kw_only=True)
class RandomStructureSpec:
    """Random shear buildings: ranges drawn uniformly (k0 is scaled so that the first period
    is ``period_s``); a structure is redrawn until every story reaches ``min_ductility``
    (peak drift / dy) under its identification record."""

    stories: int = 3
    mass_t: tuple[float, float] = (10.0, 25.0)
    period_s: tuple[float, float] = (0.25, 0.6)
    alpha: tuple[float, float] = (0.05, 0.35)
    p: tuple[float, float] = (1.2, 2.8)
    dy_mm: tuple[float, float] = (3.0, 10.0)
    delta_eta: tuple[float, float] = (0.3, 1.5)
    min_ductility: float = 1.5

    def __post_init__(self):
        if self.stories < 1:
            raise InputError(f"random.stories = {self.stories}; expected >= 1")
        for name in ("mass_t", "period_s", "alpha", "p", "dy_mm", "delta_eta"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise InputError(f"random.{name} = [{lo}, {hi}]; expected 0 <= low <= high")


@dataclass(frozen=True, kw_only=True)
class CaseGroup:
    """A product of cases: structures x records x noise levels x seeds.

    Attributes
    ----------
    structure : ``"table1"`` or ``"random"``; count : random structures in the group
    records : identification records (``builtin:NAME`` or a path), scaled to ``pga_g``
    noise : noise levels (std as a fraction of each channel's RMS); seeds : noise seeds
    """

    records: list[str]
    structure: Literal["table1", "random"] = "table1"
    count: int = 1
    noise: list[float] = field(default_factory=lambda: [0.10])
    seeds: list[int] = field(default_factory=lambda: [0])

    def __post_init__(self):
        if not self.records or not self.noise or not self.seeds or self.count < 1:
            raise InputError("a group needs records, noise levels, seeds and count >= 1")
        if any(not 0 <= n < 1 for n in self.noise):
            raise InputError(f"noise = {list(self.noise)}; expected fractions such as 0.10")


@dataclass(frozen=True, kw_only=True)
class CompareConfig:
    """A comparison study (``configs/compare.yaml``).

    Attributes
    ----------
    groups : the cases
    identifiers : names in :data:`hlaid.baselines.IDENTIFIERS`, run in this order on every case
    settings : per identifier, keyword arguments of its class (``hlasvm*``: ``config`` is an
        identification YAML, relative to the study config)
    table1 : simulation config whose ``building`` is the Table 1 structure
    unseen_record : a record never identified on; every clone and the truth replay it
    pga_g, rate_hz : records scaled to this PGA and resampled
    window_s, before_peak_s : a window of the record (null: the whole record)
    random, random_seed : random structures
    failure_r : an outcome with replay R (min over stories, identification record) below
        this is a failure
    share_hlasvm_cache : the two HLA+SVM variants share the trained classifiers (a fresh
        cache per study); the replay variant's wall time then adds the paper variant's
    """

    groups: list[CaseGroup]
    identifiers: list[str] = field(default_factory=lambda: list(IDENTIFIERS))
    settings: dict[str, dict[str, Any]] = field(default_factory=dict)
    table1: str = "poc_3story.yaml"
    unseen_record: str = "builtin:kobe-1995-nis000"
    pga_g: float = 0.62
    rate_hz: float = 200.0
    window_s: float | None = 14.0
    before_peak_s: float = 4.0
    random: RandomStructureSpec = field(default_factory=RandomStructureSpec)
    random_seed: int = 1
    failure_r: float = 0.5
    share_hlasvm_cache: bool = True

    def __post_init__(self):
        unknown = [n for n in self.identifiers if n not in IDENTIFIERS]
        if unknown or not self.identifiers:
            raise InputError(f"identifiers: unknown {unknown}; expected some of {list(IDENTIFIERS)}")
        bad = [n for n in self.settings if n not in IDENTIFIERS]
        if bad:
            raise InputError(f"settings: unknown identifier(s) {bad}; expected some of {list(IDENTIFIERS)}")


def load_compare_config(path) -> CompareConfig:
    return load_config(path, CompareConfig)


@dataclass(frozen=True, eq=False)
class Case:
    """One simulated measurement every identifier fits."""

    name: str
    structure: str
    building: Building
    motion: GroundMotion
    noise: float
    seed: int


@dataclass(frozen=True)
class Outcome:
    """One identifier on one case.

    Attributes
    ----------
    case, identifier, structure, record, noise, seed : what ran
    failed : bool; reason : why (empty when it did not fail)
    wall_s, cpu_s : time of ``fit`` (CPU: this process and its finished worker processes);
        wall_own_s, cpu_own_s : the identifier's own times (they differ from ``wall_s`` and
        ``cpu_s`` only for the replay variant with a shared classifier cache, whose totals
        add the paper variant's times on the same case)
    errors : per parameter, (story,) signed relative error of the clone against the truth
    mean_error, max_error : mean and largest |relative error| over every story parameter
    r_ident, r_unseen : (story,) replay R of floor displacements with the truth
    drift_error_unseen : (story,) relative error of the peak drift on the unseen record
    clone : the clone as JSON (None when it raised)
    """

    case: str
    identifier: str
    structure: str
    record: str
    noise: float
    seed: int
    failed: bool
    reason: str
    wall_s: float
    wall_own_s: float
    cpu_s: float
    cpu_own_s: float
    errors: dict | None = None
    mean_error: float = float("nan")
    max_error: float = float("nan")
    r_ident: list | None = None
    r_unseen: list | None = None
    drift_error_unseen: list | None = None
    clone: dict | None = None

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


# ---------------------------------------------------------------------- cases
def study_record(spec: str, cfg: CompareConfig, base_dir=None) -> GroundMotion:
    """A record of the study: read, scaled to ``pga_g``, resampled, windowed."""
    gm = MotionSpec(file=spec, pga_g=cfg.pga_g).load(base_dir).resampled(cfg.rate_hz)
    if cfg.window_s is None:
        return gm
    i0 = max(0, int(np.argmax(np.abs(gm.acc))) - round(cfg.before_peak_s / gm.dt))
    n = round(cfg.window_s / gm.dt) + 1
    return GroundMotion(dt=gm.dt, acc=gm.acc[i0:i0 + n], name=f"{gm.name}[{cfg.window_s:g}s]", source=gm.source)


def random_structure(spec: RandomStructureSpec, motion: GroundMotion, rng: np.random.Generator, name: str,
                     tries: int = 200) -> Building:
    """A random building (see :class:`RandomStructureSpec`) that yields under ``motion``."""
    n = spec.stories
    for _ in range(tries):
        mass = rng.uniform(*spec.mass_t, n)
        k0 = rng.uniform(1.0, 2.0, n)[::-1].cumsum()[::-1] / n  # stiffer at the bottom
        b = Building(mass=mass, k0=k0, alpha=rng.uniform(*spec.alpha, n), p=rng.uniform(*spec.p, n),
                     dy=rng.uniform(*spec.dy_mm, n), delta_eta=rng.uniform(*spec.delta_eta, n), name=name)
        t1 = rng.uniform(*spec.period_s)
        b = b.replace(k0=b.k0 * (b.periods()[0] / t1) ** 2)
        r = simulate_response(b, motion, outputs="peaks")
        if r.status[0] == 0 and np.all(r.peak_drift[0] >= spec.min_ductility * b.dy):
            return b
    raise InputError(f"no random structure in {tries} draws reaches ductility {spec.min_ductility} on every story "
                     f"under {motion.name}; widen the random ranges or raise pga_g")


def build_cases(cfg: CompareConfig, base_dir: str | os.PathLike | None = None) -> list[Case]:
    """Every case of the study, in order."""
    base = Path(base_dir) if base_dir is not None else Path(".")
    table1 = load_simulation_config(base / cfg.table1).building.build(source=str(base / cfg.table1))
    rng = np.random.default_rng(cfg.random_seed)
    cases, n_random = [], 0
    for group in cfg.groups:
        for spec in group.records:
            motion = study_record(spec, cfg, base)
            structures = []
            if group.structure == "table1":
                structures.append(("table1", table1))
            else:
                for _ in range(group.count):
                    n_random += 1
                    structures.append((f"random{n_random}", random_structure(cfg.random, motion, rng,
                                                                              f"random{n_random}")))
            for label, b in structures:
                for noise in group.noise:
                    for seed in group.seeds:
                        cases.append(Case(name=f"{label}/{motion.name}/noise{100 * noise:g}/seed{seed}",
                                          structure=label, building=b, motion=motion, noise=noise, seed=seed))
    return cases


# ---------------------------------------------------------------------- identifiers
def make_identifier(name: str, settings: dict | None = None, *, base_dir=None, cache_dir: str = "") -> BaseIdentifier:
    """An identifier of :data:`hlaid.baselines.IDENTIFIERS` with keyword ``settings`` (validated against its
    parameters); HLA+SVM gets ``cache_dir`` and a ``config`` path is loaded."""
    est = get_identifier(name)
    kw = dict(settings or {})
    if name.startswith("hlasvm"):
        if "refine" in kw:
            raise InputError(f"settings.{name}.refine: fixed by the identifier's name (hlasvm: none, "
                             "hlasvm_replay: the config's refinement)")
        if isinstance(kw.get("config"), str):
            kw["config"] = load_config(Path(base_dir or ".") / kw["config"], IdentifyConfig)
        kw.setdefault("cache_dir", cache_dir)
    allowed = est.get_params()
    bad = [k for k in kw if k not in allowed]
    if bad:
        raise InputError(f"settings.{name}: unknown {bad}; expected some of {sorted(allowed)}")
    return get_identifier(name, **kw)


def _cpu() -> float:
    own = time.process_time()
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own + ch.ru_utime + ch.ru_stime


def _replay_r(building: Building, motion: GroundMotion, true_disp: np.ndarray):
    r = simulate_response(building, motion)  # full outputs: disp is set
    if r.status[0] != 0 or not np.all(np.isfinite(cast(np.ndarray, r.disp)[0])):
        return None, None
    return corrcoef(cast(np.ndarray, r.disp)[0], true_disp), r.peak_drift[0]


def run_case(case: Case, names: list[str], settings: dict, unseen: GroundMotion, *, failure_r: float = 0.5,
             base_dir=None, cache_dir: str = "", shared_cache: bool = False) -> list[Outcome]:
    """Every identifier of ``names`` on ``case``; exceptions are recorded as failures."""
    meas = simulate_measurement(case.building, case.motion, rate_hz=None, noise_rms=case.noise, seed=case.seed)
    truth_unseen = simulate_response(case.building, unseen)
    out, times = [], {}
    for name in names:
        base: dict[str, Any] = {"case": case.name, "identifier": name, "structure": case.structure,
                                "record": case.motion.name, "noise": case.noise, "seed": case.seed}
        est = make_identifier(name, settings.get(name), base_dir=base_dir, cache_dir=cache_dir)
        t0, c0 = time.perf_counter(), _cpu()
        try:
            est.fit(meas)
            err = None
        except Exception as e:  # noqa: BLE001 - an identifier that raises is a result of the study
            err = f"{type(e).__name__}: {one_line(e)}"
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
        times[name] = (wall, cpu)
        before = times.get("hlasvm", (0.0, 0.0)) if shared_cache and name == "hlasvm_replay" else (0.0, 0.0)
        spent: dict[str, Any] = {"wall_s": wall + before[0], "wall_own_s": wall, "cpu_s": cpu + before[1],
                                 "cpu_own_s": cpu}
        if err is not None:
            out.append(Outcome(**base, failed=True, reason=err, **spent))
            _progress.info(f"[compare] {case.name}: {name} failed ({err}) in {wall:.1f} s")
            continue
        out.append(_assess(est, case, meas, unseen, truth_unseen, base, spent, failure_r))
        o = out[-1]
        _progress.info(f"[compare] {case.name}: {name} in {wall:.1f} s, mean |error| {100 * o.mean_error:.2f} %, "
                       f"max {100 * o.max_error:.2f} %" + (f" FAILED: {o.reason}" if o.failed else ""))
    return out


def _assess(est, case, meas, unseen, truth_unseen, base, spent, failure_r) -> Outcome:
    b, t = est.clone_.building, case.building
    errors = {k: (np.asarray(getattr(b, k)) / np.asarray(getattr(t, k)) - 1.0).tolist() for k in PARAMETERS}
    flat = np.abs(np.concatenate([np.asarray(v) for v in errors.values()]))
    reason = ""
    r_id = r_un = drift_err = None
    if not np.all(np.isfinite(flat)):
        reason = "non-finite parameters"
    else:
        r_id, _ = _replay_r(b, case.motion, meas.truth.disp)
        r_un, peak = _replay_r(b, unseen, truth_unseen.disp[0])
        if r_id is None or r_un is None:
            reason = "the clone's replay diverges"
        else:
            drift_err = (peak / truth_unseen.peak_drift[0] - 1.0).tolist()
            if np.min(r_id) < failure_r:
                reason = f"replay R {np.min(r_id):.2f} < {failure_r} on the identification record"
    return Outcome(**base, failed=bool(reason), reason=reason, **spent,
                   errors=errors, mean_error=float(np.mean(flat)), max_error=float(np.max(flat)),
                   r_ident=None if r_id is None else np.asarray(r_id).tolist(),
                   r_unseen=None if r_un is None else np.asarray(r_un).tolist(), drift_error_unseen=drift_err,
                   clone=est.clone_.to_dict())


# ---------------------------------------------------------------------- summary
def structure_kind(structure: str) -> str:
    """``"table1"`` or ``"random"`` (random structures are numbered)."""
    return "random" if structure.startswith("random") else structure


def summarise(outcomes: list[Outcome]) -> list[dict]:
    """Per noise level, structure kind (Table 1 / random) and identifier: counts, failures and
    mean / worst of every metric over the cases that did not fail (fractions, not percent)."""
    rows = []
    order = list(IDENTIFIERS)
    keys = sorted({(o.noise, structure_kind(o.structure), o.identifier) for o in outcomes},
                  key=lambda k: (k[0], k[1] != "table1", k[1], order.index(k[2]) if k[2] in order else len(order)))
    for noise, kind, name in keys:
        sel = [o for o in outcomes if o.identifier == name and o.noise == noise and structure_kind(o.structure) == kind]
        ok = [o for o in sel if not o.failed]
        row = {"identifier": name, "noise": noise, "structure": kind, "cases": len(sel), "failures": len(sel) - len(ok),
               "reasons": sorted({o.reason for o in sel if o.failed}),
               "wall_mean_s": float(np.mean([o.wall_s for o in sel])),
               "wall_max_s": float(np.max([o.wall_s for o in sel])),
               "cpu_mean_s": float(np.mean([o.cpu_s for o in sel]))}
        if ok:  # the metrics of an outcome that did not fail are set
            per = {k: np.abs(np.concatenate([cast(dict, o.errors)[k] for o in ok])) for k in PARAMETERS}
            row.update({"mean_error": float(np.mean([o.mean_error for o in ok])),
                        "worst_error": float(np.max([o.max_error for o in ok])),
                        "param_mean_error": {k: float(np.mean(v)) for k, v in per.items()},
                        "param_worst_error": {k: float(np.max(v)) for k, v in per.items()},
                        "r_ident_mean": float(np.mean([np.mean(cast(list, o.r_ident)) for o in ok])),
                        "r_ident_min": float(np.min([np.min(cast(list, o.r_ident)) for o in ok])),
                        "r_unseen_mean": float(np.mean([np.mean(cast(list, o.r_unseen)) for o in ok])),
                        "r_unseen_min": float(np.min([np.min(cast(list, o.r_unseen)) for o in ok])),
                        "drift_error_unseen_mean": float(np.mean([np.mean(np.abs(cast(list, o.drift_error_unseen)))
                                                                  for o in ok])),
                        "drift_error_unseen_worst": float(np.max([np.max(np.abs(cast(list, o.drift_error_unseen)))
                                                                   for o in ok]))})
        rows.append(row)
    return rows
