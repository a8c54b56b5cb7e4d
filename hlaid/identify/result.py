"""What an identification returns."""

from __future__ import annotations

import datetime
from dataclasses import dataclass
from pathlib import Path

from .._inputs import file_sha256
from .._version import __version__
from ..clone import Clone
from ..errors import InputError
from ..hla import HLAResult
from ..model import Building
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
    joint : the fit over all events (:class:`hlaid.joint.fit.JointFit`: several records, or an
        elastic one), else None
    """

    clone: Clone
    hla: HLAResult
    paper_estimate: Building
    passes: list
    iterations: int
    replay: ReplayCheck
    timings: dict
    refinement: object = None
    joint: object = None


def file_digest(path: str) -> str | None:
    """SHA-256 of the file at ``path`` (None where it is not a regular file hlaid reads)."""
    if not Path(path).is_file():
        return None
    try:
        return file_sha256(path)
    except InputError:
        return None


def provenance(timings: dict, **sources) -> dict:
    """What a clone keeps of how it was made: its ``sources`` (file names, digests), the hlaid
    version, the seconds of each stage and the time it was made (its settings are
    :attr:`hlaid.clone.Clone.settings`)."""
    return {**sources, "hlaid_version": __version__, "timings": timings,
            "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
