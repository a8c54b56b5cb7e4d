"""Ground motion records: PEER NGA ``.AT2``, one- or two-column text, CSV, and ``builtin:NAME``.

Every reader returns a :class:`GroundMotion` in mm/s^2 and raises
:class:`~hlaid.errors.InputError` naming the file and what is wrong, and where (line, column),
without quoting the file's contents (it may be an unrelated file given by mistake; only short
plain column names are quoted, see :func:`hlaid.errors.quotable`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable

import numpy as np

from .._inputs import DATA_LINES, read_text
from ..errors import InputError, columns_text, quotable
from ..motions.at2 import NUMBER, floats, number, read_at2, record_name
from ..motions.builtin import load_builtin
from ..motions.record import GroundMotion
from ..units import acceleration_factor

__all__ = ["MOTION_READERS", "motion_format", "read_record", "read_at2", "read_text_record", "read_csv_record"]

def _col(header: list[str], j: int) -> str:
    """``column 'acc (g)'``, or ``column 2`` when the header name is not quotable."""
    return f"column {header[j]!r}" if quotable(header[j]) else f"column {j + 1}"


def _header_hints(comments: list[str]) -> dict:
    """dt and units mentioned in comment lines, e.g. 'Acc. in cm/sec^2 and dt=0.005 sec.'."""
    text = " ".join(comments).lower()
    hints: dict[str, float | str] = {}
    m = re.search(rf"\bdt\s*=\s*({NUMBER})", text)
    if m:
        hints["dt"] = number(m.group(1))
    for pat, unit in ((r"cm/s(ec)?(\^2|2|/s(ec)?)", "cm/s^2"), (r"\bgal\b", "cm/s^2"),
                      (r"mm/s(ec)?(\^2|2|/s(ec)?)", "mm/s^2"), (r"\bm/s(ec)?(\^2|2|/s(ec)?)", "m/s^2"),
                      (r"units?\s*(of|in|:|=)\s*g\b", "g")):
        if re.search(pat, text):
            hints["units"] = unit
            break
    return hints


def read_text_record(path: str | os.PathLike, *, units: str | None = None, dt: float | None = None,
              column: int | None = None, name: str | None = None) -> GroundMotion:
    """Read a whitespace-separated text record.

    Layouts: one column of accelerations (``dt`` needed), or two or more columns where the
    first is time when it increases uniformly (``time, acceleration``; a first column that
    increases in unequal steps is an error); otherwise columns are channels and ``column``
    picks one (default 0). Lines starting with ``#`` or ``%``
    are comments; ``dt=...`` and the units may be read from them when not given.

    Parameters
    ----------
    units : acceleration units of the file: g, m/s^2, cm/s^2 (gal), mm/s^2
    dt : sample interval [s] when there is no time column
    column : which acceleration column to read (0-based, not counting a time column)
    """
    src = str(path)
    text = read_text(path, max_lines=DATA_LINES)
    comments = [ln.strip()[1:] for ln in text.splitlines() if ln.strip()[:1] in ("#", "%")]
    numbered = [(i + 1, ln.replace(",", " ")) for i, ln in enumerate(text.splitlines())
                if ln.strip() and ln.strip()[:1] not in ("#", "%")]
    body = [ln for _, ln in numbered]
    if not body:
        raise InputError("holds no data lines", source=src)
    widths = {len(ln.split()) for ln in body}
    if len(widths) != 1:
        raise InputError(f"rows have different numbers of columns {sorted(widths)}", source=src)
    data = floats(numbered, src).reshape(len(body), -1)
    hints = _header_hints(comments)
    units = units or hints.get("units")
    if units is None:
        raise InputError("units are not stated in the file; give units (g, m/s^2, cm/s^2 or mm/s^2)", source=src)
    t = data[:, 0]
    has_time = data.shape[1] >= 2 and data.shape[0] > 2 and _is_uniform_time(t)
    if not has_time and data.shape[1] >= 2 and data.shape[0] > 2 and np.all(np.diff(t) > 0):
        d = np.diff(t)
        raise InputError(f"the first column increases like a time axis but its steps are not uniform "
                         f"({d.min():g} to {d.max():g}); give a uniformly sampled record", source=src)
    channels = data[:, 1:] if has_time else data
    col = 0 if column is None else int(column)
    if not 0 <= col < channels.shape[1]:
        raise InputError(f"column {col} requested but the file has {channels.shape[1]} acceleration column(s)",
                         source=src)
    if has_time:
        step = float(np.round((t[-1] - t[0]) / (len(t) - 1), 12))
        if dt is not None and abs(dt - step) > 1e-6 * step:
            raise InputError(f"dt = {dt} s given but the time column steps by {step:g} s", source=src)
        dt = step
    dt = dt if dt is not None else hints.get("dt")
    return _motion(channels[:, col], dt, units, name, src)


def _motion(acc: np.ndarray, dt: float | None, units: str, name: str | None, src: str) -> GroundMotion:
    """The record ``acc`` (time,) in ``units``, converted to mm/s^2 (a clear error when ``dt`` is
    unknown or the units are not an acceleration)."""
    if dt is None:
        raise InputError("no time column and no dt; give dt", source=src)
    try:
        factor = acceleration_factor(units)
    except ValueError as err:
        raise InputError(str(err), source=src) from None
    return GroundMotion(dt=dt, acc=acc * factor, name=name or record_name(src), source=src)


def _is_uniform_time(t: np.ndarray) -> bool:
    """Whether ``t`` increases in equal steps (it may start at any time; the record's origin is its
    first sample)."""
    d = np.diff(t)
    step = np.median(d)
    return bool(step > 0 and np.all(np.abs(d - step) <= 1e-3 * step + 1e-9))


def read_csv_record(path: str | os.PathLike, *, units: str | None = None, dt: float | None = None,
             column: int | str | None = None, name: str | None = None) -> GroundMotion:
    """Read a CSV record with a header row, e.g. ``time,acc (g)``.

    A column named ``t``/``time`` (optionally with a unit) is the time axis; ``column`` picks
    the acceleration column by name or index (default: the first non-time column). Units
    may be given in the header in parentheses or brackets.
    """
    src = str(path)
    text = read_text(path, max_lines=DATA_LINES)
    numbered = [(i + 1, ln) for i, ln in enumerate(text.splitlines()) if ln.strip() and not ln.lstrip().startswith("#")]
    lines = [ln for _, ln in numbered]
    if len(lines) < 2:
        raise InputError("holds no data rows", source=src)
    header = [h.strip() for h in lines[0].split(",")]
    if all(re.fullmatch(NUMBER, h) for h in header):
        return read_text_record(path, units=units, dt=dt, column=column if isinstance(column, int) else None, name=name)
    rows = [ln.split(",") for ln in lines[1:]]
    if any(len(r) != len(header) for r in rows):
        bad = next(i for i, r in enumerate(rows) if len(r) != len(header))
        raise InputError(f"line {numbered[bad + 1][0]} has {len(rows[bad])} fields but the header has {len(header)}",
                         source=src)
    data = np.empty((len(rows), len(header)))
    for i, r in enumerate(rows):
        for j, v in enumerate(r):
            try:
                data[i, j] = number(v)
            except ValueError:
                raise InputError(f"line {numbered[i + 1][0]}, {_col(header, j)}: not a number", source=src) from None
    base = [re.sub(r"[\(\[].*", "", h).strip().lower() for h in header]
    tcol = next((i for i, b in enumerate(base) if b in ("t", "time", "t_s", "time_s")), None)
    col: int | None
    if isinstance(column, str):
        if column not in header and column.lower() not in base:
            raise InputError(f"no column {column!r}; columns are {columns_text(header)}", source=src)
        col = header.index(column) if column in header else base.index(column.lower())
    elif isinstance(column, int):
        col = column
    else:
        col = next(i for i in range(len(header)) if i != tcol) if len(header) > 1 or tcol is None else None
    if col is None or not 0 <= col < len(header):
        raise InputError(f"cannot pick an acceleration column from {columns_text(header)}", source=src)
    unit_in_header = re.search(r"[\(\[]\s*([^\)\]]+?)\s*[\)\]]", header[col])
    units = units or (unit_in_header.group(1) if unit_in_header else None)
    if units is None:
        raise InputError(f"units of {_col(header, col)} are not stated; give units", source=src)
    if tcol is not None:
        if not _is_uniform_time(data[:, tcol]):
            raise InputError("the time column is not uniformly increasing", source=src)
        tt = data[:, tcol]
        dt = float(np.round((tt[-1] - tt[0]) / (len(tt) - 1), 12))
    return _motion(data[:, col], dt, units, name, src)


MOTION_READERS: dict[str, Callable[..., GroundMotion]] = {"at2": read_at2, "text": read_text_record,
                                                          "csv": read_csv_record}
"""Record formats by name; :func:`read_record` picks one from the file extension."""


def motion_format(path: str) -> str:
    """The :data:`MOTION_READERS` name for ``path``, from its extension (``text`` when not AT2 or CSV)."""
    name = path.lower()
    if name.endswith(".gz"):
        name = name[:-3]
    if name.endswith(".at2"):
        return "at2"
    if name.endswith(".csv"):
        return "csv"
    return "text"


def read_record(spec: str | os.PathLike, *, units: str | None = None, dt: float | None = None,
                column: int | str | None = None, format: str | None = None) -> GroundMotion:
    """Read a record from a path, or ``builtin:NAME`` for a record shipped with hlaid
    (what ``hlaid.io.read(spec, kind="motion")`` does).

    Parameters
    ----------
    spec : path or ``builtin:NAME`` (see :func:`hlaid.motions.builtin_records`)
    units, dt, column : passed to the text and CSV readers
    format : ``"at2"``, ``"text"`` or ``"csv"``; default from the extension
    """
    spec = str(spec)
    if spec.startswith("builtin:"):
        return load_builtin(spec[len("builtin:"):])
    fmt = format or motion_format(spec)
    if fmt not in MOTION_READERS:
        raise InputError(f"unknown record format {fmt!r}; expected one of {sorted(MOTION_READERS)}", source=spec)
    if fmt == "at2":
        return read_at2(spec)
    return MOTION_READERS[fmt](spec, units=units, dt=dt, column=column)
