"""Reader for USGS/COSMOS ``.smc`` strong-motion files (one channel per file).

Layout (fixed width, 80 columns):

1. 11 text lines; line 1 is the data type (``2 CORRECTED ACCELEROGRAM``; ``1 UNCORRECTED
   ACCELEROGRAM`` is read too; velocity and displacement files are refused),
2. 6 lines of 8 integers (width 10): [0] the no-data value, [12] vertical orientation
   (0 up, 90 horizontal), [13] horizontal azimuth [deg], [15] number of comment lines,
   [16] number of samples,
3. 10 lines of 5 reals (width 15): [0] the no-data value, [1] samples per second,
4. the comment lines (starting with ``|``; ``<loclbl=>...<end>`` names the sensor location,
   ``<SCNL>`` the station.channel.network.location code),
5. the samples, 8 per line, width 10, in cm/s^2 (converted to mm/s^2 here).

:func:`smc_measurement` combines the channels of an instrumented building (one folder) into
a :class:`~hlaid.measurement.Measurement` along one horizontal axis, aligning signs by azimuth.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from .._inputs import DATA_LINES, read_text
from ..errors import InputError, quotable
from ..measurement import Measurement
from ..motions import GroundMotion
from ..units import acceleration_factor

TEXT_LINES, INT_LINES, REAL_LINES = 11, 6, 10
INT_WIDTH, REAL_WIDTH, DATA_WIDTH = 10, 15, 10
_TYPES = ("1", "2")   # 1 uncorrected, 2 corrected acceleration; 3 velocity and 4 displacement are refused
AZIMUTH_TOLERANCE = 10.0
"""Channels within this many degrees of the reference axis (or its opposite) belong to it."""


@dataclass(frozen=True, eq=False)
class SmcChannel:
    """One channel of an SMC file.

    Attributes
    ----------
    acc : (time,) acceleration [mm/s^2]
    dt : sample interval [s]
    azimuth : horizontal azimuth [deg, clockwise from north], None for a vertical channel
    vertical : True for a vertical channel
    location : the sensor location label (``<loclbl=>``), e.g. ``"Roof, center of bldg"``
    scnl : station.channel.network.location code, e.g. ``"1103.HN2.NP.RC"``
    station : station name from the header
    start : start-time fields of the integer header (compared across channels)
    source : the file
    """

    acc: np.ndarray
    dt: float
    azimuth: float | None
    vertical: bool
    location: str
    scnl: str
    station: str
    start: tuple
    source: str

    @property
    def npts(self) -> int:
        return int(self.acc.shape[0])


def _fixed(line: str, width: int, count: int, kind, what: str, src: str, lineno: int) -> list:
    out = []
    for j in range(count):
        field = line[j * width:(j + 1) * width].strip()
        try:
            out.append(kind(field))
        except ValueError:
            raise InputError(f"{what} line {lineno}: field {j + 1}: expected "
                             f"{'an integer' if kind is int else 'a number'} in a {width}-character column",
                             source=src) from None
    return out


def read_smc_channel(path: str | os.PathLike) -> SmcChannel:
    """Read one ``.smc`` file (see the module docstring for the layout)."""
    src = str(path)
    lines = read_text(path, max_lines=DATA_LINES).splitlines()
    head = TEXT_LINES + INT_LINES + REAL_LINES
    if len(lines) < head + 1:
        raise InputError(f"has {len(lines)} lines; an SMC file has {head} header lines before the comments and data",
                         source=src)
    kind = lines[0].strip()[:1]
    if kind not in _TYPES or "ACCELEROGRAM" not in lines[0].upper():
        raise InputError("line 1 should read '2 CORRECTED ACCELEROGRAM' (an SMC acceleration file) and does not",
                         source=src)
    ints = []
    for i in range(INT_LINES):
        ints += _fixed(lines[TEXT_LINES + i], INT_WIDTH, 8, int, "integer header", src, TEXT_LINES + i + 1)
    reals = []
    for i in range(REAL_LINES):
        k = TEXT_LINES + INT_LINES + i
        reals += _fixed(lines[k], REAL_WIDTH, 5, float, "real header", src, k + 1)
    nodata = ints[0]
    ncomment, npts = ints[15], ints[16]
    rate = reals[1]
    if not 0 <= ncomment <= len(lines) - head:
        raise InputError(f"integer header says {ncomment} comment lines but the file has only {len(lines)} lines",
                         source=src)
    if npts <= 0 or npts == nodata:
        raise InputError(f"integer header gives {npts} samples; expected a positive count (field 17)", source=src)
    if not (np.isfinite(rate) and 0 < rate < 1e5):
        raise InputError(f"real header gives {rate:g} samples per second; expected a positive rate (field 2)",
                         source=src)
    comments = lines[head:head + ncomment]
    if any(not c.startswith("|") for c in comments):
        raise InputError(f"expected {ncomment} comment lines starting with '|' after the real header", source=src)
    body = lines[head + ncomment:]
    nrows = -(-npts // 8)
    if len(body) < nrows:
        raise InputError(f"header says {npts} samples ({nrows} lines of 8) but only {len(body)} data lines follow "
                         "(truncated file?)", source=src)
    values = []
    for i, ln in enumerate(body[:nrows]):
        count = 8 if i < nrows - 1 else npts - 8 * (nrows - 1)
        values += _fixed(ln, DATA_WIDTH, count, float, "data", src, head + ncomment + i + 1)
    if any(ln.strip() for ln in body[nrows:]):
        raise InputError(f"has data after the {npts} samples the header announces", source=src)
    text = "\n".join(comments)
    loc = re.search(r"<loclbl=>(.*?)<end>", text)
    scnl = re.search(r"<SCNL>\s*(\S+)", text)
    station = re.search(r"station\s*=\s*(.*?)\s{2,}", lines[5] + "  ")
    azimuth = None if ints[13] == nodata else float(ints[13])
    vertical = ints[12] == 0
    acc = np.asarray(values) * acceleration_factor("cm/s^2")
    return SmcChannel(acc=acc, dt=1.0 / rate, azimuth=azimuth, vertical=vertical,
                      location=loc.group(1).strip() if loc else "", scnl=scnl.group(1) if scnl else "",
                      station=station.group(1).strip() if station else "", start=tuple(ints[1:8]), source=src)


def read_smc(path: str | os.PathLike, *, name: str | None = None) -> GroundMotion:
    """Read one ``.smc`` acceleration channel as a :class:`~hlaid.motions.GroundMotion` [mm/s^2]."""
    ch = read_smc_channel(path)
    return GroundMotion(dt=ch.dt, acc=ch.acc, name=name or ch.scnl or Path(ch.source).stem, source=ch.source)


# ---------------------------------------------------------------------- building measurement
_GROUND = re.compile(r"\b(basement|ground|base|foundation)\b", re.I)
_FLOOR = re.compile(r"\b(\d+)\s*(st|nd|rd|th)?\s*(floor|fl\b|level)", re.I)
_ROOF = re.compile(r"\broof\b", re.I)
_CENTER = re.compile(r"\bcent(er|re)\b", re.I)
_FREE_FIELD = re.compile(r"free[\s-]*field", re.I)


def _level(ch: SmcChannel) -> tuple[float, str] | None:
    """(sort key, label) of a channel's level: ground 0, floor N, roof infinity; None for free field."""
    loc = ch.location
    if _FREE_FIELD.search(loc):
        return None
    if _ROOF.search(loc):
        return np.inf, "roof"
    m = _FLOOR.search(loc)
    if m:
        n = int(m.group(1))
        return float(n), f"floor {n}"
    if _GROUND.search(loc):
        return 0.0, "ground"
    label = f"location label {loc!r}" if quotable(loc) else "the location label"
    raise InputError(f"cannot tell the level from {label}; expected basement/ground, "
                     "'Nth floor' or roof", source=ch.source)


