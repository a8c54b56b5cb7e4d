"""The whole pipeline from records to decision: ``hlaid run CONFIG.yaml`` and ``hlaid demo``.

measurement (file or simulation) -> HLA -> identification (clone) -> replay check -> IDA and
collapse fragility -> (with an ``assess`` block) IDA over an ensemble of clones drawn from the
identification uncertainty, fragility band and re-occupancy indicator at the measured record ->
(with a ``loss`` block) FEMA P-58 losses through pelicun at the measured record and the IDA stripes ->
figures, machine-readable files and a self-contained ``report.html``.
Everything is written into a temporary folder that replaces the output folder only once
complete.
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import _progress
from .._fileio import atomic_directory, check_output_folder, write_json
from .._inputs import read_json
from .._version import __version__
from ..clone import jsonable
from ..config import config_to_dict
from ..errors import InputError
from ..events.identify import identify_clone
from ..identify.config import RefineConfig
from ..identify.replaycheck import corrcoef
from ..io import read
from ..measurement import Measurement, check_band, check_moving
from ..model import Building
from ..plots import plot_time_histories, save_figure
from ..synthetic import measurement_from_config
from .config import MeasurementSource, RunConfig, input_paths, load_run_config
from .decision import run_basis, run_flags
from .summary import (
    Assessment,
    ConfigRecord,
    EventRisk,
    IDASummary,
    LossSummary,
    ParameterRow,
    Replay,
    RunSummary,
    Survival,
)

PARAMS = ("alpha", "p", "delta_eta", "dy", "k0")


def load_measurement(src: MeasurementSource, base_dir: Path | None) -> Measurement:
    """The measurement of the event the decisions are at (the last of ``src.files``)."""
    return load_measurements(src, base_dir)[-1]


def load_measurements(src: MeasurementSource, base_dir: Path | None) -> list[Measurement]:
    """The measurements of a run, oldest first (one, or the events of ``src.files``)."""
    if src.simulate is not None:
        return [_changed(src, measurement_from_config(src.simulate, base_dir=base_dir))]
    out = []
    for f in src.files:
        path = Path(f)
        if base_dir is not None and not path.is_absolute():
            path = Path(base_dir) / path
        meas = read(path, "measurement", format=src.format, **src.options)
        check_moving(meas)
        out.append(_changed(src, meas))
    return out


def _changed(src: MeasurementSource, meas: Measurement) -> Measurement:
    """``meas`` with the masses and story heights ``src`` gives."""
    import dataclasses

    changes: dict[str, Any] = {}
    if src.mass_t is not None:
        changes["mass"] = np.asarray(src.mass_t, float)
    if src.height_mm is not None:
        changes["height"] = np.asarray(src.height_mm, float)
    return dataclasses.replace(meas, **changes) if changes else meas


def parameter_table(identified: Building, truth: Building | None, uncertainty=None) -> list[ParameterRow]:
    """The paper's Table 4 layout: one row per parameter and story (error when the truth is known;
    with ``uncertainty`` the 90 % interval, ``(None, None)`` for a parameter without one)."""
    rows = []
    iv = uncertainty.interval(0.9) if uncertainty is not None else None
    for name in PARAMS:
        for i in range(identified.n_stories):
            v = float(getattr(identified, name)[i])
            t = None if truth is None else float(getattr(truth, name)[i])
            rows.append(ParameterRow(parameter=name, story=i + 1, identified=v, true=t,
                                     error=None if t is None else abs(v / t - 1.0),
                                     interval=None if iv is None else tuple(iv.get(f"{name}[{i + 1}]", (None, None)))))
    return rows


def _csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


class _Steps:
    """The numbered steps of a run (``[3/7] figures``), counted from the config before the work;
    each a :class:`~hlaid._progress.Stage` (a bar on a terminal, one closing line), so the work
    inside it says its own steps as details: one line per step."""

    def __init__(self, cfg: RunConfig) -> None:
        after = cfg.ida is not None and cfg.ida.start == "undamaged"
        self.total = 3 + (cfg.ida is not None) + after + (cfg.assess is not None) + (cfg.loss is not None)
        self.done = 0
        self.current: _progress.Stage | None = None

    def __call__(self, text: str) -> None:
        self.close()
        self.done += 1
        self.current = _progress.stage(f"[{self.done}/{self.total}] {text}")
        self.current.__enter__()

    def close(self, exc: BaseException | None = None) -> None:
        """End the step in progress (``exc``: left by that exception)."""
        st, self.current = self.current, None
        if st is not None:
            st.__exit__(type(exc) if exc is not None else None, exc, None)


def run_pipeline(cfg: RunConfig, out: str | Path, *, base_dir: str | Path | None = None, force: bool = False,
                 cache_dir: str | None = None, inputs: Sequence[str | Path | None] = (),
                 plots: bool = True) -> RunSummary:
    """Run the pipeline and write everything under ``out``; returns the run summary. An existing
    ``out`` is replaced only with ``force``, when hlaid wrote it and it holds none of ``inputs``
    (the run's own input files are added to them). ``plots`` False: no figures (the report holds
    the tables alone)."""
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    if cfg.loss is not None:  # fail before the pipeline when pelicun is missing
        from ..loss.fema_p58 import require_pelicun
        require_pelicun()
    inputs = [*inputs, *input_paths(cfg, base_dir), cache_dir]
    step = _Steps(cfg)
    try:
        summary = _pipeline(cfg, out, base_dir, force, cache_dir, inputs, plots, step, t_all, timings)
    except BaseException as exc:
        step.close(exc)
        raise
    _progress.info(f"wrote {out}/ (report.html, clone.json, hla/, ida/, figures/, tensorboard/) in "
                   f"{timings['total']:.0f} s")
    return summary


def _pipeline(cfg: RunConfig, out, base_dir, force: bool, cache_dir, inputs, plots: bool, step: _Steps, t_all: float,
              timings: dict) -> RunSummary:
    """The work of :func:`run_pipeline` (its steps said by ``step``, its times into ``timings``)."""
    from .report import build_report
    with atomic_directory(out, force=force, inputs=inputs) as tmp:
        tmp = Path(tmp)
        (tmp / "figures").mkdir()
        t = time.perf_counter()
        step("measurement")
        series = load_measurements(cfg.measurement, Path(base_dir) if base_dir else None)
        meas = series[-1]  # the event the decisions are at
        for m in series:
            check_band(m, cfg.identify.hla.preprocess.band_hz, "identify.hla.preprocess.band_hz")
            check_band(m, cfg.identify.refine.band_hz, "identify.refine.band_hz", default=RefineConfig().band_hz)
        check_output_folder(out, force=force, inputs=inputs)  # and the files the measurement named: before the work
        meas.save(tmp / "measurement.npz")
        timings["measurement"] = time.perf_counter() - t
        t = time.perf_counter()
        step("hysteresis loop analysis and identification")
        res = identify_clone(series if len(series) > 1 else meas, cfg.identify, tensorboard=str(tmp / "tensorboard"),
                             cache_dir=cache_dir)
        timings["identify"] = time.perf_counter() - t
        table, paper = _identification_outputs(meas, res, tmp, step, plots)
        risk = _risk(res.clone, meas, cfg, tmp, base_dir, timings, step, plots)
        decision = risk.pop("decision")
        assessment = risk.pop("assessment_dict")
        basis = decision.basis if decision is not None else run_basis(
            res.clone, assessment=assessment, heights_given=_heights_given(cfg), drift_limit=None)
        flags = run_flags(res.clone, stiffness_error=res.replay.stiffness_error.tolist(),
                          survival=risk.pop("survival_dict"), loss=risk.pop("loss_dict"), basis=basis)
        step.close()
        for flag in flags:
            _progress.warn(f"flag: {flag}")
        timings["total"] = time.perf_counter() - t_all
        rc = res.replay
        summary = RunSummary(
            name=cfg.name, hlaid_version=__version__, source=meas.source, n_stories=meas.n_floors,
            config=ConfigRecord.from_dict(config_to_dict(cfg), file="summary.json", path="config"),
            mass_normalised=res.clone.mass_normalised, parameters=tuple(table), paper_method=tuple(paper),
            replay=Replay(r_measured=tuple(rc.r_measured.tolist()),
                          r_true=None if rc.r_true is None else tuple(rc.r_true.tolist()),
                          stiffness_error=tuple(rc.stiffness_error.tolist())),
            outer_iterations=res.iterations, identify_timings=dict(res.timings), timings=timings,
            noise_rms=meas.noise_rms, flags=tuple(flags), figures=plots,
            basis=basis.to_dict() if cfg.ida is not None else None, **risk)
        write_json(tmp / "summary.json", summary.to_dict())
        build_report(tmp)
    return summary


def _identification_outputs(meas: Measurement, res, tmp: Path, step: _Steps, plots: bool = True
                            ) -> tuple[list[ParameterRow], list[ParameterRow]]:
    """The clone, HLA, parameter tables and identification figures of a run (into ``tmp``); returns
    the parameter tables of the clone and of the paper's method alone."""
    from ..hla.plots import plot_loops, plot_stiffness, wide_band
    res.clone.save(tmp / "clone.json")
    res.hla.save(tmp / "hla")
    truth = meas.truth.building if meas.truth is not None else None
    table = parameter_table(res.clone.building, truth, res.clone.uncertainty)
    paper = parameter_table(res.paper_estimate, truth)
    rows = [r.to_dict() for r in table]
    write_json(tmp / "parameters.json", {"identified": rows, "paper_method": [r.to_dict() for r in paper]})
    (tmp / "parameters.csv").write_text(_csv(rows))
    write_json(tmp / "identification.json", jsonable({**res.clone.diagnostics, **res.clone.identification_dict()}))
    step("figures" if plots else "figures: none (--no-plots)")
    if not plots:
        return table, paper
    figs = tmp / "figures"
    save_figure(plot_loops(res.hla, wide=wide_band(meas, res.hla)), figs / "loops.png")
    save_figure(plot_stiffness(res.hla, meas.truth, clone_ke=res.replay.ke), figs / "stiffness.png")
    save_figure(_replay_figure(meas, res), figs / "replay.png")
    return table, paper


