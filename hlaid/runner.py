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

from . import _progress
from ._fileio import atomic_directory, check_output_folder, write_json
from ._inputs import read_json
from ._version import __version__
from .config import config_to_dict
from .errors import InputError
from .identify import identify_clone
from .identify.config import RefineConfig
from .identify.replaycheck import corrcoef
from .io import read
from .measurement import Measurement, check_band
from .model import Building
from .plots import plot_time_histories, save_figure
from .runconfig import MeasurementSource, RunConfig, input_paths, load_run_config
from .synthetic import measurement_from_config

PARAMS = ("alpha", "p", "delta_eta", "dy", "k0")


def load_measurement(src: MeasurementSource, base_dir: Path | None) -> Measurement:
    import dataclasses
    if src.simulate is not None:
        meas = measurement_from_config(src.simulate, base_dir=base_dir)
    else:
        path = Path(cast(str, src.file))  # file is given when simulate is not (MeasurementSource)
        if base_dir is not None and not path.is_absolute():
            path = Path(base_dir) / path
        meas = read(path, "measurement", format=src.format, **src.options)
    changes: dict[str, Any] = {}
    if src.mass_t is not None:
        changes["mass"] = np.asarray(src.mass_t, float)
    if src.height_mm is not None:
        changes["height"] = np.asarray(src.height_mm, float)
    return dataclasses.replace(meas, **changes) if changes else meas


def parameter_table(identified: Building, truth: Building | None, uncertainty=None) -> list[dict]:
    """The paper's Table 4 layout: one row per parameter and story (error when the truth is known;
    with ``uncertainty`` the 90 % interval, ``lo90`` and ``hi90``, None for a parameter without one)."""
    rows = []
    iv = uncertainty.interval(0.9) if uncertainty is not None else None
    for name in PARAMS:
        for i in range(identified.n_stories):
            v = float(getattr(identified, name)[i])
            t = None if truth is None else float(getattr(truth, name)[i])
            row = {"parameter": name, "story": i + 1, "identified": v, "true": t,
                   "error": None if t is None else abs(v / t - 1.0)}
            if iv is not None:
                row["lo90"], row["hi90"] = iv.get(f"{name}[{i + 1}]", (None, None))
            rows.append(row)
    return rows


