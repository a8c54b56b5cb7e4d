"""Incremental dynamic analysis of a clone over a record set (Vamvatsikos & Cornell 2002).

Every record is scaled to IM levels and the clone is run with the batch simulator
(:func:`hlaid.simulate.simulate_response`, ``outputs="peaks"``), many records x levels per call. The
engineering demand parameter (EDP) is the peak inter-story drift ratio (largest over the
stories). A point is a *collapse* when

* a story's drift ratio exceeds ``drift_limit`` (the simulator stops the run there), or
* the response diverges (non-finite state), or
* the IDA curve's secant slope ``dIM/dEDP`` between consecutive points drops below
  ``slope_ratio`` x the elastic slope (the point above the flat segment is on the flatline).

Each record is integrated with RK4 steps of at most ``max_step`` (its samples refined by exact
linear interpolation, one step per refined sample), so peaks and the drift stop are checked at
every step. A run that diverges, or that the drift stop catches more than 1.5x past the limit
(a jump within one sample), is re-run with 4x and then 16x more steps first, so an integration
blow-up is never taken for a collapse.

Stages (each a few batched simulator calls):

1. *probe*: every record at a tiny intensity (scale 1e-4: linear response) gives its elastic
   slope ``IM / EDP``;
2. *grid*: every record at every level (ascending, in chunks; a record that has collapsed
   is not run at higher levels);
3. *hunt*: records that did not collapse on the grid are stepped up (IM x ``hunt_factor``)
   until they do (at most ``max_hunt`` steps; otherwise they are right-censored);
4. *fill*: the bracket [last survived, first collapsed] of every record is bisected until its
   width is below ``tolerance`` x IM. The collapse IM is the bracket's midpoint.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import _progress
from ..clone import Clone
from ..errors import InputError
from ..events.start import Start, resolve_start
from ..io.records import as_motions
from ..model import Building
from ..model.state import BuildingState
from ..motions import GroundMotion
from ..simulate import simulate_response
from .config import DEFAULT_EXCEEDANCE, IDAConfig, check_levels
from .measures import record_intensities
from .prepare import prepare_building
from .results import IDAResult

PROBE_SCALE = 1e-4
"""Scale factor of the elastic probe run (linear response for any practical clone)."""

_CONFIRM_FACTOR = 4
"""Divergent runs are repeated with this many times more sub-steps (twice)."""

_JUMP = 1.5
"""A run stopped at the drift limit with a drift above this multiple of the limit jumped there
within one sample: an integration blow-up, re-run with finer steps."""


# ---------------------------------------------------------------------------- runs
class _Runner:
    """Runs (record, IM) points through the batch simulator and accumulates them."""

    def __init__(self, building: Building, motions: list[GroundMotion], im0: np.ndarray, drift_limit: float,
                 max_step: float, state: BuildingState | None = None):
        self.b, self.im0 = building, im0
        collapse = building.collapse is not None
        self.y0 = None if state is None else state.vector(collapse)
        self.y0_probe = None if state is None else state.unloaded().vector(collapse)
        self.h = np.asarray(building.height, dtype=np.float64)
        self.stop = drift_limit * self.h
        self.drift_limit = drift_limit
        dt = np.array([m.dt for m in motions])
        self.substeps = np.maximum(1, np.ceil(dt / max_step - 1e-9)).astype(np.int64)
        # Each record is run as the same piecewise-linear input sampled `substeps` times denser
        # (one RK4 step per sample: the same arithmetic as `substeps` sub-steps), so that peaks
        # and the drift stop are checked at every step, not only at the record's samples.
        self.motions = [upsampled(m, int(f)) for m, f in zip(motions, self.substeps)]
        self.cols: dict[str, list] = {k: [] for k in ("record", "im", "scale", "stage", "status", "substeps",
                                                      "peak", "residual")}
        self.n_runs = 0

    def _sim(self, recs: np.ndarray, scales: np.ndarray, substeps: int, y0: np.ndarray | None):
        """Product runs of ``recs`` x their rows of ``scales`` ``(len(recs), k)``, at ``substeps``
        RK4 steps per sample of the (already refined) records, each from ``y0`` (None: at rest)."""
        r = simulate_response(self.b, [self.motions[i] for i in recs], scales, substeps=int(substeps),
                              outputs="peaks", stop_drift=self.stop, y0=y0)
        self.n_runs += r.batch_size
        return r.peak_drift, r.residual_drift, r.status

    def run(self, recs: np.ndarray, ims: np.ndarray, stage: str) -> None:
        """Run records ``recs`` ``(m,)`` at IM rows ``ims`` ``(m, k)`` [g]. The elastic probe
        starts from the carried state unloaded (:meth:`BuildingState.unloaded`: the elastic slope
        of the building as the last event left it), every other run from the state."""
        recs = np.asarray(recs, dtype=np.int64)
        ims = np.asarray(ims, dtype=np.float64).reshape(recs.size, -1)
        if recs.size == 0:
            return
        k = ims.shape[1]
        scales = ims / self.im0[recs, None]
        n = self.b.n_stories
        peak = np.empty((recs.size, k, n))
        resid = np.empty((recs.size, k, n))
        status = np.empty((recs.size, k), dtype=np.int64)
        sub = np.empty((recs.size, k), dtype=np.int64)
        y0 = self.y0_probe if stage == "probe" else self.y0
        for s in np.unique(self.substeps[recs]):
            sel = np.flatnonzero(self.substeps[recs] == s)
            pk, rs, st = self._sim(recs[sel], scales[sel], 1, y0)
            peak[sel], resid[sel], status[sel] = pk.reshape(sel.size, k, n), rs.reshape(sel.size, k, n), \
                st.reshape(sel.size, k)
            sub[sel] = s
        # divergence, or a jump far past the drift limit within one sample (an integration
        # blow-up caught by the drift stop), is re-run with finer steps before it counts
        for _ in range(2):
            jump = (status == 1) & (np.max(peak / self.stop, axis=-1) > _JUMP)
            bad = np.argwhere((status == 2) | jump)
            if bad.size == 0:
                break
            for i, j in bad:
                f = int(sub[i, j] // self.substeps[recs[i]]) * _CONFIRM_FACTOR
                pk, rs, st = self._sim(recs[i:i + 1], scales[i:i + 1, j:j + 1], f, y0)
                peak[i, j], resid[i, j], status[i, j] = pk[0], rs[0], st[0]
                sub[i, j] = f * self.substeps[recs[i]]
        c = self.cols
        c["record"].append(np.repeat(recs, k))
        c["im"].append(ims.ravel())
        c["scale"].append(scales.ravel())
        c["stage"].append(np.full(recs.size * k, stage, dtype=object))
        c["status"].append(status.ravel())
        c["substeps"].append(sub.ravel())
        c["peak"].append(peak.reshape(-1, n))
        c["residual"].append(resid.reshape(-1, n))

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.concatenate(v) for k, v in self.cols.items()}

    def edp(self, a: dict) -> np.ndarray:
        return np.max(a["peak"] / self.h, axis=1)


def upsampled(gm: GroundMotion, factor: int) -> GroundMotion:
    """The same piecewise-linear record sampled ``factor`` times denser (exact interpolation)."""
    if factor <= 1:
        return gm
    t = np.arange((gm.npts - 1) * factor + 1) * (gm.dt / factor)
    return GroundMotion(dt=gm.dt / factor, acc=np.interp(t, gm.time, gm.acc), name=gm.name, source=gm.source)


def scan_collapse(im: np.ndarray, edp: np.ndarray, failed: np.ndarray, elastic_slope: float,
                  slope_ratio: float) -> tuple[int | None, str]:
    """Find the first collapse along one record's IDA curve.

    Parameters
    ----------
    im, edp, failed : (point,) IM [g], EDP (drift ratio), True where the run collapsed
        (drift limit or divergence); any order
    elastic_slope : IM per unit EDP of the linear response
    slope_ratio : the flatline criterion (0.2: slope below 20 % of the elastic slope)

    Returns
    -------
    (index of the first point on the flatline or None, mode: ``"drift limit or divergence"``,
    ``"slope"`` or ``"none"``)
    """
    order = np.argsort(im, kind="stable")
    prev_im, prev_edp = 0.0, 0.0
    for i in order:
        if failed[i]:
            return int(i), "failed"
        d = edp[i] - prev_edp
        if d > 0 and (im[i] - prev_im) / d < slope_ratio * elastic_slope:
            return int(i), "slope"
        prev_im, prev_edp = im[i], edp[i]
    return None, "none"


def _auto_levels(elastic_slope: np.ndarray, drift_limit: float, n: int, smallest_limit: float | None = None
                 ) -> list[float]:
    """``n`` levels in geometric steps up to the median equal-displacement IM at the drift limit
    (``top``), from half the equal-displacement IM at ``smallest_limit`` (the lowest drift whose
    exceedance is reported; None: ``top / n``), never above ``top / n``: a fragility of a small
    drift rises well below ``top``, and equal steps would put one stripe there. Rounded to 3
    significant digits, more where ``n`` levels need them to stay distinct."""
    top = float(np.median(elastic_slope * drift_limit))
    lo = top / n if smallest_limit is None else min(top / n, 0.5 * top * smallest_limit / drift_limit)
    lv = [top] if n == 1 else list(np.geomspace(lo, top, n))
    digits = 3
    while True:
        out = [float(f"{v:.{digits}g}") for v in lv]
        if len(set(out)) == len(out) or digits >= 15:
            return out
        digits += 1


# ---------------------------------------------------------------------------- the analysis
def run_ida(model: Clone | Building | str | os.PathLike,
            records: str | os.PathLike | GroundMotion | Sequence[str | os.PathLike | GroundMotion],
            config: IDAConfig | None = None, *, event_motions: Sequence[GroundMotion] = ()) -> IDAResult:
    """Incremental dynamic analysis of a clone (or building) over a record set.

    Parameters
    ----------
    model : a :class:`~hlaid.clone.Clone`, a :class:`~hlaid.model.Building` or a clone file
    records : a folder of AT2/text records, ``"builtin-suite"``, files, or GroundMotions
        (see :func:`hlaid.io.read` with ``kind="records"``; unreadable files are skipped with a warning);
        ``config.records`` is not used (see :func:`ida_from_config`)
    config : the settings (:class:`IDAConfig`; None: its defaults). Of its fields, ``im``,
        ``levels`` ((level,) strictly increasing IM levels [g]; None: ``n_levels`` geometric steps up
        to the median equal-displacement estimate of the IM at the drift limit, from half that at
        the smallest of ``exceedance_limits``), ``drift_limit``
        (also where the simulator stops a run), ``slope_ratio``, ``exceedance_limits``, the
        refinement (``refine``, ``hunt_factor``, ``max_hunt``, ``tolerance``, ``max_fill``; see the
        module doc), ``max_step`` (largest RK4 step [s]; peaks and the drift stop are checked at
        every step), ``pdelta``, ``heights_mm``, ``gravity_kN`` and ``collapse`` (see
        :func:`prepare_building`), ``period`` and ``units`` (of text records) are used here; the
        bootstrap settings are for :meth:`IDAResult.save`
    event_motions : ground motions of the clone's events at hand (matched to its events); the
        others are read from the events' files. The clone is replayed through its events with the
        collapse law in force (:func:`hlaid.events.evidence.survivors`): a note says whether it
        survives them, as the building did

    Returns
    -------
    IDAResult
    """
    t0 = time.perf_counter()
    cfg = _checked_config(config)
    drift_limit, max_step, exceedance_limits = cfg.drift_limit, cfg.max_step, list(cfg.exceedance_limits or ())
    if isinstance(model, (str, os.PathLike)):
        model = Clone.load(model)
    building, notes = prepare_building(model, pdelta=cfg.pdelta, heights=cfg.heights_mm,
                                       gravity_load=cfg.gravity_load_n(), collapse=cfg.collapse)
    if isinstance(model, Clone) and model.events:
        notes.extend(survival_notes(model, building, cfg, event_motions))
    for note in notes:  # what the evidence changed or found: said (a detail inside a run's step), not only noted
        if note.startswith(("collapse law ", "survival")):
            _progress.step(note)
    start = start_state(model, building, cfg.start, notes)
    motions = as_motions(records, units=cfg.units)
    measure, T1, im0 = record_intensities(motions, cfg.im, building, cfg.period)
    levels, n_levels, slope_ratio, refine = cfg.levels, cfg.n_levels, cfg.slope_ratio, cfg.refine
    R = len(motions)
    runner = _Runner(building, motions, im0, drift_limit, max_step, start.state)
    log = _progress.debug if _progress.nested() else _progress.info  # inside an ensemble: details
    log(f"IDA of {building.name or 'the clone'}: {R} records, IM {measure.label}"
                   + (f" at T1 = {T1:.3f} s" if measure.needs_period else "")
                   + f", collapse at {drift_limit:.0%} drift, P-Delta {'on' if building.pdelta else 'off'}"
                   + f", collapse model {building.collapse.name if building.collapse else 'none'}"
                   + f", from the {cfg.start} state")

    slope_el, grid = _probe(runner, im0, levels, drift_limit, n_levels, notes, exceedance_limits)
    _grid(runner, grid, drift_limit)
    state = _refine(runner, slope_el, cfg) if refine else _scan_all(runner, slope_el, slope_ratio)
    a = runner.arrays()
    n_cens = _bracket_notes(state, cfg, notes)
    wall = time.perf_counter() - t0
    log(f"IDA done: {runner.n_runs} runs in {wall:.1f} s; {R - n_cens}/{R} records collapsed")
    collapse_im = np.where(state["first"] >= 0, 0.5 * (state["lo"] + state["hi"]), np.nan)
    return IDAResult(
        building=building, im=measure.name, im_label=measure.label, period=T1,
        record_names=tuple(m.name for m in motions), record_sources=tuple(m.source or m.name for m in motions),
        record_im=im0, record_dt=np.array([m.dt for m in motions]), levels=grid,
        drift_limit=drift_limit, slope_ratio=slope_ratio, exceedance_limits=tuple(exceedance_limits),
        elastic_slope=slope_el, point_record=a["record"], point_im=a["im"], point_scale=a["scale"],
        point_stage=a["stage"].astype(str), point_status=a["status"], point_substeps=a["substeps"],
        peak_drift=a["peak"], residual_drift=a["residual"],
        collapse_im=collapse_im, collapse_lo=np.where(state["first"] >= 0, state["lo"], np.nan),
        collapse_hi=np.where(state["first"] >= 0, state["hi"], np.nan), collapse_mode=tuple(state["mode"]),
        censored_im=np.where(state["first"] < 0, state["max_im"], np.nan),
        settings=_settings(cfg), notes=tuple(notes),
        timing={"wall_s": wall, "runs": runner.n_runs})


def _checked_config(config: IDAConfig | None) -> IDAConfig:
    """The settings with the exceedance limits filled in (the defaults below the drift limit)."""
    cfg = IDAConfig() if config is None else config
    if not isinstance(cfg, IDAConfig):
        raise InputError(f"config: expected an IDAConfig, got {type(cfg).__name__}")
    exceedance_limits = cfg.exceedance_limits
    if exceedance_limits is None:
        exceedance_limits = [d for d in DEFAULT_EXCEEDANCE if d < cfg.drift_limit]
    return dataclasses.replace(cfg, levels=None if cfg.levels is None else list(cfg.levels),
                               exceedance_limits=list(exceedance_limits))


def _bracket_notes(state: dict, cfg: IDAConfig, notes: list[str]) -> int:
    """Note the right-censored records and the brackets left wider than the tolerance; the
    number of censored records."""
    n_cens = int((state["first"] < 0).sum())
    if n_cens:
        notes.append(f"{n_cens} record(s) did not collapse up to the highest IM run (right-censored)")
    wide = (state["first"] >= 0) & (state["hi"] - state["lo"] > cfg.tolerance * state["hi"])
    if wide.any():
        notes.append(f"{int(wide.sum())} collapse bracket(s) wider than the tolerance {cfg.tolerance:g} "
                     + ("(refinement off)" if not cfg.refine else f"after {cfg.max_fill} bisections"))
    return n_cens


def _probe(runner: _Runner, im0: np.ndarray, levels, drift_limit: float, n_levels: int,
           notes: list[str], exceedance_limits: Sequence[float] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Stage 1, the elastic probe: every record's elastic slope ``IM / EDP`` ``(record,)``, and
    the levels (the configured ones, else :func:`_auto_levels` from the slopes)."""
    runner.run(np.arange(im0.size), (im0 * PROBE_SCALE)[:, None], "probe")
    a = runner.arrays()
    slope_el = a["im"] / runner.edp(a)
    if levels is None:
        levels = _auto_levels(slope_el, drift_limit, n_levels, min(exceedance_limits, default=None))
        notes.append(f"levels: {n_levels} geometric steps from {levels[0]:g} g (half the equal-displacement estimate "
                     f"of the IM at the smallest reported drift) to {levels[-1]:g} g (at the drift limit)")
    return slope_el, np.array(check_levels(levels))


