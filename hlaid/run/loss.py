"""``hlaid loss RUN_DIR``: the losses of a run folder (:func:`loss_of_run`), from its clone, its
measured record and its collapse fragility, through :func:`hlaid.loss.assess_losses`.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..loss.config import LossConfig
from .summary import Assessment, IDASummary, LossSummary, RunSummary, read_summary


def run_collapse(assessment: Assessment | None, ida: IDASummary | None, *,
                 source: str | None = None) -> tuple[tuple[float, float], str]:
    """The collapse fragility ``(median [g], beta)`` of a run and where it comes from: the ensemble
    assessment's, else the IDA's fit to the records' collapse capacities."""
    a = assessment
    if a is not None and a.collapse_median and a.beta:
        return (float(a.collapse_median), float(a.beta)), (
            f"ensemble of {a.n_ensemble} clones x {a.n_records} records (median of members' fits)")
    if ida is None:
        raise InputError("the run has no IDA, whose collapse fragility the losses need: add an ida block and "
                         "rerun hlaid run", source=source)
    f = ida.collapse_fragility.capacities if ida.collapse_fragility is not None else None
    if f is None or not f.median_g or not f.beta:
        raise InputError("the run's IDA has no fitted collapse fragility (ida/summary.json)", source=source)
    return (float(f.median_g), float(f.beta)), f"IDA of the identified clone, {len(ida.records)} records"


def run_loss_config(summary: RunSummary, source: str) -> LossConfig:
    """The loss settings of a run: its config's ``loss`` block, else the defaults."""
    return _config(LossConfig, summary.config.loss, f"{source}/summary.json: config.loss") or LossConfig()


def _config(cls, block: Mapping | None, source: str):
    from ..config import config_from_dict

    return None if block is None else config_from_dict(cls, dict(block), source)


def loss_of_run(run_dir: str | os.PathLike, cfg: LossConfig | None = None, *, changes: Mapping[str, Any] | None = None,
                records=None, force: bool = False, base_dir: str | os.PathLike | None = None) -> dict:
    """``hlaid loss RUN_DIR``: losses of a run folder written into ``RUN_DIR/loss/`` (replaced only with
    ``force``); its summary becomes the ``loss`` block of ``summary.json`` and ``report.html`` is rebuilt.

    The clone is ``clone.json``; the recorded event the ground motion of ``measurement.npz``; the
    ensemble and the IDA settings those of the run's config (``assess``, ``ida``); the loss settings
    ``cfg`` (None: the run config's ``loss`` block, else the defaults) with ``changes`` (a
    :class:`LossConfig` field each, None values ignored); the stripes' records ``records`` (None: the
    run's IDA records, relative paths from ``base_dir``).
    """
    from .._fileio import atomic_directory, write_json
    from .report import build_report

    d = Path(run_dir)
    src = str(d)
    s = read_summary(d)
    cfg = (cfg or run_loss_config(s, src)).replace(**(changes or {}))
    recs = records if records is not None else _ida_config(s, src).record_specs(
        None if base_dir is None else Path(base_dir))
    inputs = [cfg.inventory, *_files(recs)]  # --force never replaces a folder holding one of them
    with atomic_directory(d / "loss", force=force, inputs=inputs) as tmp:
        block = _assess(d, s, cfg, recs, tmp, base_dir)
    write_json(d / "summary.json", dataclasses.replace(s, loss=LossSummary.of_losses(block)).to_dict())
    build_report(d)
    return block


def _assess(d: Path, s: RunSummary, cfg: LossConfig, recs, folder: Path, base_dir) -> dict:
    """The losses of run folder ``d`` (summary ``s``) written into ``folder``; ``loss.json``'s content."""
    import numpy as np

    from ..clone import Clone
    from ..io import read
    from ..loss.assess import assess_losses
    from ..motions import GroundMotion
    from ..uncertainty.config import AssessConfig

    src = str(d)
    collapse, collapse_src = run_collapse(s.assessment, s.ida, source=src)
    assess_cfg = _config(AssessConfig, s.config.assess, f"{src}/summary.json: config.assess")
    clone = Clone.load(d / "clone.json")
    meas = read(d / "measurement.npz", "measurement")
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc), name="recorded", source=str(d / "measurement.npz"))
    n_ens = assess_cfg.n_ensemble if assess_cfg is not None and clone.uncertainty is not None else 0
    levels = cfg.levels if cfg.levels is not None else list(s.ida.levels_g if s.ida is not None else ())
    return assess_losses(clone, own, records=recs, levels=levels, collapse=collapse, cfg=cfg,
                         ida_config=_ida_config(s, src), n_ensemble=n_ens,
                         seed=assess_cfg.seed if assess_cfg is not None else 0, folder=folder,
                         collapse_source=collapse_src, base_dir=base_dir)


def _ida_config(s: RunSummary, src: str):
    from ..ida.config import IDAConfig

    return _config(IDAConfig, s.config.ida, f"{src}/summary.json: config.ida") or IDAConfig()


def _files(records) -> list:
    """The paths among a records spec (a path, ``builtin...``, or a list of them)."""
    specs = [records] if isinstance(records, (str, os.PathLike)) else list(records or [])
    return [r for r in specs if isinstance(r, (str, os.PathLike)) and not str(r).startswith("builtin")]


__all__ = ["loss_of_run", "run_collapse", "run_loss_config"]
