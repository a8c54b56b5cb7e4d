"""Half cycles: the drift history split at its reversals.

A reversal is a turning point of the drift (a zero crossing of the drift velocity). Noise
creates spurious short reversals; a turning point counts only when the drift has moved
back from the running extreme by more than a threshold (peak-valley detection with
hysteresis), so a wiggle smaller than the threshold is merged into the half cycle it
interrupts.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def reversals(x: np.ndarray, threshold: float) -> np.ndarray:
    """Indices of the turning points of ``x`` that are separated by more than ``threshold``.

    Parameters
    ----------
    x : (time,) drift
    threshold : the smallest drift increment between two kept turning points

    Returns
    -------
    (n_reversals,) increasing sample indices of alternating maxima and minima.
    """
    n = x.shape[0]
    out = np.empty(n, dtype=np.int64)
    k = 0
    hi = 0
    lo = 0
    direction = 0  # +1 rising (tracking a max), -1 falling (tracking a min), 0 undecided
    for i in range(1, n):
        if direction >= 0:
            if x[i] > x[hi]:
                hi = i
            if direction == 0 and x[i] < x[lo]:
                lo = i
            if direction == 0:
                if x[hi] - x[lo] > threshold:
                    if hi > lo:  # rose from the minimum: that minimum is a reversal
                        out[k] = lo
                        k += 1
                        direction = 1
                    else:
                        out[k] = hi
                        k += 1
                        direction = -1
                        lo = i
                continue
            if x[hi] - x[i] > threshold:
                out[k] = hi
                k += 1
                direction = -1
                lo = i
        else:
            if x[i] < x[lo]:
                lo = i
            if x[i] - x[lo] > threshold:
                out[k] = lo
                k += 1
                direction = 1
                hi = i
    return out[:k]


def half_cycle_bounds(x: np.ndarray, threshold: float) -> np.ndarray:
    """``(n_half_cycles, 2)`` start and end sample index (inclusive) of every complete half cycle.

    A half cycle runs from one reversal to the next; the parts before the first and after
    the last reversal are not complete half cycles and are left out.
    """
    r = reversals(np.ascontiguousarray(x, dtype=np.float64), float(threshold))
    r = r[(r > 0) & (r < x.shape[0] - 1)]  # the ends of the record are not turning points
    if r.size < 2:
        return np.zeros((0, 2), dtype=np.int64)
    return np.stack([r[:-1], r[1:]], axis=1)
