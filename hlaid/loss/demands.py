"""Engineering demands of a clone in pelicun's format: PID, PFA and RID per realization.

:func:`clone_demands` runs the clone (or an ensemble of clones drawn from its identification
uncertainty, :func:`hlaid.uncertainty.clone_ensemble`) under records, as recorded or scaled to
one intensity (an IDA stripe), and returns a :class:`Demands`: one realization per
member x record, with

* ``PID`` per story: peak inter-story drift ratio;
* ``PFA`` per floor, floor 0 the ground (pelicun's convention: location 0 is the ground, ``k`` the
  k-th floor above it; components on story ``k`` take the slab below them through pelicun's
  ``DemandOffset``): peak absolute acceleration;
* ``RID`` per story: the residual drift ratio of the replay itself. After the record the run goes
  on in free vibration (a zero-padded tail) until the elastic oscillation about the permanent
  offset has decayed to 1 % (``ln(100) / (2 pi zeta)`` periods T1 of the slowest member, with
  ``zeta`` its damping ratio, at least 5 s), then one more period T1 is integrated and the RID
  is the mean drift over it; the half range of the drift over that period (the oscillation
  left) is kept as ``rid_settling`` [drift ratio];
* ``SA`` (Sa(T1) at the nominal clone's T1, or PGA with ``im: pga``): the intensity of each
  realization, the demand pelicun's collapse fragility is evaluated at.

A realization that reached the drift limit or diverged is *collapsed* (its PID is the drift at
which the run stopped, above the limit, or inf): pelicun's ``CollapseLimits`` removes it from the
non-collapse demand sample, and collapse is counted from the collapse fragility instead, as FEMA
P-58 separates collapse from the non-collapse realizations. Units inside: drift ratios,
accelerations in mm/s^2, IM in g; :meth:`Demands.write_csv` writes g.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _progress
from ..clone import Clone
from ..errors import InputError
from ..model.state import settle_time
from ..units import G_MM_S2

SETTLE_DECAY = 100.0
"""The free-vibration tail lasts until an elastic oscillation has decayed by this factor."""

MIN_TAIL_S = 5.0
"""Shortest free-vibration tail [s]."""


@dataclass(frozen=True, eq=False)
class Demands:
    """Demands of realizations (member x record), in hlaid's units.

    Attributes
    ----------
    pid : (R, story) peak inter-story drift ratio
    pfa : (R, story + 1) peak absolute floor acceleration [mm/s^2], column 0 the ground
    rid : (R, story) residual inter-story drift ratio (absolute value, settled; see module doc)
    rid_settling : (R, story) half range of the drift ratio over the last period (oscillation left)
    im : (R,) intensity of each realization [g]
    collapsed : (R,) the run reached the drift limit or diverged
    member, record : (R,) ensemble member (-1: the identified clone) and record index
    record_names : (record,) names
    im_name, im_label, period : the intensity measure and the period of Sa [s]
    level : the IDA stripe's IM [g], or None for records as recorded
    drift_limit : the collapse drift ratio of the runs
    notes : what was decided on the way
    flags : what a reader of the demands must know (extrapolation beyond the drifts observed, a
        clone that collapses under its own events)
    survival : the ensemble conditioned on the clone's events (:meth:`hlaid.events.evidence.Survival.to_dict`)
    """

    pid: np.ndarray
    pfa: np.ndarray
    rid: np.ndarray
    rid_settling: np.ndarray
    im: np.ndarray
    collapsed: np.ndarray
    member: np.ndarray
    record: np.ndarray
    record_names: tuple
    im_name: str
    im_label: str
    period: float
    level: float | None
    drift_limit: float
    notes: tuple = field(default_factory=tuple)
    flags: tuple = field(default_factory=tuple)
    survival: dict = field(default_factory=dict)

    @property
    def n_realizations(self) -> int:
        return int(self.pid.shape[0])

    @property
    def n_stories(self) -> int:
        return int(self.pid.shape[1])

    def sa_name(self) -> str:
        """pelicun's demand type of the intensity: ``SA_0.413`` (Sa at T1 = 0.413 s) or ``PGA``."""
        return "PGA" if self.im_name == "pga" else f"SA_{self.period:.3g}"

    def table(self) -> tuple[list[str], list[str], np.ndarray]:
        """``(columns, units, values (R, column))`` of pelicun's demand file: ``1-PFA-0-1`` ...
        (event 1, type, location, direction 1), PFA and SA in g, PID and RID in rad."""
        n = self.n_stories
        cols = ([f"1-PFA-{k}-1" for k in range(n + 1)] + [f"1-PID-{k + 1}-1" for k in range(n)]
                + [f"1-RID-{k + 1}-1" for k in range(n)])
        units = ["g"] * (n + 1) + ["rad"] * (2 * n)
        vals = [self.pfa / G_MM_S2, self.pid, self.rid]
        if self.im_name != "pga":  # PGA is PFA-0 already
            cols.append(f"1-{self.sa_name()}-0-1")
            units.append("g")
            vals.append(self.im[:, None])
        return cols, units, np.concatenate(vals, axis=1)

    def csv_text(self) -> str:
        """pelicun's demand CSV: a header row, the ``Units`` row, one row per realization."""
        cols, units, vals = self.table()
        lines = ["," + ",".join(cols), "Units," + ",".join(units)]
        lines += [f"{i}," + ",".join(_num(v) for v in row) for i, row in enumerate(vals)]
        return "\n".join(lines) + "\n"

    def write_csv(self, path: str | os.PathLike, *, force: bool = True) -> Path:
        """Write :meth:`csv_text` atomically to ``path``."""
        from .._fileio import atomic_write

        text = self.csv_text()
        return atomic_write(path, lambda tmp: tmp.write_text(text), force=force)

    def summary(self) -> dict:
        """Medians over the non-collapsed realizations (JSON-able), and the counts."""
        ok = ~self.collapsed

        def med(a):
            return np.median(a[ok], axis=0).tolist() if ok.any() else None
        return {"n_realizations": self.n_realizations, "n_collapsed": int(self.collapsed.sum()),
                "level_g": self.level, "im": self.im_name, "period_s": self.period,
                "pid_median": med(self.pid), "pfa_median_g": None if not ok.any() else
                (np.median(self.pfa[ok], axis=0) / G_MM_S2).tolist(),
                "rid_median": med(self.rid), "rid_settling_max": float(np.max(self.rid_settling[ok]))
                if ok.any() else None, "notes": list(self.notes), "flags": list(self.flags),
                "survival": dict(self.survival)}