def _angle(a: float, b: float) -> float:
    """Smallest angle between two azimuths [deg], 0..180."""
    d = abs((a - b) % 360.0)
    return min(d, 360.0 - d)


def _files(paths) -> list[Path]:
    if isinstance(paths, (str, os.PathLike)):
        p = Path(paths)
        if p.is_dir():
            files = sorted(q for q in p.iterdir() if q.suffix.lower() == ".smc")
            if not files:
                raise InputError("folder holds no .smc files", source=str(p))
            return files
        return [p]
    return [Path(p) for p in paths]


def smc_measurement(paths: str | os.PathLike | Sequence[str | os.PathLike], *, azimuth: float | None = None,
                    prefer_center: bool = True, name: str | None = None) -> Measurement:
    """Combine the SMC channels of one building and event into a measurement along one axis.

    Parameters
    ----------
    paths : a folder of ``.smc`` files, or a list of files (one channel each); vertical and
        free-field channels are left out, other channels must be labelled basement/ground,
        'Nth floor' or roof
    azimuth : reference direction [deg]: channels within 10 degrees of it keep their sign,
        those within 10 degrees of the opposite direction are negated, others are left out.
        Default: the horizontal axis recorded on the most levels, pointing the way most of
        its above-ground channels point.
    prefer_center : at a level with a sensor labelled 'center', use that sensor alone;
        otherwise (and at levels without one) average the level's aligned sensors, which
        estimates the diaphragm translation when the sensors sit symmetrically (torsion is
        not modelled)
    name : measurement name (default: the station code and axis)

    Returns
    -------
    Measurement
        ``ground_acc`` from the ground/basement level, ``floor_acc`` (time, level) for the
        instrumented levels above it, bottom to top, absolute [mm/s^2]. These are the
        *instrumented* levels, not necessarily every floor: ``extra["levels"]`` names them
        (e.g. ``["floor 4", "roof"]``) and ``extra["channels"]`` lists, per level, the files
        and signs used; ``extra["azimuth"]`` is the positive direction.
    """
    files = _files(paths)
    chans = [read_smc_channel(f) for f in files]
    first = chans[0]
    for ch in chans[1:]:
        if ch.npts != first.npts or abs(ch.dt - first.dt) > 1e-9 * first.dt or ch.start != first.start:
            raise InputError(f"channel does not share the time axis of {Path(first.source).name} "
                             f"({ch.npts} samples at {ch.dt:g} s vs {first.npts} at {first.dt:g} s, or a different "
                             "start time)", source=ch.source)
    levels = {id(c): _level(c) for c in chans if not c.vertical and c.azimuth is not None}
    horiz = [c for c in chans if levels.get(id(c)) is not None]
    if not horiz:
        raise InputError("no horizontal building channels with an azimuth among the SMC files",
                         source=str(files[0].parent))
    if azimuth is None:
        azimuth = _default_azimuth(horiz, levels)
    picked: dict[float, list[tuple[SmcChannel, float]]] = {}
    for c in horiz:  # each with an azimuth and a level
        d = _angle(cast(float, c.azimuth), azimuth)
        if d <= AZIMUTH_TOLERANCE:
            sign = 1.0
        elif d >= 180.0 - AZIMUTH_TOLERANCE:
            sign = -1.0
        else:
            continue
        picked.setdefault(cast("tuple[float, str]", levels[id(c)])[0], []).append((c, sign))
    keys = sorted(picked)
    where = str(files[0].parent)
    if not keys or keys[0] != 0.0:
        raise InputError(f"no ground/basement channel along azimuth {azimuth:g} deg", source=where)
    if len(keys) < 2:
        raise InputError(f"no channel above the ground along azimuth {azimuth:g} deg", source=where)
    series, used = [], []
    for k in keys:
        group = picked[k]
        centre = [g for g in group if _CENTER.search(g[0].location)] if prefer_center else []
        group = centre[:1] or group
        series.append(np.mean([s * c.acc for c, s in group], axis=0))
        used.append([(Path(c.source).name, s) for c, s in group])
    labels = [cast("tuple[float, str]", levels[id(picked[k][0][0])])[1] for k in keys]
    station = first.scnl.split(".")[0] if first.scnl else first.station
    return Measurement(dt=first.dt, ground_acc=series[0], floor_acc=np.stack(series[1:], axis=1), source=where,
                       name=name or f"{station}-az{azimuth:g}",
                       extra={"levels": labels[1:], "channels": used, "azimuth": float(azimuth),
                              "station": first.station})