def _grid(runner: _Runner, levels: np.ndarray, drift_limit: float) -> None:
    """Stage 2, the grid: every record at every level in ascending chunks; a record that has
    collapsed stops climbing."""
    R = runner.im0.size
    ar = np.arange(R)
    chunks = np.array_split(np.arange(levels.size), min(levels.size, 5))
    alive = np.ones(R, dtype=bool)
    with _progress.stage(f"IDA grid of {R} records", levels.size, unit="levels") as bar:
        for ch in chunks:
            recs = np.flatnonzero(alive)
            runner.run(recs, np.broadcast_to(levels[ch], (recs.size, ch.size)), "grid")
            a = runner.arrays()
            failed = (a["status"] != 0) | (runner.edp(a) > drift_limit)
            alive &= ~np.isin(ar, a["record"][failed])
            bar.update(ch.size, note=f"up to {levels[ch[-1]]:.3g} g, {R - int(alive.sum())} collapsed")
            if not alive.any():
                break


def _refine(runner: _Runner, slope_el: np.ndarray, cfg: IDAConfig) -> dict:
    """Stages 3-4: records that have not collapsed are stepped up (hunt), then every collapse
    bracket is bisected (fill); returns the last :func:`_scan_all`."""
    state = _scan_all(runner, slope_el, cfg.slope_ratio)
    with _progress.stage("IDA collapse search", unit="steps") as bar:
        for step in range(cfg.max_hunt):
            need = np.flatnonzero(state["first"] < 0)
            if need.size == 0:
                break
            nxt = state["max_im"][need] * cfg.hunt_factor
            _progress.debug(f"hunt step {step + 1}: {need.size} record(s) not collapsed yet")
            bar.update(1, note=f"stepping up {need.size} record(s) not collapsed yet")
            runner.run(need, nxt[:, None], "hunt")
            state = _scan_all(runner, slope_el, cfg.slope_ratio)
        for step in range(cfg.max_fill):
            lo, hi = state["lo"], state["hi"]
            need = np.flatnonzero((state["first"] >= 0) & (hi - lo > cfg.tolerance * hi))
            if need.size == 0:
                break
            _progress.debug(f"fill step {step + 1}: bisecting {need.size} collapse bracket(s)")
            bar.update(1, note=f"bisecting {need.size} collapse bracket(s)")
            runner.run(need, (0.5 * (lo[need] + hi[need]))[:, None], "fill")
            state = _scan_all(runner, slope_el, cfg.slope_ratio)
        bar.done(f"{int((state['first'] >= 0).sum())}/{state['first'].size} records collapsed")
    return state