def _num(v: float) -> str:
    if np.isnan(v):
        return "nan"
    if np.isinf(v):
        return "inf"
    return f"{v:.8g}"


def _members(clone: Clone, n_ensemble: int, seed: int, cfg, motions=()) -> tuple[list, list[str], Any]:
    """The buildings to run (prepared as IDA prepares them: the nominal clone, then the members
    that survive the clone's events, :func:`hlaid.events.evidence.survivors`), notes and the survival."""
    from ..events.evidence import survivors
    from ..ida.assessment import member_preparer
    from ..ida.prepare import prepare_building

    nominal, notes = prepare_building(clone, pdelta=cfg.pdelta, heights=cfg.heights_mm,
                                      gravity_load=cfg.gravity_load_n(), collapse=cfg.collapse)
    cfg = cfg.replace(collapse=nominal.collapse.to_dict() if nominal.collapse is not None else "none")
    prep = member_preparer(cfg)
    surv = survivors(clone, n_ensemble, seed=seed, prepare=prep, motions=motions, drift_limit=cfg.drift_limit,
                     max_step=cfg.max_step)
    notes += list(surv.notes)
    if n_ensemble == 0:
        return [nominal], notes + ["the identified clone alone (no ensemble): no identification uncertainty"], surv
    out = [prep(clone.member(b)) for b in surv.members]
    return [nominal] + out, notes + [f"{len(out)} clones drawn from the identification uncertainty (seed {seed})"], surv


def _checked(clone, level, n_ensemble, ida_config) -> tuple[Clone, Any]:
    """The clone (read from its file) and the IDA config (default ``IDAConfig()``) of
    :func:`clone_demands`, its arguments checked."""
    from ..ida.config import IDAConfig

    cfg = IDAConfig() if ida_config is None else ida_config
    if not isinstance(cfg, IDAConfig):
        raise InputError(f"ida_config must be an hlaid.ida.IDAConfig, got {type(cfg).__name__}")
    if isinstance(clone, (str, os.PathLike)):
        clone = Clone.load(clone)
    if not isinstance(clone, Clone):
        raise InputError(f"expected an hlaid Clone or a clone file, got {type(clone).__name__}")
    if isinstance(n_ensemble, bool) or not isinstance(n_ensemble, (int, np.integer)) or n_ensemble < 0:
        raise InputError(f"n_ensemble = {n_ensemble!r}; expected a whole number >= 0 (0: the identified clone)")
    if level is not None and not (isinstance(level, (int, float)) and math.isfinite(level) and level > 0):
        raise InputError(f"level = {level!r}; expected a positive intensity [g]")
    return clone, cfg