def _default_azimuth(horiz: list[SmcChannel], levels: dict) -> float:
    axes: dict[float, list[SmcChannel]] = {}
    for c in horiz:
        az = cast(float, c.azimuth)  # horizontal channels have an azimuth
        key = next((a for a in axes if _angle(a, az) <= AZIMUTH_TOLERANCE
                    or _angle(a, az) >= 180 - AZIMUTH_TOLERANCE), az)
        axes.setdefault(key, []).append(c)

    def score(item):
        chans = item[1]
        return (len({levels[id(c)][0] for c in chans}), len(chans))

    _, chans = max(axes.items(), key=score)
    upper = [c for c in chans if levels[id(c)][0] > 0] or chans
    votes: dict[float, int] = {}
    for c in upper:
        az = cast(float, c.azimuth)
        key = next((a for a in votes if _angle(a, az) <= AZIMUTH_TOLERANCE), az)
        votes[key] = votes.get(key, 0) + 1
    return max(votes.items(), key=lambda kv: kv[1])[0]


def sniff_smc(head: str) -> bool:
    """Whether a file's first line is an SMC acceleration header."""
    first = head.splitlines()[0].strip() if head.strip() else ""
    return bool(re.fullmatch(r"[12] (UN)?CORRECTED ACCELEROGRAM", first))