def _heights_given(cfg: RunConfig) -> list[float] | None:
    """The story heights the config gives (the measurement's ``height_mm``, else the IDA's
    ``heights_mm``), None where the heights are the measurement's own."""
    m = cfg.measurement
    if m.height_mm is not None and m.simulate is None:
        return list(m.height_mm)
    if cfg.ida is not None and cfg.ida.heights_mm is not None:
        return list(cfg.ida.heights_mm)
    return None


def _own_motion(meas: Measurement):
    return meas.ground_motion()


def _risk(clone, meas: Measurement, cfg: RunConfig, tmp: Path, base_dir, timings: dict, step: _Steps,
          plots: bool = True) -> dict:
    """The IDA (before and after the event), the ensemble assessment and the losses a run's config
    asks for (into ``tmp``, their times into ``timings``); returns the summary's blocks of them
    (and, for the flags, ``*_dict``: the survival, the assessment and the losses as mappings)."""
    out: dict = dict.fromkeys(("ida", "ida_after", "assessment", "loss", "survival", "survival_dict",
                               "assessment_dict", "loss_dict", "decision"))
    out["events"] = ()
    if cfg.ida is None:
        return out
    t = time.perf_counter()
    step("incremental dynamic analysis of the clone" + (" from the state the event left it in"
                                                        if cfg.ida.start == "carried" else ""))
    from ..events.evidence import survivors
    from ..ida import ida_from_config
    own = _own_motion(meas)
    ir = ida_from_config(clone, cfg.ida, base_dir=base_dir, event_motions=[own])
    ir.save(tmp / "ida", plots=plots, n_boot=cfg.ida.bootstrap, ci=cfg.ida.ci, seed=cfg.ida.seed)
    out["ida"] = _ida_summary(tmp / "ida")
    timings["ida"] = time.perf_counter() - t
    surv = survivors(clone, 0, prepare=lambda _: ir.building, motions=[own], drift_limit=cfg.ida.drift_limit,
                     max_step=cfg.ida.max_step)
    out["survival_dict"] = surv.to_dict()
    if cfg.ida.start == "undamaged":
        t = time.perf_counter()
        step("incremental dynamic analysis from the state the event left the clone in"
             + ("" if clone.state is not None else ": skipped (the clone carries no state)"))
        if clone.state is not None:
            out["ida_after"] = _aftershock(clone, ir, cfg, tmp, base_dir, own, plots)
            timings["ida_after"] = time.perf_counter() - t
    if cfg.assess is not None:
        t = time.perf_counter()
        step(f"ensemble assessment: IDA of {cfg.assess.n_ensemble} clones drawn from the identification uncertainty, "
             "those that collapse under the measured record rejected")
        out["assessment"], out["assessment_dict"] = _assess(clone, meas, cfg, tmp, base_dir, plots)
        timings["assess"] = time.perf_counter() - t
        if out["assessment_dict"] is not None:
            out["survival_dict"] = {**out["survival_dict"], **out["assessment_dict"]["survival"],
                                    "nominal_survives": surv.nominal_survives,
                                    "nominal_collapsed_in": surv.nominal_collapsed_in}
    out["survival"] = Survival.from_dict(out["survival_dict"], file="summary.json", path="survival")
    out["decision"] = _decision(clone, ir, cfg, out["assessment_dict"], meas)
    out["events"] = tuple(EventRisk.from_dict(e.to_dict(), file="summary.json", path="events")
                          for e in out["decision"].basis.events)
    if cfg.loss is not None:
        t = time.perf_counter()
        step("FEMA P-58 losses through pelicun: the measured record and the IDA stripes")
        out["loss"], out["loss_dict"] = _loss(clone, meas, cfg, tmp, out["ida"], out["assessment"], base_dir, plots)
        timings["loss"] = time.perf_counter() - t
    return out


