"""Run a clone's OpenSees model in-process: one record (:func:`run_opensees`) or a batch of jobs
on worker processes (:func:`run_opensees_batch`, the benchmarks' peer).

Both call :func:`hlaid.opensees.standalone.analyze`, the code the exported script runs, with
the data the script holds (:func:`hlaid.opensees.script.model_data`): tests and benchmarks
therefore check exactly what users get.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..motions import GroundMotion
from .script import model_data
from .standalone import analyze

__all__ = ["OpenSeesResult", "OpenSeesUnavailable", "import_opensees", "run_opensees", "run_opensees_batch"]


class OpenSeesUnavailable(InputError):
    """openseespy cannot be imported (not installed, or its native libraries are missing)."""


def import_opensees():
    """``openseespy.opensees``, or :class:`OpenSeesUnavailable` with the reason."""
    try:
        import openseespy.opensees as ops
    except (ImportError, RuntimeError, OSError) as err:
        raise OpenSeesUnavailable(f"openseespy is not usable ({type(err).__name__}: {err}); install it with "
                                  "pip install openseespy==3.5.1.12 (Python 3.11)") from None
    return ops


@dataclass(frozen=True, eq=False)
class OpenSeesResult:
    """Response of one OpenSees run.

    Attributes
    ----------
    peak_drift : (story,) peak |drift| over every analysis step [mm]
    residual_drift : (story,) drift at the end [mm]
    ok : the analysis converged to the end of the record
    time_reached : analysis time reached [s]
    drift : (time, story) drift at the record's samples [mm], with ``histories=True``
    dt : sample interval of ``drift`` [s]
    """

    peak_drift: np.ndarray
    residual_drift: np.ndarray
    ok: bool
    time_reached: float
    drift: np.ndarray | None
    dt: float


def run_opensees(model, motion: GroundMotion, *, scale: float = 1.0, dt_factor: int = 10,
                 histories: bool = False) -> OpenSeesResult:
    """Run the exported script's model in-process under ``motion`` x ``scale``.

    Parameters
    ----------
    model : Clone, Building or clone file
    motion : ground acceleration [mm/s^2]
    dt_factor : analysis steps per record sample (``dt / dt_factor``)
    histories : also return the drift at every record sample (slower: steps in Python)
    """
    if int(dt_factor) < 1:
        raise InputError(f"dt_factor = {dt_factor}; expected an integer >= 1")
    ops = import_opensees()
    out = analyze(ops, model_data(model), np.asarray(motion.acc) * float(scale), motion.dt, int(dt_factor),
                  histories)
    return OpenSeesResult(peak_drift=np.asarray(out["peak_drift"]), residual_drift=np.asarray(out["residual_drift"]),
                          ok=bool(out["ok"]), time_reached=float(out["time"]),
                          drift=None if out.get("drift") is None else np.asarray(out["drift"]), dt=motion.dt)


def _opensees_chunk(args):
    building, jobs, dt_factor = args
    out = []
    for gm, s in jobs:
        r = run_opensees(building, gm, scale=s, dt_factor=dt_factor)
        out.append(r.peak_drift if r.ok else np.full(len(r.peak_drift), np.nan))
    return out


def run_opensees_batch(model, jobs, *, dt_factor: int = 10, workers: int = 2):
    """Run ``jobs`` (``(motion, scale)`` pairs) in OpenSees on ``workers`` processes (benchmarks).

    Returns ``(wall [s], CPU of the worker processes [s], peak drifts (job, story))``; NaN rows
    where OpenSees failed to converge.
    """
    import resource
    import time
    from concurrent.futures import ProcessPoolExecutor

    def children_cpu():
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    import_opensees()
    chunks = [jobs[i::workers] for i in range(workers)]
    t0, c0 = time.perf_counter(), children_cpu()
    with ProcessPoolExecutor(workers) as ex:
        parts = list(ex.map(_opensees_chunk, [(model, c, dt_factor) for c in chunks]))
    wall, cpu = time.perf_counter() - t0, children_cpu() - c0
    out = [None] * len(jobs)
    for w, part in enumerate(parts):
        for k, pk in enumerate(part):
            out[w + k * workers] = pk
    return wall, cpu, np.array(out)