def survival_notes(clone: Clone, building: Building, cfg: IDAConfig, motions: Sequence[GroundMotion] = ()) -> list[str]:
    """Whether the prepared ``building`` of ``clone`` survives the clone's events, in words."""
    from ..events.evidence import survivors

    surv = survivors(clone, 0, prepare=lambda _: building, motions=motions, drift_limit=cfg.drift_limit,
                     max_step=cfg.max_step)
    out = list(surv.notes)
    if surv.nominal_survives and surv.nominal_peak is not None:
        h = np.asarray(building.height, dtype=float)  # prepare_building requires the heights
        drifts = ", ".join(f"{100 * d / hi:.2f}" for d, hi in zip(surv.nominal_peak, h))
        law = (f"with its collapse law {building.collapse.name!r}" if building.collapse is not None else
               f"with no collapse law (collapse only beyond the {cfg.drift_limit:.0%} drift limit)")
        out.append(f"survival: the clone survives {', '.join(surv.events)} (events it was identified from) {law}; "
                   f"its largest drift in that replay {drifts} % of the story heights")
    return out


def start_state(model, building: Building, start: str, notes: list[str]) -> Start:
    """Where every IDA run starts (:func:`hlaid.events.start.resolve_start`), and a note saying
    which: at rest, or the state the clone's events left (``"carried"`` needs a clone that carries
    one)."""
    resolved = resolve_start(model if isinstance(model, Clone) else building, start)
    st = resolved.state
    if st is None:
        notes.append(f"start: undamaged, every run from rest ({resolved.reason})")
        return resolved
    eta = st.eta(building)
    h = np.asarray(building.height, dtype=float)  # prepare_building requires the heights
    notes.append(f"start: carried, the state after {', '.join(st.events) or 'the last event'}: residual drift "
                 + ", ".join(f"{100 * d / hi:.2f}" for d, hi in zip(st.drift, h))
                 + " %, eta " + ", ".join(f"{v:.2f}" for v in eta))
    return resolved