def _decision(clone, ir, cfg: RunConfig, assessment: dict | None, meas: Measurement):
    """The run's decision (:func:`hlaid.run.decide.decide`): both questions at every event of the
    clone, the members of the ensemble assessment replaying each event's own motion, the
    assessment's band beside the fragility's figure and its members' median peak drift ratio as
    the demand."""
    from .decide import decide

    assert cfg.ida is not None
    demand = None
    if assessment and assessment.get("own_peak_drift") is not None:
        demand = float(np.median(np.asarray(assessment["own_peak_drift"], dtype=float)))
    ens = {e["name"]: e for e in (assessment or {}).get("events") or () if isinstance(e, dict) and "name" in e}
    n = cfg.assess.n_ensemble if cfg.assess is not None and clone.uncertainty is not None else 0
    seed = cfg.assess.seed if cfg.assess is not None else 0
    return decide(clone, ir, cfg.ida, at_hand=[meas], n_ensemble=n, seed=seed,
                  heights_given=_heights_given(cfg), demand_ratio=demand, ensemble_events=ens)


def _ida_summary(folder: Path) -> IDASummary:
    """The IDA's ``summary.json`` in ``folder``, as the run summary's block."""
    return IDASummary.from_dict(read_json(folder / "summary.json"), file=f"{folder.name}/summary.json")


