"""Zero-phase filtering and integration of sampled records.

Every filter is a Butterworth design in second-order sections applied forward and backward
(:func:`scipy.signal.sosfiltfilt`): no phase shift, so filtered force and drift stay in phase,
and the magnitude response is the design's squared (the effective order doubles). All
functions work along the time axis (axis 0 unless ``axis`` says otherwise) of arrays such as
``(time,)`` or ``(time, channel)`` and return arrays of the same shape.

The Nyquist rule
----------------
A corner used for analysis is at most :func:`max_corner` (``0.45 / dt``, i.e. 0.9 x the
Nyquist frequency); :func:`cap_corner` applies the rule. The filter design itself only guards
against unrealisable corners (above 0.95 x Nyquist it designs at 0.95 x Nyquist), so a corner
given explicitly is used as given when it is realisable.

scipy is imported where a filter is designed or applied, so that the rule itself
(:func:`max_corner`) is checked before any heavy library loads.
"""

from __future__ import annotations

import numpy as np

MAX_CORNER_RATIO = 0.45
"""Highest analysis corner as a fraction of the sample rate (0.9 x Nyquist)."""

MIN_CORNER_HZ = 0.001
"""Lowest corner [Hz] hlaid designs a filter at (a period of 1000 s: far below any building's and any
record's content); a lower one, 1e-300 Hz, is refused (the design's initial conditions are singular)."""

MIN_CORNER_RATIO = 1e-6
"""Lowest corner as a fraction of the Nyquist frequency (the same reason at a high sample rate)."""

DESIGN_GUARD = 0.95
"""Fraction of the Nyquist frequency above which a corner cannot be designed and is lowered to it."""

__all__ = ["MAX_CORNER_RATIO", "MIN_CORNER_HZ", "min_corner", "max_corner", "cap_corner", "butter_sos", "bandpass",
           "lowpass", "highpass", "integrate_twice", "content_corner"]

ABOVE_NOISE_DB = 10.0
""":func:`content_corner`: a frequency holds the record's content where its spectrum is at least
this far above the noise floor (the spectrum's level near the Nyquist frequency, where a sensor
records its own noise)."""

BELOW_PEAK_DB = 40.0
""":func:`content_corner`: and no further below the spectrum's peak than this (content 10^4 times
weaker in power than the peak moves no peak response; a record low-passed before it was stored
has a stop band far below its peak, not sensor noise, above its filter's corner)."""


def max_corner(dt: float) -> float:
    """The highest corner [Hz] used for analysis at sample interval ``dt`` [s]: ``0.45 / dt``."""
    return MAX_CORNER_RATIO / dt


def min_corner(dt: float) -> float:
    """The lowest corner [Hz] a filter is designed at, sample interval ``dt`` [s]: a high-pass corner
    of 0 means none; any other corner below this is refused."""
    return max(MIN_CORNER_HZ, MIN_CORNER_RATIO * 0.5 / dt)


def cap_corner(hi_hz: float, dt: float) -> float:
    """``hi_hz`` lowered to :func:`max_corner` when above it (the one Nyquist rule)."""
    return min(hi_hz, max_corner(dt))


def _scipy_signal():
    from scipy import signal

    return signal


