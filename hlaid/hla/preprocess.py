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
from ..signal import bandpass, cap_corner, integrate_twice, max_corner


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
    return _spectral_peak(roof_acc - ground_acc, dt)


def _spectral_peak(x: np.ndarray, dt: float) -> float:
    """Frequency [Hz] of the largest peak of the Welch spectrum of ``x`` ``(time,)`` between 0.1 Hz
    and 0.4 x the sampling rate (1 Hz where that range holds no bin)."""
    nper = int(min(x.shape[0], max(256, 2 ** int(np.ceil(np.log2(20.0 / dt))))))
    f, p = signal.welch(x - x.mean(), fs=1.0 / dt, nperseg=nper)
    band = (f >= 0.1) & (f <= 0.4 / dt)
    if not band.any():
        return 1.0
    return float(f[band][np.argmax(p[band])])


DISP_PEAK_RATIO = 0.4
"""Where the roof's measured displacement spectrum peaks below this fraction of its relative
acceleration's, the displacement's peak is the first mode: under an isolation layer the relative
acceleration peaks at the ground motion's own frequency (1.5-4.5 Hz on simulated isolated
buildings), the displacement at the isolation mode (0.3-0.5 Hz: ratios 0.08-0.32 whenever the
isolator yields); 0.55-1.0 on the hotel's 21 records, 0.64-1.0 on simulated yielding frames,
0.78-0.98 on the steel frame."""


def displacement_peak(roof_disp: np.ndarray, dt: float) -> float:
    """Frequency [Hz] of the largest peak of the roof's displacement relative to the ground
    (Welch spectrum, 0.1 Hz to 0.4 x sampling rate)."""
    return _spectral_peak(np.asarray(roof_disp, dtype=float), dt)


def first_mode(ground_acc: np.ndarray, roof_acc: np.ndarray, dt: float, roof_disp: np.ndarray | None = None) -> float:
    """The record's first mode [Hz]: the dominant frequency of the roof's relative acceleration
    (:func:`dominant_frequency`), or the peak of its measured relative displacement where that lies
    below :data:`DISP_PEAK_RATIO` of it (an isolation mode the acceleration does not show)."""
    f1 = dominant_frequency(ground_acc, roof_acc, dt)
    if roof_disp is not None:
        fd = displacement_peak(roof_disp, dt)
        if fd < DISP_PEAK_RATIO * f1:
            return fd
    return f1


def auto_band(ground_acc: np.ndarray, roof_acc: np.ndarray, dt: float, highpass_ratio: float,
              roof_disp: np.ndarray | None = None) -> tuple[float, float]:
    """Band-pass corners chosen from the record (see :class:`~hlaid.hla.PreprocessConfig`): the
    low corner ``highpass_ratio`` times the first mode (:func:`first_mode`, from the roof's
    measured displacement ``roof_disp`` where it shows one far below the acceleration's), the
    high corner ``max(20 Hz, 4 f)`` of the acceleration's dominant frequency ``f``."""
    f = dominant_frequency(ground_acc, roof_acc, dt)
    f1 = first_mode(ground_acc, roof_acc, dt, roof_disp)
    return highpass_ratio * f1, min(max(20.0, 4.0 * f), max_corner(dt))


def drift_agreement(floor_disp: np.ndarray, floor_acc: np.ndarray, ground_acc: np.ndarray, dt: float, band_hz,
                    order: int = 4) -> np.ndarray:
    """``(story,)`` correlation of each story's drift from the measured floor displacements
    ``(time, floor)`` with its drift from the integrated absolute accelerations less the
    ground's, both band-passed in ``band_hz``: near 1 where the displacement sensors resolve the
    story's drift, low where their noise (which scales with the floor's whole motion) buries it."""
    band = (float(band_hz[0]), cap_corner(float(band_hz[1]), dt))
    d = bandpass(np.asarray(floor_disp, dtype=float), dt, band, order)
    a = bandpass(np.asarray(floor_acc, dtype=float), dt, band, order)
    g = bandpass(np.asarray(ground_acc, dtype=float), dt, band, order)
    _, di = integrate_twice(a - g[:, None], dt, band, order)
    xm, xi = story_drift(d), story_drift(di)
    xm, xi = xm - xm.mean(axis=0), xi - xi.mean(axis=0)
    den = np.sqrt(np.sum(xm**2, axis=0) * np.sum(xi**2, axis=0))
    return np.where(den > 0, np.sum(xm * xi, axis=0) / np.maximum(den, 1e-300), 0.0)