def _replays(buildings, motions, scale: np.ndarray, cfg, tail: float, window: float, h: np.ndarray):
    """Every building under every record scaled by ``scale``, then a free vibration of ``tail``
    seconds: ``(building, record, story)`` peak drift ratios, ``(building, record, floor + 1)``
    peak floor accelerations (floor 0 the ground) [mm/s^2], residual drift ratios (their mean over
    ``window``; NaN where the run stopped) and how far they were from settled, and the simulator
    status ``(building, record)``."""
    from ..ida.analysis import upsampled
    from ..simulate import simulate_response

    n, nb, nm = buildings[0].n_stories, len(buildings), len(motions)
    pid = np.empty((nb, nm, n))
    pfa = np.empty((nb, nm, n + 1))
    rid = np.full((nb, nm, n), np.nan)
    settle = np.full((nb, nm, n), np.nan)
    status = np.empty((nb, nm), dtype=np.int64)
    sub = np.maximum(1, np.ceil(np.array([m.dt for m in motions]) / cfg.max_step - 1e-9)).astype(np.int64)
    for s in _progress.progress(np.unique(sub), desc=f"demands of {nb} clone(s) x {nm} record(s)", unit="batches"):
        idx = np.flatnonzero(sub == s)
        mot = [upsampled(motions[j], int(s)) for j in idx]
        r = simulate_response(buildings, mot, scale[idx][:, None], substeps=1, outputs="peaks", free_vibration=tail,
                              stop_drift=cfg.drift_limit * h)
        shape = (nb, idx.size)
        pid[:, idx] = (r.peak_drift.reshape(*shape, n) / h[:, None, :])
        pfa[:, idx, 1:] = r.peak_acc.reshape(*shape, n)
        pfa[:, idx, 0] = np.array([m.pga for m in motions])[idx][None, :] * scale[idx][None, :]
        status[:, idx] = r.status.reshape(shape)
        ok = r.status == 0
        if ok.any():
            d = _settle(buildings, mot, r, ok, window)
            ri = np.flatnonzero(ok)
            bi, mi = np.unravel_index(ri, shape)
            rid[bi, idx[mi]] = np.abs(d[0]) / h[bi]
            settle[bi, idx[mi]] = d[1] / h[bi]
    return pid, pfa, rid, settle, status


def residual_window(buildings) -> tuple[float, float]:
    """``(tail [s], window [s])``: the free-vibration tail after which an elastic oscillation has
    decayed by :data:`SETTLE_DECAY` in every building (:func:`~hlaid.model.state.settle_time`,
    at least :data:`MIN_TAIL_S`), and the averaging window, the longest first period."""
    tail = max(settle_time(b, math.log(SETTLE_DECAY), (MIN_TAIL_S, math.inf)) for b in buildings)
    return tail, max(float(b.periods()[0]) for b in buildings)