def butter_sos(band_hz, dt: float, order: int = 4, kind: str = "bandpass") -> np.ndarray | None:
    """Butterworth second-order sections for the corners ``band_hz = (lo, hi)`` [Hz].

    Parameters
    ----------
    band_hz : (lo, hi) corners [Hz]; ``lo <= 0`` means no high-pass
    dt : sample interval [s]
    order : order of the design (forward-backward filtering doubles it)
    kind : ``"bandpass"`` (a low-pass when ``lo <= 0``) or ``"highpass"`` (at ``lo``)

    Returns
    -------
    (section, 6) array, or None for a high-pass whose corner is 0 (nothing to remove)
    """
    nyq = 0.5 / dt
    lo, hi = band_hz
    hi = min(hi, DESIGN_GUARD * nyq)
    low = min_corner(dt)
    if hi < low or 0 < lo < low:
        from .errors import InputError

        raise InputError(f"band {lo:g}-{hi:g} Hz: a corner below {low:g} Hz cannot be designed; give 0 for no "
                         f"high-pass and a high corner of at least {low:g} Hz")
    if kind == "bandpass" and lo > 0:
        return _scipy_signal().butter(order, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
    if kind == "bandpass":
        return _scipy_signal().butter(order, hi / nyq, btype="lowpass", output="sos")
    if lo <= 0:
        return None
    return _scipy_signal().butter(order, lo / nyq, btype="highpass", output="sos")


def bandpass(x: np.ndarray, dt: float, band_hz, order: int = 4, *, axis: int = 0) -> np.ndarray:
    """Zero-phase band-pass of ``x`` between ``band_hz = (lo, hi)`` [Hz] (a low-pass when ``lo`` is 0)."""
    return _scipy_signal().sosfiltfilt(butter_sos(band_hz, dt, order), x, axis=axis)


def lowpass(x: np.ndarray, dt: float, hi_hz: float, order: int = 4, *, axis: int = 0) -> np.ndarray:
    """Zero-phase low-pass of ``x`` at ``hi_hz`` [Hz]."""
    return bandpass(x, dt, (0.0, hi_hz), order, axis=axis)


def highpass(x: np.ndarray, dt: float, band_hz, order: int = 4) -> np.ndarray:
    """Zero-phase high-pass at ``band_hz[0]`` [Hz] along axis 0; only the mean is removed when
    that corner is 0."""
    sos = butter_sos(band_hz, dt, order, "highpass")
    return x - x.mean(axis=0) if sos is None else _scipy_signal().sosfiltfilt(sos, x, axis=0)


def integrate_twice(acc: np.ndarray, dt: float, band_hz, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and displacement ``(time, channel)`` from a band-passed acceleration.

    Trapezoidal integration, each result high-passed at ``band_hz[0]`` (so the drift that
    integration makes of offsets and noise never accumulates). Returns ``(vel, disp)``.
    """
    from scipy import integrate

    vel = highpass(integrate.cumulative_trapezoid(acc, dx=dt, axis=0, initial=0.0), dt, band_hz, order)
    disp = highpass(integrate.cumulative_trapezoid(vel, dx=dt, axis=0, initial=0.0), dt, band_hz, order)
    return vel, disp


def arias_window(acc: np.ndarray, dt: float, arias, tail_s: float = 2.0, lead_s: float = 1.0) -> tuple[int, int]:
    """Sample range ``[i0, i1)`` from ``lead_s`` before the ``arias[0]`` Arias-intensity
    fraction of ``acc`` to ``tail_s`` after the ``arias[1]`` fraction."""
    e = np.cumsum(np.asarray(acc) ** 2)
    i0 = max(0, int(np.searchsorted(e, arias[0] * e[-1])) - round(lead_s / dt))
    i1 = min(acc.shape[0], int(np.searchsorted(e, arias[1] * e[-1])) + round(tail_s / dt) + 1)
    return i0, i1


def content_corner(x: np.ndarray, dt: float, *, above_noise_db: float = ABOVE_NOISE_DB,
                   below_peak_db: float = BELOW_PEAK_DB) -> float:
    """The highest frequency [Hz] at which the channels ``x`` ``(time,)`` or ``(time, channel)``
    still hold their content: where some channel's spectrum (Welch, segments of about 8 s, the
    log spectrum smoothed by a running median over a sixth of an octave so that one spectral
    line, mains hum say, counts as nothing) stays above both its noise floor by
    ``above_noise_db`` and its peak less ``below_peak_db``. The noise floor of a channel is the
    median of its spectrum over the top eighth of the frequencies below Nyquist. Capped by
    :func:`cap_corner`; 0 where no channel moves."""
    sig = _scipy_signal()
    x = np.asarray(x, dtype=float)
    x = x[:, None] if x.ndim == 1 else x
    n = x.shape[0]
    nper = int(min(n, 2 ** int(np.round(np.log2(max(8.0 / dt, 16.0))))))
    f, P = sig.welch(x - x.mean(axis=0), fs=1.0 / dt, nperseg=nper, axis=0)
    corner = 0.0
    for j in range(P.shape[1]):
        p = P[1:, j]
        fj = f[1:]
        if not np.any(p > 0):
            continue
        logp = np.log10(np.maximum(p, 1e-300 * p.max()))
        smooth = np.array([np.median(logp[(fj >= fk * 2 ** (-1 / 12)) & (fj <= fk * 2 ** (1 / 12))]) for fk in fj])
        noise = float(np.median(smooth[fj >= 0.875 * fj[-1]]))
        level = max(noise + above_noise_db / 10.0, float(smooth.max()) - below_peak_db / 10.0)
        above = np.flatnonzero(smooth >= level)
        if above.size:
            corner = max(corner, float(fj[above[-1]]))
    return cap_corner(corner, dt) if corner > 0 else 0.0

