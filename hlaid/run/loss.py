"""``hlaid loss RUN_DIR``: the losses of a run folder (:func:`loss_of_run`), from its clone, its
measured record and its collapse fragility, through :func:`hlaid.loss.assess_losses`."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._fileio import write_json
from ..errors import InputError
from ..loss.assess import assess_losses
from ..loss.config import LossConfig


def _read_json(path: Path, what: str):
    """The JSON in ``path``, read as every input is (:mod:`hlaid._inputs`); a missing file says ``what``."""
    from .._inputs import read_json

    if not os.path.lexists(path):
        raise InputError(f"{path.name} not found; {what}", source=str(path.parent))
    return read_json(path)


def run_collapse(run_dir: Path, summary: dict) -> tuple[tuple[float, float], str]:
    """The collapse fragility of a run: the ensemble's (``assessment.json``) or the IDA's."""
    a = summary.get("assessment")
    if isinstance(a, dict) and a.get("collapse_median") and a.get("beta"):
        return (float(a["collapse_median"]), float(a["beta"])), (
            f"ensemble of {a.get('n_ensemble')} clones x {a.get('n_records')} records (median of members' fits)")
    ida = summary.get("ida")
    if not isinstance(ida, dict):
        raise InputError("the run has no IDA, whose collapse fragility the losses need: add an ida block and "
                         "rerun hlaid run", source=str(run_dir))
    f = (ida.get("collapse_fragility") or {}).get("capacities") or {}
    if not f.get("median_g") or not f.get("beta"):
        raise InputError("the run's IDA has no fitted collapse fragility (ida/summary.json)", source=str(run_dir))
    n = len(ida.get("records", []))
    return (float(f["median_g"]), float(f["beta"])), f"IDA of the identified clone, {n} records"


def loss_of_run(run_dir: str | os.PathLike, cfg: LossConfig | None = None, *, records=None, force: bool = False,
                base_dir: str | os.PathLike | None = None) -> dict:
    """``hlaid loss RUN_DIR``: losses of a run folder written into ``RUN_DIR/loss/`` (replaced only with
    ``force``); its summary becomes the ``loss`` block of ``summary.json`` and ``report.html`` is rebuilt.

    The clone is ``clone.json``; the recorded event the ground motion of ``measurement.npz``; the
    ensemble and the IDA settings those of the run's config (``assess``, ``ida``); the loss settings
    ``cfg`` (None: the run config's ``loss`` block, else defaults); the stripes' records ``records``
    (None: the run's IDA records, relative paths from ``base_dir``).
    """
    from .._fileio import atomic_directory
    from ..clone import Clone
    from ..config import config_from_dict
    from ..ida.config import IDAConfig
    from ..io import read
    from ..motions import GroundMotion
    from .report import build_report

    d = Path(run_dir)
    if not d.is_dir():
        raise InputError("not found or not a folder; expected a run folder written by hlaid run or hlaid demo",
                         source=str(d))
    summary = _read_json(d / "summary.json", "expected a run folder written by hlaid run or hlaid demo")
    if not isinstance(summary, dict) or summary.get("format") != "hlaid-run":
        raise InputError("summary.json is not an hlaid run summary", source=str(d))
    conf = summary.get("config") or {}
    if cfg is None:
        cfg = config_from_dict(LossConfig, conf["loss"], f"{d}/summary.json: config.loss") if conf.get("loss") \
            else LossConfig()
    ida_cfg = config_from_dict(IDAConfig, conf["ida"], f"{d}/summary.json: config.ida") if conf.get("ida") \
        else IDAConfig()
    clone = Clone.load(d / "clone.json")
    meas = read(d / "measurement.npz", "measurement")
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc), name="recorded", source=str(d / "measurement.npz"))
    collapse, src = run_collapse(d, summary)
    assess_cfg = conf.get("assess") or {}
    n_ens = int(assess_cfg.get("n_ensemble", 0)) if clone.uncertainty is not None else 0
    levels = cfg.levels if cfg.levels is not None else ((summary.get("ida") or {}).get("levels_g") or [])
    recs = records if records is not None else ida_cfg.record_specs(None if base_dir is None else Path(base_dir))
    inputs = [cfg.inventory, *_files(recs)]  # --force never replaces a folder holding one of them
    with atomic_directory(d / "loss", force=force, inputs=inputs) as tmp:
        block = assess_losses(clone, own, records=recs, levels=levels, collapse=collapse, cfg=cfg, ida_config=ida_cfg,
                              n_ensemble=n_ens, seed=int(assess_cfg.get("seed", 0)), folder=tmp,
                              collapse_source=src, base_dir=base_dir)
    summary["loss"] = run_block(block)
    write_json(d / "summary.json", summary)
    build_report(d)
    return block


def _files(records) -> list:
    """The paths among a records spec (a path, ``builtin...``, or a list of them)."""
    specs = [records] if isinstance(records, (str, os.PathLike)) else list(records or [])
    return [r for r in specs if isinstance(r, (str, os.PathLike)) and not str(r).startswith("builtin")]


def run_block(block: dict) -> dict:
    """The ``loss`` block of a run summary / fleet row: the recorded event's figures and the settings."""
    keep = ("engine", "system", "inventory", "floor_area_m2", "floor_area_source", "replacement_cost",
            "replacement_time", "collapse_fragility", "irreparable", "n_ensemble", "realizations", "assumptions")
    out = {k: block[k] for k in keep}
    out["recorded"] = block["recorded"]
    out["curve"] = [{k: s[k] for k in ("level_g", "repair_cost_ratio_mean", "repair_cost_ratio_median",
                                        "repair_cost_ratio_band", "p_collapse", "p_irreparable")}
                    for s in block["stripes"]]
    return out


__all__ = ["loss_of_run", "run_block", "run_collapse"]