def _csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def run_pipeline(cfg: RunConfig, out: str | Path, *, base_dir: str | Path | None = None, force: bool = False,
                 cache_dir: str | None = None, inputs: Sequence[str | Path | None] = ()) -> dict:
    """Run the pipeline and write everything under ``out``; returns the run summary. An existing
    ``out`` is replaced only with ``force``, when hlaid wrote it and it holds none of ``inputs``
    (the run's own input files are added to them)."""
    from .hla.plots import plot_loops, plot_stiffness
    from .report import build_report
    t_all = time.perf_counter()
    timings = {}
    if cfg.loss is not None:  # fail before the pipeline when pelicun is missing
        from .loss.fema_p58 import require_pelicun
        require_pelicun()
    inputs = [*inputs, *input_paths(cfg, base_dir), cache_dir]
    with atomic_directory(out, force=force, inputs=inputs) as tmp:
        tmp = Path(tmp)
        figs = tmp / "figures"
        figs.mkdir()
        t = time.perf_counter()
        _progress.info("[1/4] measurement")
        meas = load_measurement(cfg.measurement, Path(base_dir) if base_dir else None)
        check_band(meas, cfg.identify.hla.preprocess.band_hz, "identify.hla.preprocess.band_hz")
        check_band(meas, cfg.identify.refine.band_hz, "identify.refine.band_hz", default=RefineConfig().band_hz)
        check_output_folder(out, force=force, inputs=inputs)  # and the files the measurement named: before the work
        meas.save(tmp / "measurement.npz")
        timings["measurement"] = time.perf_counter() - t
        t = time.perf_counter()
        _progress.info("[2/4] hysteresis loop analysis and identification")
        res = identify_clone(meas, cfg.identify, tensorboard=str(tmp / "tensorboard"), cache_dir=cache_dir)
        timings["identify"] = time.perf_counter() - t
        res.clone.save(tmp / "clone.json")
        res.hla.save(tmp / "hla")
        truth = meas.truth.building if meas.truth is not None else None
        table = parameter_table(res.clone.building, truth, res.clone.uncertainty)
        paper = parameter_table(res.paper_estimate, truth)
        write_json(tmp / "parameters.json", {"identified": table, "paper_method": paper})
        (tmp / "parameters.csv").write_text(_csv(table))
        write_json(tmp / "identification.json", res.clone.diagnostics)
        _progress.info("[3/4] figures")
        save_figure(plot_loops(res.hla), figs / "loops.png")
        save_figure(plot_stiffness(res.hla, meas.truth, clone_ke=res.replay.ke), figs / "stiffness.png")
        save_figure(_replay_figure(meas, res), figs / "replay.png")
        ida_summary = ida_after = None
        if cfg.ida is not None:
            t = time.perf_counter()
            _progress.info("[4/4] incremental dynamic analysis of the clone")
            from .ida import ida_from_config
            ir = ida_from_config(res.clone, cfg.ida, base_dir=base_dir)
            ir.save(tmp / "ida", plots=True, n_boot=cfg.ida.bootstrap, ci=cfg.ida.ci, seed=cfg.ida.seed)
            ida_summary = read_json(tmp / "ida" / "summary.json")
            timings["ida"] = time.perf_counter() - t
            if res.clone.state is not None and cfg.ida.start == "undamaged":
                t = time.perf_counter()
                ida_after = _aftershock(res.clone, ir, cfg, tmp, base_dir)
                timings["ida_after"] = time.perf_counter() - t
        assessment = None
        if cfg.ida is not None and cfg.assess is not None:
            t = time.perf_counter()
            assessment = _assess(res.clone, meas, cfg, tmp, base_dir)
            timings["assess"] = time.perf_counter() - t
        loss = None
        if cfg.ida is not None and cfg.loss is not None:
            t = time.perf_counter()
            loss = _loss(res.clone, meas, cfg, tmp, ida_summary, assessment, base_dir)
            timings["loss"] = time.perf_counter() - t
        timings["total"] = time.perf_counter() - t_all
        summary = {"format": "hlaid-run", "version": 1, "name": cfg.name, "hlaid_version": __version__,
                   "config": config_to_dict(cfg), "source": meas.source, "n_stories": meas.n_floors,
                   "mass_normalised": res.clone.mass_normalised, "parameters": table, "paper_method": paper,
                   "replay": res.replay.to_dict(), "outer_iterations": res.iterations,
                   "identify_timings": res.timings, "timings": timings, "ida": ida_summary, "ida_after": ida_after,
                   "noise_rms": meas.noise_rms, "assessment": assessment, "loss": loss}
        write_json(tmp / "summary.json", summary)
        build_report(tmp)
    _progress.info(f"wrote {out}/ (report.html, clone.json, hla/, ida/, figures/, tensorboard/) in "
                   f"{timings['total']:.0f} s")
    return summary


def _aftershock(clone, before, cfg: RunConfig, tmp: Path, base_dir) -> dict:
    """The IDA of the clone from the state its event left it in (``ida-after/``) and the figure of
    the fragility before and after; returns the summary's ``ida_after`` block."""
    from .ida import ida_from_config
    from .ida.plots import plot_fragility_before_after
    assert cfg.ida is not None
    _progress.info("[4/4] incremental dynamic analysis from the state the event left the clone in")
    after = ida_from_config(clone, cfg.ida.replace(start="carried"), base_dir=base_dir)
    after.save(tmp / "ida-after", plots=False, n_boot=cfg.ida.bootstrap, ci=cfg.ida.ci, seed=cfg.ida.seed)
    save_figure(plot_fragility_before_after(before, after), tmp / "figures" / "aftershock.png")
    return read_json(tmp / "ida-after" / "summary.json")


