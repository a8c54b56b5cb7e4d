"""Shared pieces of the data readers: numeric tables, time axes, offsets, derivatives.

Everything here works in the units it is given; the readers convert to N, mm, t, s.
Errors are :class:`~hlaid.errors.InputError` naming the file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, column_label, columns_text

_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)", re.I)

JITTER_FRACTION = 0.05
"""Time stamps within this fraction of dt of a uniform grid are rounded stamps of uniform
samples: the values are kept as they are (no interpolation)."""


@dataclass(frozen=True)
class Table:
    """A numeric table read from text: column ``names`` and ``data`` of shape ``(row, column)``."""

    names: list[str]
    data: np.ndarray

    def column(self, key: str | int, source: str) -> np.ndarray:
        """One column by name (case-sensitive first, then case-insensitive) or 0-based index."""
        return self.data[:, self.index(key, source)]

    def index(self, key: str | int, source: str) -> int:
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            if not 0 <= int(key) < len(self.names):
                raise InputError(f"column index {key} is out of range; the file has {len(self.names)} columns "
                                 f"(0..{len(self.names) - 1})", source=source)
            return int(key)
        key = str(key)
        if key in self.names:
            return self.names.index(key)
        low = [n.lower() for n in self.names]
        if key.lower() in low:
            return low.index(key.lower())
        raise InputError(f"no column {key!r}; columns are {columns_text(self.names)}", source=source)


def split_row(line: str, delimiter: str | None) -> list[str]:
    """Fields of one line: ``delimiter`` None splits on any whitespace."""
    if delimiter is None:
        return line.split()
    return [f.strip() for f in line.split(delimiter)]


def parse_table(text: str, source: str, *, delimiter: str | None, comment: str = "#",
                header: bool = True, min_rows: int = 2) -> Table:
    """Parse a delimited numeric table with an optional header row.

    Parameters
    ----------
    text : the file's text
    source : file name for error messages
    delimiter : field separator, or None for any whitespace
    comment : lines starting with this (after blanks) are skipped
    header : whether the first non-comment line names the columns (else ``col0, col1, ...``)
    min_rows : fewest data rows accepted
    """
    lines = [ln for ln in text.splitlines() if ln.strip() and not (comment and ln.lstrip().startswith(comment))]
    if not lines:
        raise InputError("holds no data lines", source=source)
    if header:
        names = split_row(lines[0], delimiter)
        if all(_NUM.fullmatch(n) for n in names if n):
            raise InputError("the first data line should name the columns but holds numbers (give header: false "
                             "when the file has no header row)", source=source)
        body = lines[1:]
        first = 2
    else:
        body = lines
        names = [f"col{i}" for i in range(len(split_row(lines[0], delimiter)))]
        first = 1
    if len(body) < min_rows:
        raise InputError(f"has {len(body)} data rows; expected at least {min_rows}", source=source)
    ncol = len(names)
    rows = [split_row(ln, delimiter) for ln in body]
    for i, r in enumerate(rows):
        if len(r) != ncol:
            raise InputError(f"data row {i + first} has {len(r)} fields but there are {ncol} columns", source=source)
    try:
        data = np.array(rows, dtype=np.float64)
    except ValueError:
        for i, r in enumerate(rows):
            for j, v in enumerate(r):
                if not _NUM.fullmatch(v.strip()):
                    raise InputError(f"non-numeric value in data row {i + first}, {column_label(names, j)}",
                                     source=source) from None
        raise InputError("has a value that is not a number", source=source) from None
    bad = ~np.isfinite(data)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(f"NaN or inf in data row {i + first}, {column_label(names, j)}", source=source)
    return Table(names=names, data=data)


@dataclass(frozen=True)
class TimeAxis:
    """How a time column was turned into a uniform sample interval.

    Attributes
    ----------
    dt : uniform sample interval [s]
    t0 : time of the first sample [s]
    jitter : largest distance of a time stamp from the uniform grid [s]
    resampled : True when the values were interpolated onto the grid
    """

    dt: float
    t0: float
    jitter: float
    resampled: bool


def uniform_time(t: np.ndarray, values: np.ndarray, source: str, *, column: str = "time"
                 ) -> tuple[TimeAxis, np.ndarray]:
    """Put samples recorded at times ``t`` on a uniform grid.

    When every stamp lies within ``JITTER_FRACTION * dt`` of the straight line through the
    first and last stamps, the stamps are rounded versions of uniform times (as in files
    that print time to 4 decimals) and the values are kept; ``dt = (t[-1] - t[0]) / (n - 1)``.
    Otherwise the values are linearly interpolated onto a grid with the median step.

    Parameters
    ----------
    t : (time,) sample times [s], strictly increasing
    values : (time, ...) samples
    """
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.size < 3:
        raise InputError(f"{column} column needs at least 3 samples", source=source)
    step = np.diff(t)
    if not np.all(step > 0):
        i = int(np.argmax(step <= 0))
        raise InputError(f"{column} column does not increase at row {i + 2} ({t[i]:g} then {t[i + 1]:g} s)",
                         source=source)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    jitter = float(np.max(np.abs(t - (t[0] + dt * np.arange(t.size)))))
    if jitter <= JITTER_FRACTION * dt:
        return TimeAxis(dt=dt, t0=float(t[0]), jitter=jitter, resampled=False), values
    dt = float(np.median(step))
    n = int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
    grid = t[0] + dt * np.arange(n)
    flat = values.reshape(values.shape[0], -1)
    out = np.stack([np.interp(grid, t, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    return TimeAxis(dt=dt, t0=float(t[0]), jitter=jitter, resampled=True), out.reshape((n,) + values.shape[1:])


def pre_event_mean(x: np.ndarray, dt: float, seconds: float, source: str) -> np.ndarray:
    """Mean of the first ``seconds`` of each channel (the static bias before the event).

    Parameters
    ----------
    x : (time, channel) or (time,) samples
    """
    n = int(round(seconds / dt))
    if seconds <= 0 or n < 1:
        raise InputError(f"pre-event window of {seconds} s holds no samples (dt = {dt:g} s)", source=source)
    if n > x.shape[0] // 2:
        raise InputError(f"pre-event window of {seconds} s is more than half the record "
                         f"({x.shape[0] * dt:.3g} s)", source=source)
    return x[:n].mean(axis=0)


def remove_offset(values: np.ndarray, dt: float, mode: str, pre_event_s: float, source: str
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (time, channel) less each channel's static offset, and the offsets (channel,).

    ``mode``: ``"mean"`` (the whole record's mean), ``"pre-event"`` (the mean of the first
    ``pre_event_s`` seconds, :func:`pre_event_mean`) or anything else (none removed).
    """
    if mode == "mean":
        bias = values.mean(axis=0)
    elif mode == "pre-event":
        bias = pre_event_mean(values, dt, pre_event_s, source)
    else:
        bias = np.zeros(values.shape[1])
    return values - bias, bias


def second_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """Second time derivative by the 3-point central stencil along axis 0.

    The stencil's gain at frequency f is ``sinc^2(f dt)`` (numpy sinc), within 1% of exact
    below ``0.055 / dt`` (14 Hz at 256 Hz sampling). The end samples copy their neighbours.
    """
    a = np.empty_like(x, dtype=np.float64)
    a[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt**2
    a[0] = a[1]
    a[-1] = a[-2]
    return a


def spectral_second_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """Second time derivative by FFT (exact for a band-limited record that starts and ends at rest).

    The record is mirrored before the transform so its periodic extension has no jump.
    """
    n = x.shape[0]
    ext = np.concatenate([x, x[::-1]], axis=0)
    w = 2 * np.pi * np.fft.rfftfreq(ext.shape[0], dt)
    shape = (-1,) + (1,) * (x.ndim - 1)
    spec = np.fft.rfft(ext, axis=0) * (-(w**2)).reshape(shape)
    return np.fft.irfft(spec, ext.shape[0], axis=0)[:n]
