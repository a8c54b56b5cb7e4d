"""HLA preprocessing: record-length checks, story differences and the automatic band.

The filters and the double integration are in :mod:`hlaid.signal`: accelerations are
band-passed with a zero-phase Butterworth filter, then integrated twice with the trapezoidal
rule, high-passed again after each integration. Zero-phase filtering keeps force and drift in
phase, which is what makes the force-drift loops meaningful.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from ..errors import InputError
from ..signal import max_corner


def check_record_length(n_samples: int, dt: float, band_hz, order: int, source: str | None) -> None:
    """A record must be long enough for the filters (several periods of the low corner)."""
    padlen = 3 * (2 * 2 * order + 1)
    if n_samples <= padlen:
        raise InputError(f"record has {n_samples} samples; HLA needs more than {padlen} for its filters",
                         source=source)
    lo = band_hz[0]
    if lo > 0 and n_samples * dt < 1.0 / lo:
        raise InputError(f"record lasts {n_samples * dt:.2f} s, shorter than one period of the {lo:g} Hz "
                         "high-pass corner; lower preprocess.band_hz[0] or use a longer record", source=source)


def story_drift(floor: np.ndarray) -> np.ndarray:
    """Inter-story quantity from floor quantities ``(time, floor)``: ``X_i - X_{i-1}``, ``X_0 = 0``."""
    return np.diff(floor, axis=1, prepend=0.0)


def dominant_frequency(ground_acc: np.ndarray, roof_acc: np.ndarray, dt: float) -> float:
    """Frequency [Hz] of the largest peak of the roof's acceleration relative to the ground
    (Welch spectrum, 0.1 Hz to 0.4 x sampling rate): the effective first mode."""
    rel = roof_acc - ground_acc
    nper = int(min(rel.shape[0], max(256, 2 ** int(np.ceil(np.log2(20.0 / dt))))))
    f, p = signal.welch(rel - rel.mean(), fs=1.0 / dt, nperseg=nper)
    band = (f >= 0.1) & (f <= 0.4 / dt)
    if not band.any():
        return 1.0
    return float(f[band][np.argmax(p[band])])


def auto_band(ground_acc: np.ndarray, roof_acc: np.ndarray, dt: float, highpass_ratio: float) -> tuple[float, float]:
    """Band-pass corners chosen from the record (see :class:`~hlaid.hla.PreprocessConfig`)."""
    f1 = dominant_frequency(ground_acc, roof_acc, dt)
    return highpass_ratio * f1, min(max(20.0, 4.0 * f1), max_corner(dt))
