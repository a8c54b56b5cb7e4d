"""``hlaid loss RUN_DIR``: the losses of a run folder (:func:`loss_of_run`), from its clone, its
measured record and its collapse fragility, through :func:`hlaid.loss.assess_losses`.

Without an output folder the run folder is updated all or nothing: ``loss/``, the ``loss`` block
of ``summary.json`` and ``report.html`` are written under temporary names and put in place
together once all are complete; a failure leaves the run folder as it was. With one (``-o OUT``)
the run folder is only read: ``OUT`` holds what ``RUN_DIR/loss`` would.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..loss.config import LossConfig
from ..loss.fema_p58 import require_pelicun
from .report import Figures, render_report
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
                records=None, out: str | os.PathLike | None = None, force: bool = False,
                base_dir: str | os.PathLike | None = None) -> dict:
    """``hlaid loss RUN_DIR [-o OUT]``: the losses of a run folder; returns ``loss.json``'s content.

    The clone is ``clone.json``; the recorded event the ground motion of ``measurement.npz``; the
    ensemble and the IDA settings those of the run's config (``assess``, ``ida``); the loss settings
    ``cfg`` (None: the run config's ``loss`` block, else the defaults) with ``changes`` (a
    :class:`LossConfig` field each, None values ignored); the stripes' records ``records`` (None: the
    run's IDA records, relative paths from ``base_dir``).

    ``out`` None: ``RUN_DIR/loss/`` (replaced only with ``force``), the ``loss`` block of
    ``summary.json`` and ``report.html`` are replaced together, or none of them. ``out`` given: the
    losses go into that folder (outside the run folder; replaced only with ``force``) and the run
    folder is not written. Either output is checked before the work.
    """
    from .._fileio import atomic_directory, atomic_files, check_output_file, check_output_folder, json_text

    d = Path(run_dir)
    src = str(d)
    s = read_summary(d)
    cfg = (cfg or run_loss_config(s, src)).replace(**(changes or {}))
    recs = records if records is not None else _ida_config(s, src).record_specs(
        None if base_dir is None else Path(base_dir))
    inputs = [cfg.inventory, *_files(recs), d / "clone.json", d / "measurement.npz"]
    if out is not None:
        _outside(Path(out), d)
        check_output_folder(out, force=force, inputs=[*inputs, d])
        require_pelicun()
        with atomic_directory(out, force=force, inputs=[*inputs, d]) as tmp:
            return _assess(d, s, cfg, recs, tmp, base_dir)
    check_output_folder(d / "loss", force=force, inputs=inputs)
    for name in ("summary.json", "report.html"):
        check_output_file(d / name, force=True)
    Figures(d).check(dataclasses.replace(s, loss=None))
    require_pelicun()
    with atomic_files() as stage, atomic_directory(d / "loss", force=force, inputs=inputs, with_files=stage) as tmp:
        block = _assess(d, s, cfg, recs, tmp, base_dir)
        new = dataclasses.replace(s, loss=LossSummary.of_losses(block))
        figs = Figures(d, loss_dir=tmp)
        figs.check(new)
        page = render_report(new, figs)
        stage(d / "summary.json", lambda p: p.write_text(json_text(new.to_dict())))
        stage(d / "report.html", lambda p: p.write_text(page))
    return block


def _assess(d: Path, s: RunSummary, cfg: LossConfig, recs, folder: Path, base_dir) -> dict:
    """The losses of run folder ``d`` (summary ``s``) written into ``folder``; ``loss.json``'s content."""

    from ..clone import Clone
    from ..io import read
    from ..loss.assess import assess_losses
    from ..uncertainty.config import AssessConfig

    src = str(d)
    collapse, collapse_src = run_collapse(s.assessment, s.ida, source=src)
    assess_cfg = _config(AssessConfig, s.config.assess, f"{src}/summary.json: config.assess")
    clone = Clone.load(d / "clone.json")
    meas = read(d / "measurement.npz", "measurement")
    own = meas.ground_motion(name="recorded", source=str(d / "measurement.npz"))
    n_ens = assess_cfg.n_ensemble if assess_cfg is not None and clone.uncertainty is not None else 0
    levels = cfg.levels if cfg.levels is not None else list(s.ida.levels_g if s.ida is not None else ())
    events = [e.to_dict() for e in s.events] if s.events else None  # the run's figures, not new ones
    assumed = bool(s.basis.get("heights_assumed")) if s.basis is not None else None
    return assess_losses(clone, own, records=recs, levels=levels, collapse=collapse, cfg=cfg,
                         ida_config=_ida_config(s, src), n_ensemble=n_ens,
                         seed=assess_cfg.seed if assess_cfg is not None else 0, folder=folder,
                         collapse_source=collapse_src, base_dir=base_dir, events=events, heights_assumed=assumed)


def _ida_config(s: RunSummary, src: str):
    from ..ida.config import IDAConfig

    return _config(IDAConfig, s.config.ida, f"{src}/summary.json: config.ida") or IDAConfig()


def _outside(out: Path, run_dir: Path) -> None:
    """Refuse an output folder inside the run folder (``-o`` leaves the run folder as it is)."""
    o = Path(os.path.abspath(out))
    o, r = o.parent.resolve() / o.name, run_dir.resolve()  # a link named OUT is replaced, not followed
    if o == r or r in o.parents:
        raise InputError(f"is inside the run folder {run_dir}; -o writes the losses elsewhere and leaves the run "
                         "folder as it is (without -o they go into RUN_DIR/loss and its report)", source=str(out))


def _files(records) -> list:
    """The paths among a records spec (a path, ``builtin...``, or a list of them)."""
    specs = [records] if isinstance(records, (str, os.PathLike)) else list(records or [])
    return [r for r in specs if isinstance(r, (str, os.PathLike)) and not str(r).startswith("builtin")]


__all__ = ["loss_of_run", "run_collapse", "run_loss_config"]
