"""Reader for the 3-story steel moment-frame shake-table records (``filtered_fbgm152s*_denoised``).

Tab-separated text (optionally gzipped), ``#`` comment lines, a header row. Columns used:

- ``Time`` [s]: printed to 4 decimals. The samples are uniform at 256 Hz (every stamp is
  within 5e-5 s of ``i / 256``); the apparent 0.0039/0.0040 s steps are rounding, so the
  values are kept and ``dt = (t[-1] - t[0]) / (n - 1)`` (see :func:`hlaid.io._common.uniform_time`;
  a truly irregular time column is interpolated onto a uniform grid).
- ``aextx`` [g]: measured table acceleration -> ``ground_acc``.
- ``s2``..``s5`` [in]: lab-frame (absolute) displacements; ``s2`` is the table, ``s3..s5``
  floors 1..3 bottom to top (established in ``docs/data.md``: the second derivative of ``s2``
  matches ``aextx`` with gain 1.0 and phase 0 over 0.2-8 Hz; ``s_j/s2 -> 1`` at low frequency
  and the amplitudes grow ``s3 < s4 < s5`` at the first mode).

The file's ``Vs*`` and ``ACCs*`` columns are *derived* by the data's authors from the
displacements with heavy smoothing (``ACCs = d(Vs)/dt / 386.07``; 99% of their power lies below
1.6 Hz) and are not measured accelerations: they are ignored. The absolute floor
accelerations are instead the second derivative of the floor displacements after a zero-phase
low-pass (default 10 Hz: above about 9 Hz the displacement sensors no longer follow the
table accelerometer, coherence < 0.75).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._inputs import DATA_LINES, read_text
from ..errors import InputError
from ..measurement import Measurement
from ..units import G_MM_S2, INCH_MM
from ._common import parse_table, pre_event_mean, second_derivative, uniform_time

TIME = "Time"
TABLE_ACC = "aextx"


def _level_columns(names: list[str]) -> list[str]:
    levels = [n for n in names if re.fullmatch(r"s\d+", n)]
    return sorted(levels, key=lambda n: int(n[1:]))


def read_steel_frame(path: str | os.PathLike, *, lowpass_hz: float | None = 10.0, zero_start: bool = True,
                     pre_event_s: float = 2.0, base: str | None = None, name: str | None = None) -> Measurement:
    """Read one steel-frame shake-table run as a :class:`~hlaid.measurement.Measurement`.

    Parameters
    ----------
    path : ``.tsv`` or ``.tsv.gz`` file with columns ``Time, aextx, s2..s5``
    lowpass_hz : zero-phase low-pass corner [Hz] applied to the floor displacements before
        differentiating them into accelerations (None: no filter)
    zero_start : subtract the pre-event mean of each relative floor displacement, so the
        record starts from rest (the runs start with offsets of up to 2 in at the roof left
        by earlier runs); the removed offsets are kept in ``extra["initial_offset_mm"]``
    pre_event_s : length of the pre-event window [s] (shaking starts after about 8 s)
    base : the table displacement column (default: the lowest-numbered ``s`` column)
    name : measurement name (default: the file name without extensions)

    Returns
    -------
    Measurement
        ``ground_acc`` (time,) = table acceleration [mm/s^2]; ``floor_acc`` (time, 3) absolute
        floor accelerations [mm/s^2] derived from the displacements; ``floor_disp`` (time, 3)
        floor displacements relative to the table [mm]; ``mass`` None. ``extra`` holds
        ``table_disp_mm`` (time,), ``initial_offset_mm`` (3,), ``time_jitter_s``,
        ``resampled``, ``lowpass_hz`` and ``columns``.
    """
    src = str(path)
    table = parse_table(read_text(path, max_lines=DATA_LINES), src, delimiter="\t", comment="#")
    for col in (TIME, TABLE_ACC):
        table.index(col, src)
    levels = _level_columns(table.names)
    if base is not None:
        table.index(base, src)
        levels = [base] + [c for c in levels if c != base]
    if len(levels) < 2:
        raise InputError(f"needs a table displacement column and at least one floor column (s2, s3, ...); "
                         f"columns are {', '.join(table.names)}", source=src)
    cols = [TABLE_ACC] + levels
    axis, values = uniform_time(table.column(TIME, src), table.data[:, [table.index(c, src) for c in cols]], src,
                                column=TIME)
    dt = axis.dt
    ground = values[:, 0] * G_MM_S2
    disp = values[:, 1:] * INCH_MM                      # lab frame, mm
    rel = disp[:, 1:] - disp[:, :1]
    offset = pre_event_mean(rel, dt, pre_event_s, src) if zero_start else np.zeros(rel.shape[1])
    smooth = disp[:, 1:] if lowpass_hz is None else _lowpass(disp[:, 1:], dt, lowpass_hz, src)
    floor_acc = second_derivative(smooth, dt)
    extra = {"table_disp_mm": disp[:, 0], "initial_offset_mm": offset, "time_jitter_s": axis.jitter,
             "resampled": axis.resampled, "lowpass_hz": lowpass_hz, "columns": cols}
    return Measurement(dt=dt, ground_acc=ground, floor_acc=floor_acc, floor_disp=rel - offset, source=src,
                       name=name or Path(src).name.split(".")[0], extra=extra)


def _lowpass(x: np.ndarray, dt: float, corner: float, src: str) -> np.ndarray:
    """:func:`hlaid.signal.lowpass`, the corner checked first (it is a user's option)."""
    nyq = 0.5 / dt
    if not 0 < corner < nyq:
        raise InputError(f"lowpass_hz: low-pass corner {corner} Hz must be between 0 and the Nyquist frequency "
                         f"{nyq:g} Hz", source=src)
    from ..signal import lowpass  # scipy: imported where it filters
    return lowpass(x, dt, corner)


def sniff_steel_frame(head: str) -> bool:
    """Whether the first lines of a file look like a steel-frame record (header with aextx, s2...)."""
    for ln in head.splitlines():
        if ln.strip() and not ln.lstrip().startswith("#"):
            names = ln.split("\t")
            return TABLE_ACC in [n.strip() for n in names] and any(re.fullmatch(r"s\d+", n.strip()) for n in names)
    return False