def _aftershock(clone, before, cfg: RunConfig, tmp: Path, base_dir, own, plots: bool = True) -> IDASummary:
    """The IDA of the clone from the state its event left it in (``ida-after/``) and the figure of
    the fragility before and after; returns the summary's ``ida_after`` block."""
    from ..ida import ida_from_config
    from ..ida.plots import plot_fragility_before_after
    assert cfg.ida is not None
    after = ida_from_config(clone, cfg.ida.replace(start="carried"), base_dir=base_dir, event_motions=[own])
    after.save(tmp / "ida-after", plots=False, n_boot=cfg.ida.bootstrap, ci=cfg.ida.ci, seed=cfg.ida.seed)
    if plots:
        save_figure(plot_fragility_before_after(before, after), tmp / "figures" / "aftershock.png")
    return _ida_summary(tmp / "ida-after")


def _assess(clone, meas: Measurement, cfg: RunConfig, tmp: Path, base_dir, plots: bool = True
            ) -> tuple[Assessment | None, dict | None]:
    """Ensemble IDA and re-occupancy indicator at the measured record; writes ``assessment.json`` and
    ``figures/fragility_band.png``; returns the summary's ``assessment`` block and the assessment
    as a mapping (None: no uncertainty)."""
    from ..ida import assess
    if clone.uncertainty is None:
        _progress.warn("no identification uncertainty (refinement off): the ensemble assessment is skipped")
        return None, None
    a, ida_cfg = cfg.assess, cfg.ida
    if a is None or ida_cfg is None:  # load_run_config allows an assess block only with an ida block
        return None, None
    recs = ida_cfg.record_specs(base_dir)
    own = _own_motion(meas)
    res = assess(clone, recs, n_ensemble=a.n_ensemble, ida_config=ida_cfg, own_motion=own, seed=a.seed,
                 n_boot=a.n_boot, ci=a.ci)
    d = res.to_dict()
    write_json(tmp / "assessment.json", d)
    if plots:
        save_figure(res.plot(), tmp / "figures" / "fragility_band.png")
    medians = {"own_residual_drift_median": float(np.median(cast(np.ndarray, res.own_residual_drift))),
               "own_peak_drift_median": float(np.median(cast(np.ndarray, res.own_peak_drift)))}  # own_motion given
    return Assessment.from_dict({**d, **medians}, file="assessment.json"), d


