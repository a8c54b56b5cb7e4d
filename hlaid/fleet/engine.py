"""Running a fleet on dask.distributed: one task per (building, event), results as they come.

The driver (this process) reads the IDA records once and scatters them to every worker, then
submits one task per unit (:func:`hlaid.fleet.task.run_unit`): a worker holds one building from
its measurement to its decision. Each finished unit is written at once, atomically, to
``OUT/buildings/BUILDING@EVENT.json`` with the digest of its inputs, so a rerun skips it; a
unit that failed is retried by the next run. The table and the report are rebuilt from those
files at the end of every run.

Ctrl-C: the worker processes are started with SIGINT ignored (only the driver handles it); the
driver cancels the tasks, closes the client and the cluster, and the command exits with 130. A
Ctrl-C in the seconds while the workers start is ignored (the driver ignores it then too).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from .. import _progress
from .._fileio import MARKER as OUTPUT_MARKER
from .._fileio import write_json
from .._inputs import own_files, read_json
from .._outdir import marker as output_marker
from .._outdir import warn_unsigned, written_here
from .._version import __version__
from ..errors import InputError, one_line
from ..io import read
from .address import probe
from .assess import POINT, default_assess, engine_label, point_assess
from .config import ClusterConfig, FleetConfig, load_fleet_config
from .output import MARKER, check_output
from .report import build_fleet_report, table_rows, write_table
from .task import RESULT_FORMAT, UnitJob, make_jobs, records_digest, run_unit


@dataclass(frozen=True)
class FleetSummary:
    """What a fleet run did: units computed, skipped (done before) and failed; the table rows."""

    out: Path
    computed: tuple[str, ...]
    skipped: tuple[str, ...]
    failed: tuple[str, ...]
    rows: list
    wall_s: float


def _dask():
    try:
        from dask import distributed
    except ImportError:
        raise InputError("hlaid fleet needs dask.distributed: pip install \"hlaid[fleet]\"") from None
    return distributed


@contextlib.contextmanager
def _workers_ignore_sigint() -> Iterator[None]:
    """SIGINT ignored while the worker processes start: an ignored signal stays ignored in a
    spawned child (a blocked one does not: multiprocessing's spawn clears the mask), so a Ctrl-C
    sent to the whole process group reaches only the driver, which then closes the cluster.
    Only the main thread can change it; elsewhere (a library caller's thread) nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def open_client(cluster: ClusterConfig, scheduler: str | None = None) -> Iterator:
    """A dask ``Client``: of the cluster at ``scheduler`` (an address such as
    ``tcp://10.0.0.5:8786``), else of an embedded ``LocalCluster`` closed on exit."""
    if scheduler:
        probe(scheduler)  # a valid address where a dask scheduler answers (hlaid.fleet.address)
    distributed = _dask()
    if scheduler:
        try:
            client = distributed.Client(scheduler, timeout="20s")
        except Exception as err:  # noqa: BLE001 - whatever dask raises for a failed connection is one line
            raise InputError(f"--scheduler {scheduler}: cannot connect ({type(err).__name__}: "
                             f"{one_line(err, 200)})") from None
        try:
            yield client
        finally:
            client.close()
        return
    with _workers_ignore_sigint():
        lc = distributed.LocalCluster(n_workers=cluster.n_workers, threads_per_worker=cluster.threads_per_worker,
                                      processes=cluster.processes, memory_limit=cluster.memory_limit,
                                      dashboard_address=None, silence_logs=logging.CRITICAL)
    try:
        client = distributed.Client(lc)
        try:
            yield client
        finally:
            client.close()
    finally:
        lc.close()


# ---------------------------------------------------------------------------- output folder
def prepare_output(out: Path, *, force: bool, jobs: list[UnitJob] | tuple = ()) -> Path:
    """Create (or reopen) the output folder (see :func:`check_output`) and mark it as hlaid's."""
    out = check_output(out, force=force)
    out.mkdir(exist_ok=True)
    (out / "buildings").mkdir(exist_ok=True)
    mark_output(out, jobs, pending=True)
    return out


FLEET_FILES = (MARKER, "buildings", "results.csv", "results.parquet", "report.html")
"""What a fleet writes in its folder, besides ``buildings/UNIT.json`` per unit."""


def mark_output(out: Path, jobs: list[UnitJob] | tuple = (), *, pending: bool = False) -> None:
    """Write the folder's :data:`hlaid._fileio.MARKER` listing what the fleet writes there (also
    for earlier configs, where the marker is this folder's own), so that another command's
    ``--force`` may replace the folder when it holds nothing else, and a rerun resumes it. With
    ``pending`` (before the run) the tables, the report and the results of units not finished yet
    are listed without their contents (the run rewrites them); the rest are recorded."""
    files = set(FLEET_FILES) | {f"buildings/{j.unit}.json" for j in jobs} | (written_here(out) or set())
    todo = set()
    if pending:
        todo = set(FLEET_FILES) - {"buildings"} | {f"buildings/{j.unit}.json" for j in jobs}
        todo -= {f for f in files if f.startswith("buildings/") and _finished(out / f, jobs)}
    body = output_marker("hlaid fleet", sorted(files), out, pending=todo)
    write_json(out / OUTPUT_MARKER, body)
    if not pending:
        warn_unsigned(body, out)  # said once, when the fleet's output is complete


def _finished(path: Path, jobs) -> bool:
    """Whether ``path`` holds an ``ok`` result of one of ``jobs`` (kept by this run)."""
    digests = {f"{j.unit}.json": j.digest for j in jobs}
    try:
        with own_files():
            d = read_json(path)
    except InputError:
        return False
    return isinstance(d, dict) and d.get("status") == "ok" and d.get("digest") == digests.get(path.name)


def result_path(out: Path, job: UnitJob) -> Path:
    return out / "buildings" / f"{job.unit}.json"


def stored_result(out: Path, job: UnitJob) -> dict | None:
    """The stored result of a unit, or None (none, unreadable, or not a fleet result)."""
    p = result_path(out, job)
    if not os.path.lexists(p):
        return None
    try:
        with own_files():  # the fleet's own file, rewritten when the unit is recomputed
            d = read_json(p)
    except InputError as err:
        _progress.warn(f"unreadable result ({err}); {job.unit} is recomputed")
        return None
    return d if isinstance(d, dict) and d.get("format") == RESULT_FORMAT else None


def plan(out: Path, jobs: list[UnitJob], *, force: bool) -> tuple[list[UnitJob], list[dict]]:
    """``(jobs to run, results kept)``: an ``ok`` result with the job's digest is kept; a failed
    one is retried; an ``ok`` result of other inputs (stale) is recomputed only with ``force``."""
    todo, kept, stale = [], [], []
    for job in jobs:
        d = stored_result(out, job)
        if d is not None and d.get("status") == "ok":
            if d.get("digest") == job.digest:
                kept.append(d)
                continue
            stale.append(job.unit)
        todo.append(job)
    if stale and not force:
        shown = ", ".join(stale[:5]) + (f" and {len(stale) - 5} more" if len(stale) > 5 else "")
        raise InputError(f"holds results of other inputs (config, files or hlaid version changed) for {shown}; "
                         "use --force to recompute them, or choose another folder", source=str(out))
    return todo, kept


# ---------------------------------------------------------------------------- the run
def run_fleet(cfg: FleetConfig, out: str | Path, *, base_dir: str | Path | None = None, scheduler: str | None = None,
              client=None, force: bool = False, assess: Callable | None = None,
              cache_dir: str | None = None) -> FleetSummary:
    """Assess every (building, event) of ``cfg`` on dask and write the table and the report.

    Parameters
    ----------
    cfg : the fleet config
    out : output folder (created; a fleet output is resumed)
    base_dir : folder that relative paths in ``cfg`` are taken from
    scheduler : address of an existing dask scheduler; None: an embedded ``LocalCluster``
        (``cfg.cluster``); ``client``: an already connected ``dask.distributed.Client`` instead
    force : recompute units whose stored result came from other inputs
    assess : an assess function (contract: :mod:`hlaid.fleet.assess`); None:
        ``hlaid.ida.assess`` (``n_ensemble: 0``: :func:`~hlaid.fleet.assess.point_assess`)
    cache_dir : classifier cache of the identifications (None: hlaid's default)
    """
    t0 = time.perf_counter()
    base = Path(base_dir) if base_dir is not None else None
    out = check_output(Path(out), force=force)
    if scheduler and client is None:
        probe(scheduler)  # before anything is read or written: a wrong address is one line at once
    if cfg.loss is not None:  # fail before the fleet runs when pelicun is missing
        from ..loss.fema_p58 import require_pelicun
        require_pelicun()
    records = read(cfg.record_specs(base), kind="records", units=cfg.ida.units)
    given_assess = assess
    if assess is None and cfg.n_ensemble == 0:
        assess, engine = point_assess, POINT
    elif assess is None:
        assess, engine = default_assess()
        if cfg.identify.refine.method == "none":
            raise InputError("identify.refine.method is 'none': such clones carry no identification uncertainty, "
                             "which the ensemble (n_ensemble > 0) is drawn from; use 'replay' or n_ensemble: 0")
    else:
        engine = engine_label(assess)
    if given_assess is None and engine != POINT and len(records) < 2:
        raise InputError(f"the assessment fits a collapse fragility and needs at least 2 IDA records; the config "
                         f"names {len(records)} (records:)")
    cfg.check_measurement_files(base)  # a missing measurement: before a cluster starts or anything is identified
    jobs = make_jobs(cfg, base, records_digest(records), engine, cache_dir=cache_dir)
    todo, kept = plan(out, jobs, force=force)
    computed: list[str] = []
    failed: list[str] = []
    results = {d["unit"]: d for d in kept}
    ctx = contextlib.nullcontext(client) if client is not None or not todo else open_client(cfg.cluster, scheduler)
    with ctx as cl:
        prepare_output(out, force=force, jobs=jobs)  # only now, when nothing refused the run and the cluster is up
        _progress.info(f"fleet {cfg.name!r}: {len(jobs)} unit(s) (building@event), {len(kept)} done before, "
                       f"{len(todo)} to run; {len(records)} IDA records, ensemble {cfg.n_ensemble}, assessment: "
                       f"{engine}")
        write_json(out / MARKER, {"format": "hlaid-fleet", "version": 1, "name": cfg.name,
                                  "hlaid_version": __version__, "state": "running", "units": [j.unit for j in jobs]})
        if todo:
            computed, failed = _run_on(cl, todo, records, assess, out, results)
    ordered = [results[j.unit] for j in jobs if j.unit in results]
    rows = table_rows(ordered)
    wall = time.perf_counter() - t0
    written = write_table(rows, out)
    meta = {"name": cfg.name, "n_records": len(records), "n_ensemble": cfg.n_ensemble, "hlaid_version": __version__,
            "wall_s": wall}
    build_fleet_report(out, rows, meta)
    write_json(out / MARKER, {"format": "hlaid-fleet", "version": 1, "name": cfg.name, "hlaid_version": __version__,
                              "state": "complete", "units": [j.unit for j in jobs], "computed": computed,
                              "skipped": [d["unit"] for d in kept], "failed": failed, "engine": engine,
                              "n_records": len(records), "wall_s": wall,
                              "tables": [p.name for p in written]})
    mark_output(out, jobs)
    _progress.info(f"wrote {out}/ (report.html, {', '.join(p.name for p in written)}, buildings/): "
                   f"{len(rows) - len(failed)} ok, {len(failed)} failed, {wall:.1f} s")
    return FleetSummary(out=out, computed=tuple(computed), skipped=tuple(d["unit"] for d in kept),
                        failed=tuple(failed), rows=rows, wall_s=wall)


def _run_on(client, todo: list[UnitJob], records, assess, out: Path, results: dict) -> tuple[list, list]:
    distributed = _dask()
    n_workers = len(client.scheduler_info().get("workers", {}))
    _progress.info(f"dask: {n_workers} worker(s) at {client.scheduler.address}")
    futures = {}
    try:
        recs = client.scatter(list(records), broadcast=True)
    except BaseException:
        _quiet()
        raise
    for job in todo:
        f = client.submit(run_unit, job, recs, assess, key=f"hlaid-fleet-{job.unit}-{job.digest[:12]}", pure=False)
        futures[f] = job
    computed: list[str] = []
    failed: list[str] = []
    try:
        with _progress.stage("fleet", len(todo), unit="units") as bar:
            for i, fut in enumerate(distributed.as_completed(futures), 1):
                job = futures[fut]
                try:
                    res = fut.result()
                except Exception as err:  # noqa: BLE001 - a lost worker, an unpicklable result ...
                    res = {"format": RESULT_FORMAT, "version": 1, "unit": job.unit, "building": job.building,
                           "event": job.event, "digest": job.digest, "status": "failed", "stage": "worker",
                           "reason": f"worker: {type(err).__name__}: {one_line(err, 300)}",
                           "timings": {}}
                write_json(result_path(out, job), res)
                results[job.unit] = res
                (computed if res["status"] == "ok" else failed).append(job.unit)
                t = res.get("timings", {}).get("total_s")
                what = (_risk_text(res["row"]) if res["status"] == "ok" else res["reason"])
                line = f"{job.unit}: {res['status']}" + (f" in {t:.1f} s" if t is not None else "") + f" ({what})"
                quiet = res["status"] == "ok" and _progress.drawing()  # on a terminal the bar shows it
                (_progress.debug if quiet else _progress.info)(f"[{i}/{len(todo)}] {line}")
                bar.update(1, note=f"last {line}"[:80])
            bar.done(f"{len(computed)} ok, {len(failed)} failed")
    except BaseException:  # Ctrl-C: stop the remaining tasks before the cluster closes
        _quiet()
        client.cancel(list(futures), force=True)
        raise
    return computed, failed


def _quiet() -> None:
    """After Ctrl-C: the connections that the closing cluster cuts are expected, not errors to
    log (asyncio's "exception was never retrieved", distributed's comm errors)."""
    for name in ("asyncio", "distributed", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


def _risk_text(row: dict) -> str:
    p, r = row.get("p_collapse"), row.get("indicator")
    return ", ".join(([f"P(collapse) {p:.3g}"] if isinstance(p, (int, float)) else [])
                     + ([str(r)] if r is not None else [])) or "no risk figures"


def run_fleet_from_file(path: str | Path, out: str | Path, **kw) -> FleetSummary:
    """Load a fleet config and :func:`run_fleet` it (relative paths from the config's folder)."""
    cfg = load_fleet_config(path)
    return run_fleet(cfg, out, base_dir=Path(path).parent, **kw)


__all__ = ["run_fleet", "run_fleet_from_file", "open_client", "FleetSummary", "plan", "check_output",
           "prepare_output", "mark_output", "MARKER"]
