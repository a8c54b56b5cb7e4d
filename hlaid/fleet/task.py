"""One building under one event: measurement -> identify -> assess, run on one dask worker.

A :class:`UnitJob` holds everything the worker needs (resolved paths, settings, seed); the IDA
records come separately (scattered once to every worker). :func:`run_unit` never raises for a
problem of the building itself (bad file, identification failure, a diverging IDA): it returns
a ``failed`` result whose ``reason`` is one line, so the other buildings go on. Ctrl-C
(``KeyboardInterrupt``) is not caught.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import socket
import time
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import _progress
from .._inputs import file_sha256
from .._version import __version__
from ..config import config_to_dict
from ..errors import InputError, one_line
from ..ida import IDAConfig
from ..identify import IdentifyConfig
from ..loss.config import LossConfig
from ..measurement import Measurement
from ..motions import GroundMotion
from .assess import assess_clone, flatten
from .config import FleetConfig, FleetMeasurement, unit_id

RESULT_FORMAT = "hlaid-fleet-unit"
RESULT_VERSION = 1


@dataclass(frozen=True, kw_only=True)
class UnitJob:
    """The work of one (building, event): what a worker needs besides the records."""

    unit: str
    building: str
    event: str
    measurement: FleetMeasurement
    mass_t: list[float] | None
    height_mm: list[float] | None
    identify: IdentifyConfig
    ida: IDAConfig
    n_ensemble: int
    seed: int
    base_dir: str | None
    cache_dir: str | None = None
    task_threads: int = 1
    engine: str = ""
    digest: str = ""
    verbosity: int = 1
    driver_pid: int = 0
    loss: LossConfig | None = None
    earlier: tuple[tuple[str, FleetMeasurement], ...] = ()
    """The building's earlier events ``(event, measurement)``, oldest first (a fleet with
    ``history: true``): the unit's clone is of them and its own event."""


def unit_seed(seed: int, unit: str) -> int:
    """A seed per unit that does not depend on the order of the buildings in the config."""
    return (int(seed) * 1_000_003 + zlib.crc32(unit.encode())) % 2**31


def _resolve(path: str, base_dir: str | None) -> Path:
    p = Path(path)
    return p if p.is_absolute() or base_dir is None else Path(base_dir) / p


def input_files(m: FleetMeasurement, base_dir: str | None) -> list[Path]:
    """The files a measurement is read from (hashed into the unit's digest)."""
    if m.file is not None:
        p = _resolve(m.file, base_dir)
        return sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p]
    if m.station is not None:
        return [_resolve(f, base_dir) for f in m.station.files]
    return []


def _file_digest(p: Path) -> str:
    try:
        return file_sha256(p)
    except InputError:  # missing, unreadable or not a regular file: the worker reports it; the digest says so
        return "missing"


def records_digest(records: Sequence[GroundMotion]) -> str:
    """SHA-256 of the IDA records (names, dt and samples)."""
    h = hashlib.sha256()
    for m in records:
        h.update(f"{m.name}|{m.dt!r}|{m.acc.size}|".encode())
        h.update(np.ascontiguousarray(m.acc, dtype=np.float64).tobytes())
    return h.hexdigest()


def make_jobs(cfg: FleetConfig, base_dir: Path | None, records_sha: str, engine: str, *,
              cache_dir: str | None = None) -> list[UnitJob]:
    """One job per (building, event), each with the digest of everything its result depends on:
    its config (building, measurement, identify, IDA, ensemble, seed), the contents of its input
    files, the IDA records, the assessment engine and the hlaid version."""
    jobs = []
    base = None if base_dir is None else str(base_dir)
    for b, ev in cfg.units():
        m = b.measurements[ev]
        uid = unit_id(b.name, ev)
        names = list(b.measurements)
        earlier = tuple((e, b.measurements[e]) for e in names[:names.index(ev)]) if cfg.history else ()
        job = UnitJob(unit=uid, building=b.name, event=ev, measurement=m, earlier=earlier,
                      mass_t=m.mass_t if m.mass_t is not None else b.mass_t,
                      height_mm=m.height_mm if m.height_mm is not None else b.height_mm,
                      identify=dataclasses.replace(cfg.identify, n_jobs=1), ida=cfg.ida, n_ensemble=cfg.n_ensemble,
                      seed=unit_seed(cfg.seed, uid), base_dir=base, cache_dir=cache_dir,
                      task_threads=cfg.cluster.task_threads, engine=engine, loss=cfg.loss)
        key = {"unit": uid, "measurement": config_to_dict(m), "mass_t": job.mass_t, "height_mm": job.height_mm,
               "identify": config_to_dict(job.identify),
               "ida": config_to_dict(dataclasses.replace(cfg.ida, records=None)),
               "n_ensemble": cfg.n_ensemble, "seed": job.seed, "engine": engine, "hlaid": __version__,
               "loss": None if cfg.loss is None else config_to_dict(cfg.loss),
               "records": records_sha, "files": {str(p): _file_digest(p) for p in input_files(m, base)},
               **({"earlier": [{"event": e, "measurement": config_to_dict(x),
                                "files": {str(p): _file_digest(p) for p in input_files(x, base)}}
                               for e, x in earlier]} if earlier else {})}
        digest = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()
        jobs.append(dataclasses.replace(job, digest=digest, verbosity=_progress.verbosity(), driver_pid=os.getpid()))
    return jobs


