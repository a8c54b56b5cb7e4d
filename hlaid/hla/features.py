"""Half-cycle shape features for the alpha/p classifiers (eq 18).

Each yielding half cycle is cut into ``n`` segments of equal drift increment from its
reversal; in segment ``i`` the feature is ``v_i = (ke - k_i) / k0``, with ``k_i`` the
least-squares slope of the (band-passed) force on the drift over that segment and ``ke``
the half cycle's elastic stiffness. Measured and simulated training data go through this
same function.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .result import StoryHLA
from .stiffness import segment_slopes


@dataclass(frozen=True)
class HalfCycleFeatures:
    """Features of the selected half cycles of one story.

    Attributes
    ----------
    values : (half_cycle, segment) features ``(ke - k_i) / k0``
    slopes : (half_cycle, segment) segment slopes ``k_i`` [N/mm]
    index : (half_cycle,) rows of the story's half-cycle table that were selected

    With ``with_ke`` the values get one more column, ``ke / k0`` of the half cycle: the
    plateau of ``v`` is ``ke/k0 - alpha``, so the degradation must be known to read alpha.
    """

    values: np.ndarray
    slopes: np.ndarray
    index: np.ndarray

    def __len__(self) -> int:
        return int(self.index.shape[0])


def half_cycle_features(story: StoryHLA, n_segments: int = 10, *, yield_ratio: float = 0.6,
                        min_increment: float = 0.0, with_ke: bool = False) -> HalfCycleFeatures:
    """Features of the half cycles in which the story yields.

    A half cycle is selected when the slope of its last segment falls below
    ``yield_ratio * ke`` (it reached the plastic branch) and its drift increment is at least
    ``min_increment`` times the largest one.

    Returns
    -------
    HalfCycleFeatures with ``(half_cycle, n_segments)`` arrays.
    """
    hc = story.half_cycles
    rows, slopes, idx = [], [], []
    big = hc.drift_increment.max() if len(hc) else 0.0
    for j in range(len(hc)):
        if hc.drift_increment[j] < min_increment * big:
            continue
        ke = hc.ke[j]
        k = segment_slopes(story.drift, story.force_fit, int(hc.start[j]), int(hc.end[j]), n_segments)
        if not np.all(np.isfinite(k)) or not np.isfinite(ke) or k[-1] >= yield_ratio * ke:
            continue
        v = (ke - k) / story.k0
        rows.append(np.append(v, ke / story.k0) if with_ke else v)
        slopes.append(k)
        idx.append(j)
    shape = (len(rows), n_segments)
    return HalfCycleFeatures(values=np.asarray(rows, dtype=float).reshape(len(rows), n_segments + with_ke),
                             slopes=np.asarray(slopes, dtype=float).reshape(shape), index=np.asarray(idx, dtype=int))