def clone_demands(clone: Clone | str | os.PathLike, records, *, level: float | None = None, n_ensemble: int = 0,
                  seed: int = 0, ida_config=None, event_motions=()) -> Demands:
    """Demands of a clone (and its ensemble) under records, as recorded or at one IM level.

    Parameters
    ----------
    clone : a :class:`~hlaid.clone.Clone` or a clone file
    records : what :func:`hlaid.ida.run_ida` takes (files, a folder, ``builtin-suite``, GroundMotions);
        the building's own ground motion for the demands of the event it recorded
    level : None: every record as recorded (scale 1); a number: every record scaled to this IM [g]
        (an IDA stripe)
    n_ensemble : clones drawn from the identification uncertainty (0: the identified clone only);
        each realization is one member under one record, the identified clone excluded
    seed : seed of the ensemble
    ida_config : :class:`hlaid.ida.IDAConfig` (its ``im``, ``period``, ``drift_limit``, ``max_step``,
        ``pdelta``, ``heights_mm``, ``gravity_kN``, ``collapse`` and ``units`` are used); None: defaults
    event_motions : ground motions of the clone's events at hand (the records themselves when
        ``level`` is None); the ensemble is conditioned on surviving them
        (:func:`hlaid.events.evidence.survivors`), the others read from the events' files

    Returns
    -------
    Demands
    """
    from ..ida.measures import record_intensities
    from ..io.records import as_motions

    clone, cfg = _checked(clone, level, n_ensemble, ida_config)
    motions = as_motions(records, units=cfg.units)
    buildings, notes, surv = _members(clone, int(n_ensemble), seed, cfg,
                                      [*event_motions, *(motions if level is None else ())])
    nominal = buildings[0]
    if n_ensemble:
        buildings = buildings[1:]
    measure, period, im0 = record_intensities(motions, cfg.im, nominal, cfg.period)
    scale = np.ones(len(motions)) if level is None else float(level) / im0
    tail, window = residual_window(buildings)
    notes.append(f"residual drift: free vibration for {tail:.1f} s after each record, then the mean drift over "
                 f"{window:.3g} s (one period T1)")
    h = np.array([np.asarray(b.height, dtype=np.float64) for b in buildings])
    n, nb, nm = nominal.n_stories, len(buildings), len(motions)
    pid, pfa, rid, settle, status = _replays(buildings, motions, scale, cfg, tail, window, h)
    collapsed = (status != 0) | (np.max(pid, axis=-1) > cfg.drift_limit)
    pid = np.where((status == 2)[..., None], np.inf, pid)
    if collapsed.any():
        notes.append(f"{int(collapsed.sum())} of {collapsed.size} realization(s) reached the {cfg.drift_limit:.0%} "
                     "drift limit or diverged (collapsed)")
    flags = list(extrapolation_flags(clone, pid[~collapsed], np.asarray(nominal.height, dtype=float)))
    if surv.nominal_survives is False:
        flags.append(f"the clone collapses under {surv.nominal_collapsed_in}, an event it was identified from")
    members = np.repeat(np.arange(nb) if n_ensemble else np.full(nb, -1), nm)
    return Demands(pid=pid.reshape(-1, n), pfa=pfa.reshape(-1, n + 1), rid=rid.reshape(-1, n),
                   rid_settling=settle.reshape(-1, n), im=np.tile(im0 * scale, nb), collapsed=collapsed.ravel(),
                   member=members, record=np.tile(np.arange(nm), nb), record_names=tuple(m.name for m in motions),
                   im_name=measure.name, im_label=measure.label, period=float(period),
                   level=None if level is None else float(level), drift_limit=cfg.drift_limit, notes=tuple(notes),
                   flags=tuple(flags), survival=surv.to_dict())


def extrapolation_flags(clone: Clone, pid: np.ndarray, height: np.ndarray) -> list[str]:
    """A line where the median peak drift ratio of the realisations ``pid`` ``(realisation,
    story)`` lies beyond :data:`~hlaid.ida.basis.EXTRAPOLATION_MARGIN` times the largest the building
    survived (:meth:`hlaid.clone.Clone.survived_drift`): demands the clone extrapolates to."""
    from ..ida.basis import decision_basis

    if pid.size == 0:
        return []
    b = decision_basis(clone, heights=height, demand_ratio=median_peak_ratio(pid))
    return [f for f in b.flags() if f.startswith("demands extrapolated")]


def median_peak_ratio(pid: np.ndarray) -> float | None:
    """The demand a decision rests on: the median over realisations of the largest story's peak
    drift ratio (``pid`` ``(realisation, story)``, the collapsed ones left out); None: none."""
    return None if pid.size == 0 else float(np.median(np.max(pid, axis=-1)))