def load_unit_measurements(job: UnitJob) -> list[Measurement]:
    """The measurements of a job, oldest first: its building's earlier events (``history: true``)
    and its own, the last; masses and heights applied."""
    earlier = [load_unit_measurement(dataclasses.replace(job, measurement=m, earlier=()),
                                     name=unit_id(job.building, e)) for e, m in job.earlier]
    return [*earlier, load_unit_measurement(job)]


def load_unit_measurement(job: UnitJob, name: str | None = None) -> Measurement:
    """The measurement of a job, masses and heights applied (named ``name``, default the unit)."""
    from ..io.station import read_station
    from ..run.config import MeasurementSource
    from ..run.runner import load_measurement
    m = job.measurement
    base = None if job.base_dir is None else Path(job.base_dir)
    if m.station is not None:
        meas = read_station(m.station, base=base if base is not None else Path("."))
    else:
        src = MeasurementSource(file=m.file, format=m.format, options=m.options, simulate=m.simulate)
        meas = load_measurement(src, base)
    changes: dict[str, Any] = {"name": name or job.unit}  # the clone is named after the unit
    if job.mass_t is not None:
        changes["mass"] = np.asarray(job.mass_t, float)
    if job.height_mm is not None:
        changes["height"] = np.asarray(job.height_mm, float)
    return dataclasses.replace(meas, **changes)


def _one_line(err: BaseException) -> str:
    text = one_line(err)
    return text if isinstance(err, InputError) else f"{type(err).__name__}: {text}"


def unit_loss(clone, own: GroundMotion, a: dict, job: UnitJob) -> dict:
    """FEMA P-58 losses of the event through pelicun, with the assessment's collapse fragility; the
    scalar figures become the ``loss.*`` columns of the fleet table (pelicun's inputs stay on the worker
    only for the time of the assessment)."""
    import tempfile

    from ..loss.assess import assess_losses
    if not (a.get("collapse_median") and a.get("beta")):
        raise InputError("no collapse fragility fitted: the losses need one")
    with tempfile.TemporaryDirectory(prefix="hlaid-loss-") as tmp:
        block = assess_losses(clone, own, collapse=(float(a["collapse_median"]), float(a["beta"])), cfg=job.loss,
                              ida_config=job.ida, n_ensemble=job.n_ensemble if clone.uncertainty is not None else 0,
                              seed=job.seed, folder=tmp, collapse_source="the unit's assessment",
                              base_dir=job.base_dir)
    r = block["recorded"]
    keep = ("repair_cost_median", "repair_cost_band", "repair_cost_ratio_median", "repair_cost_ratio_band",
            "repair_cost_ratio_mean", "repair_time_parallel_median", "repair_time_sequential_median", "p_collapse",
            "p_irreparable", "p_replacement")
    return {**{k: r[k] for k in keep}, "replacement_cost": block["replacement_cost"], "system": block["system"],
            "cost_unit": r["cost_unit"]}


def unit_decision(clone, records: Sequence[GroundMotion], a: dict, job: UnitJob, own: GroundMotion,
                  meas: Measurement) -> tuple[dict, dict]:
    """The unit's decision (:func:`hlaid.run.decide.decide`, the step ``hlaid run`` takes): the
    identified clone's IDA fragility at the event's intensity (the ensemble's band beside it) and
    the clone replaying the event's own motion, its residual drift beside the measured, with the
    identification's and the plausibility flags. Returns its scalar figures (the ``decision.*``
    columns of the fleet table) and the whole decision (the unit's result file)."""
    from ..ida import ida_from_config
    from ..run.decide import decide

    ir = ida_from_config(clone, job.ida, list(records), event_motions=[own])
    ens = {e["name"]: e for e in a.get("events") or () if isinstance(e, dict) and "name" in e}
    n = job.n_ensemble if clone.uncertainty is not None else 0
    d = decide(clone, ir, job.ida, at_hand=[meas], n_ensemble=n, seed=job.seed, ensemble_events=ens)
    at, mine = d.basis.events[-1:] or (None,), d.basis.own_motion[-1:] or (None,)
    err = mine[0].residual_error if mine[0] is not None else None
    return {"p_collapse_fragility_at_im": at[0].p_collapse if at[0] is not None else None,
            "p_collapse_own_motion": mine[0].p_collapse if mine[0] is not None else None,
            "residual_drift_error_max": None if err is None else max(abs(v) for v in err),
            "flags": " | ".join(d.flags), "n_flags": len(d.flags)}, d.to_dict()


