"""Filtering and integration of accelerations into drift and drift velocity.

Accelerations are band-passed with a zero-phase Butterworth filter (``sosfiltfilt``), then
integrated twice with the trapezoidal rule; the high-pass is applied again after each
integration, so the low-frequency drift that integration creates from sensor offsets and
noise never accumulates. Zero-phase filtering keeps force and drift in phase, which is what
makes the force-drift loops meaningful.
"""

from __future__ import annotations

import numpy as np
from scipy import integrate, signal

from ..errors import InputError


def _sos(band_hz, order, dt, kind):
    nyq = 0.5 / dt
    lo, hi = band_hz
    hi = min(hi, 0.95 * nyq)
    if kind == "bandpass" and lo > 0:
        return signal.butter(order, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
    if kind == "bandpass":
        return signal.butter(order, hi / nyq, btype="lowpass", output="sos")
    if lo <= 0:
        return None
    return signal.butter(order, lo / nyq, btype="highpass", output="sos")


def bandpass(x: np.ndarray, dt: float, band_hz, order: int = 4) -> np.ndarray:
    """Zero-phase band-pass along axis 0 of ``x`` ``(time, ...)``."""
    return signal.sosfiltfilt(_sos(band_hz, order, dt, "bandpass"), x, axis=0)


def highpass(x: np.ndarray, dt: float, band_hz, order: int = 4) -> np.ndarray:
    """Zero-phase high-pass at ``band_hz[0]`` along axis 0 (identity when the corner is 0)."""
    sos = _sos(band_hz, order, dt, "highpass")
    return x - x.mean(axis=0) if sos is None else signal.sosfiltfilt(sos, x, axis=0)


def integrate_twice(acc: np.ndarray, dt: float, band_hz, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and displacement from band-passed acceleration ``(time, channel)``.

    Returns ``(vel, disp)``, each high-passed after integration.
    """
    vel = highpass(integrate.cumulative_trapezoid(acc, dx=dt, axis=0, initial=0.0), dt, band_hz, order)
    disp = highpass(integrate.cumulative_trapezoid(vel, dx=dt, axis=0, initial=0.0), dt, band_hz, order)
    return vel, disp


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
    return highpass_ratio * f1, min(max(20.0, 4.0 * f1), 0.45 / dt)
