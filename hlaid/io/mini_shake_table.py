"""Reader for the mini shake-table 3-story model (Xsens DOT IMUs, one per level).

CSV with ``#`` comment lines and a header ``t_s, ground_AccX, ground_AccY, floor1_AccX, ...``:
raw sensor-frame accelerations [m/s^2] at about 120 Hz, gravity projection and sensor bias
not removed; the table shakes along sensor X. The reader

- takes ``dt`` from the time column (the IMU clock steps 8333 us, so ``dt = 0.008333 s``,
  120.005 Hz; stamps are printed to 10 us and lie within 5 us of that grid),
- removes the static bias of every channel: its mean over the first ``pre_event_s`` seconds
  (the shaking starts after 10 s or more in the shipped runs). This removes the constant
  gravity projection from a slightly tilted sensor (0.1-0.2 m/s^2, about 1 degree) and the
  accelerometer offset; a tilt that changes during the test is not corrected,
- keeps the signs: every floor's X axis points the same way as the table's (the floor/table
  transfer function between 0.3 and 1 Hz, where the model moves rigidly with the table, is
  1.00-1.06 with phase within 4 degrees; a reversed sensor would show 180 degrees).
  ``signs`` flips channels of a differently mounted set-up.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import cast

import numpy as np

from .._inputs import DATA_LINES, read_text
from ..errors import InputError
from ..measurement import Measurement
from ..units import acceleration_factor
from ._common import parse_table, pre_event_mean, uniform_time

TIME = "t_s"
_LEVEL = re.compile(r"(ground|floor(\d+))_Acc([XYZ])", re.I)


def read_mini_shake_table(path: str | os.PathLike, *, axis: str = "X", pre_event_s: float = 5.0,
                          signs: tuple[float, ...] | None = None, units: str = "m/s^2",
                          name: str | None = None) -> Measurement:
    """Read one mini shake-table run as a :class:`~hlaid.measurement.Measurement`.

    Parameters
    ----------
    path : CSV file with ``t_s`` and ``<level>_Acc<axis>`` columns (``ground``, ``floor1``...)
    axis : sensor axis along the shaking (``X`` in the shipped files)
    pre_event_s : length [s] of the quiet window at the start whose mean is the static bias
    signs : +1/-1 per channel, ground first then floors bottom to top (default all +1)
    units : acceleration units of the file
    name : measurement name (default: the file name without extension)

    Returns
    -------
    Measurement
        ``ground_acc`` (time,) and ``floor_acc`` (time, floor) absolute accelerations
        [mm/s^2], bias removed; ``mass`` None. ``extra["bias_mm_s2"]`` holds the removed
        biases (ground first) and ``extra["other_axis"]`` the bias-removed accelerations
        along the other horizontal axis, (time, 1 + floor), when present.
    """
    src = str(path)
    axis = str(axis).upper()
    if axis not in ("X", "Y", "Z"):
        raise InputError(f"axis must be X, Y or Z, got {axis!r}", source=src)
    table = parse_table(read_text(path, max_lines=DATA_LINES), src, delimiter=",", comment="#")
    table.index(TIME, src)
    chans = {}
    for n in table.names:
        m = _LEVEL.fullmatch(n.strip())
        if m:
            level = 0 if m.group(1).lower() == "ground" else int(m.group(2))
            chans[(level, m.group(3).upper())] = n
    levels = sorted({lv for lv, ax in chans if ax == axis})
    if 0 not in levels or len(levels) < 2:
        raise InputError(f"needs columns ground_Acc{axis} and floor1_Acc{axis}, floor2_Acc{axis}, ...; "
                         f"columns are {', '.join(table.names)}", source=src)
    if levels != list(range(len(levels))):
        raise InputError(f"floor columns must be numbered 1..n without gaps, got floors {levels[1:]}", source=src)
    try:
        factor = acceleration_factor(units)
    except ValueError as err:
        raise InputError(str(err), source=src) from None
    names = [chans[(lv, axis)] for lv in levels]
    other_axis = "Y" if axis == "X" else "X"
    other = [chans.get((lv, other_axis)) for lv in levels]
    cols = names + (cast("list[str]", [c for c in other]) if all(other) else [])
    tax, values = uniform_time(table.column(TIME, src), table.data[:, [table.index(c, src) for c in cols]], src,
                               column=TIME)
    values = values * factor
    bias = pre_event_mean(values, tax.dt, pre_event_s, src)
    values = values - bias
    acc = values[:, :len(names)]
    if signs is not None:
        s = np.asarray(signs, dtype=np.float64).reshape(-1)
        if s.shape[0] != len(names) or not np.all(np.abs(s) == 1):
            raise InputError(f"signs must be {len(names)} values of +1 or -1 (ground then floors), got "
                             f"{list(signs)}", source=src)
        acc = acc * s
    extra = {"bias_mm_s2": bias[:len(names)], "columns": names, "time_jitter_s": tax.jitter,
             "resampled": tax.resampled}
    if len(cols) > len(names):
        extra["other_axis"] = values[:, len(names):]
    return Measurement(dt=tax.dt, ground_acc=acc[:, 0], floor_acc=acc[:, 1:], source=src,
                       name=name or Path(src).name.split(".")[0], extra=extra)


def sniff_mini_shake_table(head: str) -> bool:
    """Whether the first lines look like a mini shake-table CSV (``t_s`` and ``ground_AccX``)."""
    for ln in head.splitlines():
        if ln.strip() and not ln.lstrip().startswith("#"):
            names = [n.strip() for n in ln.split(",")]
            return TIME in names and any(_LEVEL.fullmatch(n) for n in names)
    return False
