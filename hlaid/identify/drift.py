"""Drift paths for the path-driven training sets.

HLA's drift is the doubly integrated, high-passed relative acceleration: right above the
high-pass corner, wrong below it (the plastic offsets of the drift are filtered away, and
the integrated sensor noise concentrates just above the corner). A story law driven along
it drifts away from the measured force, so the drift path for the training sets is
reconstructed from two sources that are each good where the other is not
(a complementary filter):

    x = HP_c(x_HLA) + LP_c(x_model)

``x_model`` is the drift of the current building estimate replayed on the measured ground
motion (the low-frequency drift the model says the loops close at), ``HP_c`` and ``LP_c =
1 - HP_c`` a zero-phase Butterworth pair at the crossover ``c`` (default 1 Hz: above the
band where HLA's drift is wrong, below the band that carries the loops' shape).
Measured figures: ``scripts/study_drift.py`` and docs/identification.md.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..hla import HLAResult
from ..model import Building
from ..motions import GroundMotion
from ..signal import highpass, max_corner
from ..simulate import simulate_response

__all__ = ["hla_drift", "reconstruct_drift"]


def hla_drift(res: HLAResult) -> np.ndarray:
    """HLA's drift of every story, ``(time, story)`` [mm]."""
    return np.stack([s.drift for s in res.stories], axis=1)


def reconstruct_drift(res: HLAResult, ground: GroundMotion, building: Building | None, *,
                      crossover_hz: float = 1.0, order: int = 4) -> np.ndarray:
    """Drift path of every story, ``(time, story)`` [mm].

    Parameters
    ----------
    res : HLA of the measurement (its drift is the high-frequency part)
    ground : the measured ground motion (low-passed), the excitation of the replay
    building : the current estimate; None (or a replay that diverges): HLA's drift
    crossover_hz : the complementary filters' corner [Hz]
    """
    if not 0 < crossover_hz < max_corner(res.dt):
        raise InputError(f"crossover_hz = {crossover_hz:g} Hz; expected a frequency below 0.45 x the sampling rate "
                         f"({max_corner(res.dt):g} Hz)", source=res.source)
    x = hla_drift(res)
    if building is None:
        return x
    r = simulate_response(building, ground, substeps=4)
    if r.status[0] != 0:
        return x
    assert r.drift is not None  # simulate keeps the histories by default
    xm = r.drift[0][: x.shape[0]]
    return highpass(x - xm, res.dt, (crossover_hz, np.inf), order) + xm
