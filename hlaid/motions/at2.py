"""PEER NGA ``.AT2`` records (the format of the records shipped with hlaid), and the number
parsing that the other record readers (:mod:`hlaid.io.motion`) share."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._inputs import DATA_LINES, read_text
from ..errors import InputError
from ..limits import check_count
from ..units import acceleration_factor
from .record import GroundMotion

__all__ = ["NUMBER", "number", "floats", "record_name", "read_at2"]

NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?"


def record_name(src: str) -> str:
    """A record's label from its file name: ``RSN6_IMPVALL.I_I-ELC180-hor1.AT2`` ->
    ``RSN6_IMPVALL.I_I-ELC180-hor1`` (only the extension, and ``.gz``, are dropped)."""
    name = Path(src).name
    if name.lower().endswith(".gz"):
        name = name[:-3]
    return Path(name).stem or name


def number(token: str) -> float:
    """``float`` that also reads a Fortran exponent (``.01D00``); raises ValueError."""
    return float(token.strip().replace("D", "E").replace("d", "e"))


def floats(lines: list[tuple[int, str]], source: str) -> np.ndarray:
    """The numbers of ``(line number, text)`` data lines, in order; a value that is not a number
    is reported by its position, not quoted."""
    text = "\n".join(t for _, t in lines)
    try:
        return np.array(text.replace("D", "E").replace("d", "e").split(), dtype=np.float64)
    except ValueError:
        for lineno, t in lines:
            for k, token in enumerate(t.split()):
                try:
                    number(token)
                except ValueError:
                    raise InputError(f"non-numeric value at line {lineno} (value {k + 1} of that line)",
                                     source=source) from None
        raise InputError("holds a value that is not a number", source=source) from None


def read_at2(path: str | os.PathLike, *, name: str | None = None) -> GroundMotion:
    """Read a PEER NGA ``.AT2`` file (units g, 4 header lines, ``NPTS= n, DT= dt SEC``).

    The old NGA layout (``n dt NPTS, DT`` on line 4) is accepted too. The number of values
    must equal NPTS.
    """
    src = str(path)
    lines = read_text(path, max_lines=DATA_LINES).splitlines()
    if len(lines) < 5:
        raise InputError(f"has {len(lines)} lines; an AT2 file has 4 header lines and data", source=src)
    header = lines[3]
    m_n = re.search(r"NPTS\s*=\s*(\d+)", header, re.I)
    m_dt = re.search(rf"DT\s*=\s*({NUMBER})", header, re.I)
    if m_n and m_dt:
        npts, dt = int(m_n.group(1)), number(m_dt.group(1))
    else:
        m_old = re.match(rf"\s*(\d+)\s+({NUMBER})\s+NPTS", header, re.I)
        if not m_old:
            raise InputError("line 4 should give NPTS and DT (e.g. 'NPTS= 5372, DT= .0100 SEC') and does not",
                             source=src)
        npts, dt = int(m_old.group(1)), number(m_old.group(2))
    check_count(npts, "SAMPLES", "NPTS", source=src)  # from the header, before the values are parsed
    units = lines[2].upper()
    if re.search(r"CM/S", units):
        factor = acceleration_factor("cm/s^2")
    elif re.search(r"\bG\b", units) or "UNITS OF G" in units or units.strip() == "":
        factor = acceleration_factor("g")
    else:
        raise InputError("cannot tell the units from line 3; expected 'UNITS OF G' (or CM/S/S)", source=src)
    values = floats([(i + 5, ln) for i, ln in enumerate(lines[4:])], src)
    if values.size != npts:
        raise InputError(f"header says NPTS = {npts} but the file holds {values.size} values", source=src)
    label = name or record_name(src)
    return GroundMotion(dt=dt, acc=values * factor, name=label, source=src)