def _settle(buildings, motions, r, ok: np.ndarray, window: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean drift and half range over ``window`` s of free vibration from the end states of the
    runs ``ok`` (batch order building x motion); both ``(run, story)`` [mm]."""
    from ..motions import GroundMotion
    from ..simulate import simulate_response

    nm = len(motions)
    ri = np.flatnonzero(ok)
    bi, mi = ri // nm, ri % nm
    zero = {}
    for j in np.unique(mi):
        dt = motions[j].dt
        zero[j] = GroundMotion(dt=dt, acc=np.zeros(max(8, int(math.ceil(window / dt)) + 1)), name="free vibration")
    res = simulate_response([buildings[b] for b in bi], [zero[j] for j in mi], 1.0, substeps=1, pairing="zip",
                   outputs="full", y0=r.final_state[ri])
    drift = res.drift
    assert drift is not None  # outputs="full"
    mean = np.nanmean(drift, axis=1)
    half = 0.5 * (np.nanmax(drift, axis=1) - np.nanmin(drift, axis=1))
    return mean, half


_COLUMN = re.compile(r"(\d+)-(PID|RID|PFA|PGA|SA_\d*\.?\d+)-(\d+)-(\d+)")
_DRIFT_UNITS = ("rad", "unitless")
_ACC_UNITS = ("g", "mps2", "inps2", "inchps2", "ftps2")


@dataclass(frozen=True)
class DemandFile:
    """A checked pelicun demand CSV: its text, the number of stories (PID locations) and its
    intensity column's demand type (``SA_0.413``, ``PGA`` or None)."""

    text: str
    n_stories: int
    im_type: str | None
    n_realizations: int


def read_demand_csv(path: str | os.PathLike) -> DemandFile:
    """Read and check a demand file in pelicun's format (what :meth:`Demands.write_csv` writes).

    The header names ``EVENT-TYPE-LOCATION-DIRECTION`` columns of PID, RID, PFA, PGA or SA_T; the
    second row is ``Units`` with rad (or unitless) for drifts and g, mps2, inps2 or ftps2 for
    accelerations; every other row is one realization of numbers (inf allowed: a diverged run).
    Errors name the file, line and column and exit with status 2 on the command line.
    """
    from .._inputs import read_text
    from ..errors import quotable

    src = str(path)
    text = read_text(path)
    rows = list(csv.reader(io.StringIO(text)))
    if len(rows) < 3:
        raise InputError("expected a header, a Units row and at least one realization (pelicun's demand file)",
                         source=src)
    cols = [c.strip() for c in rows[0][1:]]
    kinds = []
    for j, c in enumerate(cols):
        m = _COLUMN.fullmatch(c)
        if not m:
            name = f"column {j + 2} ({c!r})" if quotable(c) else f"column {j + 2}"
            raise InputError(f"line 1: {name} is not a demand name; expected EVENT-TYPE-LOCATION-DIRECTION such as "
                             "1-PID-1-1 (types PID, RID, PFA, PGA, SA_T)", source=src)
        kinds.append(m.group(2))
    if rows[1][:1] != ["Units"]:
        raise InputError("line 2: expected the Units row (its first cell 'Units'), as pelicun's demand files have",
                         source=src)
    units = [u.strip() for u in rows[1][1:]]
    if len(units) != len(cols):
        raise InputError(f"line 2: the Units row has {len(units)} units for {len(cols)} demand columns", source=src)
    for c, k, u in zip(cols, kinds, units):
        ok = _DRIFT_UNITS if k in ("PID", "RID") else _ACC_UNITS
        if u not in ok:
            what = f"unit {u!r}" if quotable(u) else "the unit"
            kind = "a drift ratio" if k in ("PID", "RID") else "an acceleration"
            raise InputError(f"line 2: column {c}: {what} is not {kind} unit; expected {', '.join(ok)}", source=src)
    for ln, row in enumerate(rows[2:], start=3):
        if len(row) != len(cols) + 1:
            raise InputError(f"line {ln}: {len(row) - 1} values for {len(cols)} demand columns", source=src)
        for j, v in enumerate(row[1:]):
            try:
                float(v)
            except ValueError:
                raise InputError(f"line {ln}: column {cols[j]}: not a number", source=src) from None
    pid = sorted({int(_COLUMN.fullmatch(c).group(3)) for c, k in zip(cols, kinds) if k == "PID"})  # type: ignore[union-attr]
    if not pid:
        raise InputError("no PID (peak inter-story drift) columns; expected 1-PID-1-1 ...", source=src)
    im = next((k for k in kinds if k.startswith("SA_") or k == "PGA"), None)
    return DemandFile(text=text, n_stories=max(pid), im_type=im, n_realizations=len(rows) - 2)


__all__ = ["DemandFile", "read_demand_csv", "Demands", "clone_demands", "residual_window", "SETTLE_DECAY", "MIN_TAIL_S"]