def run_unit(job: UnitJob, records: Sequence[GroundMotion], assess: Callable | None = None) -> dict:
    """Assess one building under one event (on a worker); returns the unit's result mapping.

    ``status`` is ``"ok"`` with ``row`` (the table columns), ``assessment``, ``clone`` and
    ``timings``, or ``"failed"`` with ``reason`` (one line) and the ``stage`` it failed in.
    """
    import torch

    from ..events.identify import identify_clone
    t_all = time.perf_counter()
    out = {"format": RESULT_FORMAT, "version": RESULT_VERSION, "unit": job.unit, "building": job.building,
           "event": job.event, "digest": job.digest, "worker": f"{socket.gethostname()}:{os.getpid()}"}
    timings = {}
    stage = "measurement"
    import numba

    saved = torch.get_num_threads(), numba.get_num_threads()
    torch.set_num_threads(job.task_threads)
    # numba.config sets NUMBA_NUM_THREADS at import time (from the environment): not seen by mypy
    numba.set_num_threads(min(job.task_threads, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]
    own_process = os.getpid() != job.driver_pid
    if own_process:  # a worker process: its own messages only with --verbose
        _progress.set_verbosity(2 if job.verbosity >= 2 else 0)
    # CPU seconds: of the worker process (one task at a time; numba's threads included), or of
    # this thread when the workers are threads of the driver (processes: false)
    cpu_time = time.process_time if own_process else time.thread_time
    c_all = cpu_time()

    def clock(name: str, t: float, c: float) -> None:
        timings[f"{name}_s"] = time.perf_counter() - t
        timings[f"{name}_cpu_s"] = cpu_time() - c
    try:
        t, c = time.perf_counter(), cpu_time()
        series = load_unit_measurements(job)
        meas = series[-1]
        clock("measurement", t, c)
        stage = "identify"
        t, c = time.perf_counter(), cpu_time()
        res = identify_clone(series if len(series) > 1 else meas, job.identify, cache_dir=job.cache_dir)
        clock("identify", t, c)
        stage = "assess"
        t, c = time.perf_counter(), cpu_time()
        own = meas.ground_motion(name=f"{job.unit}-own")
        a = assess_clone(res.clone, records, n_ensemble=job.n_ensemble, ida_config=job.ida, own_motion=own,
                         seed=job.seed, assess=assess, engine=job.engine or None)
        a["decision"], decision = unit_decision(res.clone, records, a, job, own, meas)
        clock("assess", t, c)
        if job.loss is not None:
            stage = "loss"
            t, c = time.perf_counter(), cpu_time()
            a["loss"] = unit_loss(res.clone, own, a, job)
            clock("loss", t, c)
    except Exception as err:  # noqa: BLE001 - one building's failure must not stop the fleet
        clock("total", t_all, c_all)
        return {**out, "status": "failed", "stage": stage, "reason": f"{stage}: {_one_line(err)}", "timings": timings}
    finally:
        torch.set_num_threads(saved[0])
        numba.set_num_threads(saved[1])
    clock("total", t_all, c_all)
    b = res.clone.building
    r = np.asarray(res.replay.r_measured, dtype=np.float64)
    row = {"n_stories": b.n_stories, "mass_normalised": bool(res.clone.mass_normalised),
           "T1_s": float(b.periods()[0]),
           "replay_r_min": float(np.nanmin(r)) if r.size else None, **flatten(a)}
    return {**out, "status": "ok", "row": row, "assessment": a, "decision": decision, "clone": res.clone.to_dict(),
            "timings": timings,
            "measurement": {"source": meas.source, "dt_s": meas.dt, "n_samples": meas.n_samples,
                            "n_floors": meas.n_floors}}


__all__ = ["UnitJob", "make_jobs", "run_unit", "unit_decision", "unit_loss", "records_digest", "unit_seed",
           "load_unit_measurement", "load_unit_measurements", "RESULT_FORMAT", "RESULT_VERSION"]
