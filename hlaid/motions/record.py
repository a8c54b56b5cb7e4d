"""Ground motion records."""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction

import numpy as np

from ..errors import InputError
from ..limits import check_count
from ..units import G_MM_S2

MIN_SAMPLES = 8


@dataclass(frozen=True, eq=False)
class GroundMotion:
    """A uniformly sampled ground acceleration record.

    Attributes
    ----------
    dt : sample interval [s]
    acc : (time,) ground acceleration [mm/s^2]
    name : short label, e.g. ``"elcentro-1940-ns"``
    source : where it came from (file path or ``builtin:NAME``), used in error messages
    """

    dt: float
    acc: np.ndarray
    name: str = ""
    source: str = ""

    def __post_init__(self):
        src = self.source or self.name or None
        try:
            dt = float(self.dt)
        except (TypeError, ValueError):
            raise InputError(f"dt must be a number, got {self.dt!r}", source=src) from None
        if not np.isfinite(dt) or dt <= 0:
            raise InputError(f"dt = {self.dt} s; expected a positive sample interval", source=src)
        if np.iscomplexobj(self.acc):
            raise InputError("acceleration holds complex numbers; expected real values", source=src)
        acc = np.array(self.acc, dtype=np.float64)
        if acc.ndim != 1:
            raise InputError(f"acceleration must be one channel (time,), got shape {acc.shape}", source=src)
        if acc.shape[0] < MIN_SAMPLES:
            raise InputError(f"record has {acc.shape[0]} samples; expected at least {MIN_SAMPLES}", source=src)
        check_count(acc.shape[0], "SAMPLES", "samples", source=src)
        bad = ~np.isfinite(acc)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(f"acceleration has {int(bad.sum())} NaN or inf samples (first at sample {i}, "
                             f"t = {i * dt:g} s)", source=src)
        acc.setflags(write=False)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "acc", acc)

    # ------------------------------------------------------------------ properties
    @property
    def npts(self) -> int:
        return int(self.acc.shape[0])

    @property
    def duration(self) -> float:
        """Record length [s]."""
        return (self.npts - 1) * self.dt

    @property
    def time(self) -> np.ndarray:
        """Sample times [s], ``(time,)``."""
        return np.arange(self.npts) * self.dt

    @property
    def pga(self) -> float:
        """Peak ground acceleration [mm/s^2]."""
        return float(np.max(np.abs(self.acc)))

    @property
    def pga_g(self) -> float:
        """Peak ground acceleration [g]."""
        return self.pga / G_MM_S2

    # ------------------------------------------------------------------ transformations
    def scaled(self, factor: float) -> GroundMotion:
        """The record multiplied by ``factor``."""
        return replace(self, acc=self.acc * float(factor))

    def scaled_to_pga(self, pga_g: float) -> GroundMotion:
        """The record scaled so that its PGA is ``pga_g`` [g]."""
        if not pga_g > 0:
            raise InputError(f"target PGA = {pga_g} g; expected a positive value", source=self.source or None)
        if self.pga == 0.0:
            raise InputError("the record is all zeros; it cannot be scaled to a PGA", source=self.source or None)
        return self.scaled(pga_g * G_MM_S2 / self.pga)

    def resampled(self, rate_hz: float) -> GroundMotion:
        """The record at ``rate_hz`` samples per second.

        Uses polyphase resampling (:func:`scipy.signal.resample_poly`), whose FIR low-pass
        removes content above the new Nyquist frequency before decimation (anti-aliasing)
        and interpolates band-limited when upsampling.
        """
        if not rate_hz > 0:
            raise InputError(f"rate = {rate_hz} Hz; expected a positive rate", source=self.source or None)
        ratio = Fraction(self.dt * rate_hz).limit_denominator(1000)
        check_count(int(self.npts * ratio), "SAMPLES", f"samples at {rate_hz:g} Hz", source=self.source or None)
        if ratio == 1:
            return replace(self, dt=1.0 / rate_hz)
        up, down = ratio.numerator, ratio.denominator
        from scipy import signal  # imported where a record is resampled, not where one is read
        acc = signal.resample_poly(self.acc, up, down)
        return replace(self, dt=1.0 / rate_hz, acc=acc)

    def padded(self, seconds: float) -> GroundMotion:
        """The record followed by ``seconds`` of zeros (free vibration)."""
        n = int(round(seconds / self.dt))
        return replace(self, acc=np.concatenate([self.acc, np.zeros(max(n, 0))])) if n > 0 else self

    def __repr__(self) -> str:
        return (f"GroundMotion(name={self.name!r}, dt={self.dt:g}, npts={self.npts}, "
                f"duration={self.duration:.2f} s, pga={self.pga_g:.3f} g)")
