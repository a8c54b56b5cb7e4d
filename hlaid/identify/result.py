"""What an identification returns."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._inputs import file_sha256
from ..clone import Clone
from ..errors import InputError
from ..hla import HLAResult
from ..measurement import Measurement, ground_digest
from ..model import Building
from ..units import G_MM_S2
from .joint import JointFit
from .replaycheck import ReplayCheck


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Everything an identification produced.

    Attributes
    ----------
    clone : the identified clone (write it with ``clone.save``)
    hla : the hysteresis loop analysis of the measurement
    paper_estimate : the building after regressions + classifiers (before refinement)
    passes : per outer iteration, per story, the classifier passes
    iterations : outer-loop iterations run
    replay : replay of the clone on the measured ground motion
    timings : seconds per step
    refinement : the refinement's final fit (its Jacobian and residuals at the solution give
        ``clone.uncertainty``), None without refinement
    joint : the fit over all events (several records, an elastic one, or a system named), else None
    """

    clone: Clone
    hla: HLAResult
    paper_estimate: Building
    passes: list
    iterations: int
    replay: ReplayCheck
    timings: dict
    refinement: object = None
    joint: JointFit | None = None


def file_digest(path: str) -> str | None:
    """SHA-256 of the file at ``path`` (None where it is not a regular file hlaid reads)."""
    if not Path(path).is_file():
        return None
    try:
        return file_sha256(path)
    except InputError:
        return None


def event_record(meas: Measurement, start: str | None = None) -> dict:
    """What a clone keeps of an event it learnt from (``start``: where its replay started,
    ``"carried"`` or ``"undamaged"``, when an update chose it)."""
    return {"name": meas.name, "source": meas.source or None,
            "sha256": file_digest(meas.source) if meas.source else None, "ground_sha256": ground_digest(meas),
            "pga_g": float(np.max(np.abs(meas.ground_acc)) / G_MM_S2), "duration_s": float(meas.n_samples * meas.dt),
            "dt": float(meas.dt), "n_floors": int(meas.n_floors),
            **({"recorded": meas.recorded} if meas.recorded else {}), **({"start": start} if start else {})}