def _scan_all(runner: _Runner, slope_el: np.ndarray, slope_ratio: float) -> dict:
    """Per record: first flatline point, bracket [lo, hi], mode, highest IM run."""
    a = runner.arrays()
    edp = runner.edp(a)
    failed = (a["status"] != 0) | (edp > runner.drift_limit)
    R = slope_el.size
    out: dict[str, Any] = {"first": np.full(R, -1), "lo": np.full(R, np.nan), "hi": np.full(R, np.nan),
                           "max_im": np.zeros(R), "mode": ["none"] * R}
    for r in range(R):
        idx = np.flatnonzero(a["record"] == r)
        out["max_im"][r] = a["im"][idx].max()
        i, mode = scan_collapse(a["im"][idx], edp[idx], failed[idx], slope_el[r], slope_ratio)
        if i is None:
            continue
        p = idx[i]
        below = a["im"][idx][a["im"][idx] < a["im"][p]]
        out["first"][r] = p
        out["hi"][r] = a["im"][p]
        out["lo"][r] = below.max() if below.size else 0.0
        if mode == "failed":
            mode = {1: "drift limit", 2: "diverged"}.get(int(a["status"][p]), "drift limit")
        out["mode"][r] = mode
    return out




def _settings(cfg: IDAConfig) -> dict:
    from ..config import config_to_dict
    d = config_to_dict(cfg)
    for k in ("records", "units", "heights_mm", "gravity_kN", "bootstrap", "ci", "seed"):
        d.pop(k, None)
    return d


def ida_from_config(model, cfg: IDAConfig, records=None, *, base_dir: str | Path | None = None,
                    event_motions: Sequence[GroundMotion] = ()) -> IDAResult:
    """Run :func:`run_ida` on the config's own records (relative paths from ``base_dir``) unless
    ``records`` are given."""
    recs = records if records is not None else cfg.record_specs(base_dir)
    if recs is None:
        raise InputError("no records: give them in the config ('records:') or as the records argument "
                         "(records=[...])")
    return run_ida(model, recs, cfg, event_motions=event_motions)