def _assess(clone, meas: Measurement, cfg: RunConfig, tmp: Path, base_dir) -> dict | None:
    """Ensemble IDA and re-occupancy indicator at the measured record; writes ``assessment.json`` and
    ``figures/fragility_band.png``; returns the summary's ``assessment`` block (None: no uncertainty)."""
    from .motions import GroundMotion
    from .uncertainty import assess
    if clone.uncertainty is None:
        _progress.warn("no identification uncertainty (refinement off): the ensemble assessment is skipped")
        return None
    a, ida_cfg = cfg.assess, cfg.ida
    if a is None or ida_cfg is None:  # load_run_config allows an assess block only with an ida block
        return None
    _progress.info(f"[4/4] ensemble assessment: IDA of {a.n_ensemble} clones drawn from the identification "
                   "uncertainty")
    recs = ida_cfg.record_specs(base_dir)
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc), name="measured")
    res = assess(clone, recs, n_ensemble=a.n_ensemble, ida_config=ida_cfg, own_motion=own, seed=a.seed,
                 n_boot=a.n_boot, ci=a.ci)
    d = res.to_dict()
    write_json(tmp / "assessment.json", d)
    save_figure(res.plot(), tmp / "figures" / "fragility_band.png")
    keep = ("n_ensemble", "n_records", "ci", "im_label", "period", "collapse_median", "collapse_median_band",
            "beta", "own_im", "p_collapse", "p_collapse_band", "drift_limits", "p_exceed", "p_exceed_band",
            "indicator", "placard", "reasons", "thresholds")
    out = {k: d[k] for k in keep}
    # both are set when own_motion is given
    out["own_residual_drift_median"] = float(np.median(cast(np.ndarray, res.own_residual_drift)))
    out["own_peak_drift_median"] = float(np.median(cast(np.ndarray, res.own_peak_drift)))
    return out


def _loss(clone, meas: Measurement, cfg: RunConfig, tmp: Path, ida_summary, assessment, base_dir) -> dict:
    """FEMA P-58 losses at the measured record and the IDA stripes (``loss/``); the summary's ``loss`` block."""
    from .loss.assess import assess_losses, run_block, run_collapse
    from .motions import GroundMotion
    a, ida_cfg, lc = cfg.assess, cfg.ida, cfg.loss
    if ida_cfg is None or lc is None:  # load_run_config allows a loss block only with an ida block
        raise InputError("the loss block needs an ida block")
    _progress.info("[4/4] FEMA P-58 losses through pelicun: the measured record and the IDA stripes")
    collapse, src = run_collapse(tmp, {"assessment": assessment, "ida": ida_summary})
    n_ens = a.n_ensemble if a is not None and assessment is not None else 0
    levels = lc.levels if lc.levels is not None else (ida_summary or {}).get("levels_g") or []
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc), name="measured")
    block = assess_losses(clone, own, records=ida_cfg.record_specs(base_dir), levels=levels, collapse=collapse,
                          cfg=lc, ida_config=ida_cfg, n_ensemble=n_ens, seed=a.seed if a is not None else 0,
                          folder=tmp / "loss", collapse_source=src, base_dir=base_dir)
    return run_block(block)


def _replay_figure(meas: Measurement, res):
    from .hla.analysis import floor_motion
    from .signal import bandpass
    _, _, _, disp = floor_motion(meas, res.hla.config)
    rep = bandpass(res.replay.disp, meas.dt, res.hla.band_hz)
    series, labels = [disp, rep], ["measured (integrated)", "clone (replayed)"]
    if meas.truth is not None:
        series.insert(0, meas.truth.disp)
        labels.insert(0, "true")
    r = corrcoef(rep, disp)
    notes = [f"R = {v:.3f}" for v in r]
    return plot_time_histories(meas.time, series, labels, ylabel="disp. [mm]", annotate=notes,
                               title="Floor displacement relative to the ground: measured against replayed clone")


def run_from_file(path: str | Path, out: str | Path, *, force: bool = False, cache_dir: str | None = None) -> dict:
    cfg = load_run_config(path)
    return run_pipeline(cfg, out, base_dir=Path(path).parent, force=force, cache_dir=cache_dir, inputs=[path])


__all__ = ["RunConfig", "MeasurementSource", "load_run_config", "run_pipeline", "run_from_file", "parameter_table"]