def _loss(clone, meas: Measurement, cfg: RunConfig, tmp: Path, ida_summary: IDASummary | None,
          assessment: Assessment | None, base_dir, plots: bool = True) -> tuple[LossSummary, dict]:
    """FEMA P-58 losses at the measured record and the IDA stripes (``loss/``); the summary's ``loss`` block."""
    from ..loss.assess import assess_losses
    from .loss import run_collapse
    a, ida_cfg, lc = cfg.assess, cfg.ida, cfg.loss
    if ida_cfg is None or lc is None:  # load_run_config allows a loss block only with an ida block
        raise InputError("the loss block needs an ida block")
    collapse, src = run_collapse(assessment, ida_summary, source=str(tmp))
    n_ens = a.n_ensemble if a is not None and assessment is not None else 0
    levels = lc.levels if lc.levels is not None else list(ida_summary.levels_g if ida_summary is not None else ())
    own = _own_motion(meas)
    block = assess_losses(clone, own, records=ida_cfg.record_specs(base_dir), levels=levels, collapse=collapse,
                          cfg=lc, ida_config=ida_cfg, n_ensemble=n_ens, seed=a.seed if a is not None else 0,
                          folder=tmp / "loss", collapse_source=src, base_dir=base_dir, plots=plots)
    return LossSummary.of_losses(block), block


def _replay_figure(meas: Measurement, res):
    from ..hla.analysis import floor_motion
    from ..signal import bandpass
    _, _, _, disp = floor_motion(meas, res.hla.config)
    rep = bandpass(res.replay.disp, meas.dt, res.hla.band_hz)
    series, labels = [disp, rep], ["measured (integrated)", "clone (replayed)"]
    if meas.truth is not None:
        series.insert(0, meas.truth.disp)
        labels.insert(0, "true")
    r = corrcoef(rep, disp)
    notes = [f"R = {v:.3f}" for v in r]
    return plot_time_histories(meas.time, series, labels, ylabel="disp. [mm]", annotate=notes, panel="floor",
                               title="Floor displacement relative to the ground: measured against replayed clone")


def run_from_file(path: str | Path, out: str | Path, *, force: bool = False,
                  cache_dir: str | None = None) -> RunSummary:
    cfg = load_run_config(path)
    return run_pipeline(cfg, out, base_dir=Path(path).parent, force=force, cache_dir=cache_dir, inputs=[path])


__all__ = ["RunConfig", "MeasurementSource", "load_run_config", "run_pipeline", "run_from_file", "parameter_table"]
