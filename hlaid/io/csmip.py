"""Reader for CSMIP (CDMG/CGS) Volume 2 corrected accelerograms, in plain files or CESMD zips.

A V2 file holds one or more channels, each a text header (line 8 reads e.g.
``CHAN  1: 270 DEG  (STA CHN:  1)     LOCATION: BASE OF CENTER BENT``), an integer and a real
header, then three data blocks each announced by a line like
``3000 POINTS OF ACCEL DATA EQUALLY SPACED AT  .020 SEC.  (UNITS: CM/SEC/SEC)`` with 8 values
per line in 10-character columns, and ``/& ... END OF DATA FOR CHANNEL n`` at the end. Only
the acceleration block is read (cm/s^2, converted to mm/s^2).

CESMD event archives are zips of zips (``Structure.zip``, ``Free Field.zip``) holding
``CHANn.V2`` and ``.V3`` files; they are read in memory with :mod:`zipfile`, never extracted.
"""

from __future__ import annotations

import io
import os
import re
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._inputs import read_bytes
from ..errors import InputError
from ..measurement import Measurement
from ..motions import GroundMotion
from ..units import acceleration_factor

_CHAN = re.compile(r"CHAN\s*(\d+)\s*:\s*(?:(\d+)\s*DEG|(UP|DOWN|DWN|VERT\w*))\s*\(STA\s*CHN\s*:\s*(\d+)\)\s*"
                   r"(?:LOCATION\s*:\s*(.*))?", re.I)
_BLOCK = re.compile(r"^\s*(\d+)\s+POINTS OF (ACCEL|VELOC|DISPL)\w* DATA EQUALLY SPACED AT\s+([\d.]+)\s*SEC"
                    r"(?:.*UNITS:\s*([^)]+)\))?", re.I)
_UNITS = {"CM/SEC/SEC": "cm/s^2", "CM/S/S": "cm/s^2", "CM/SEC2": "cm/s^2", "G": "g", "MM/SEC/SEC": "mm/s^2"}
MAX_MEMBER_BYTES = 50_000_000


@dataclass(frozen=True, eq=False)
class CsmipChannel:
    """One channel of a CSMIP V2 file.

    Attributes
    ----------
    acc : (time,) acceleration [mm/s^2]
    dt : sample interval [s]
    station_channel : station channel number (``STA CHN``), unique within a station
    azimuth : horizontal direction [deg], None for a vertical channel
    location : the location text, e.g. ``"FREE FIELD"``
    key : where it came from: ``"Structure.zip/CHAN14.V2"`` inside an archive, else the file name
    header : the channel's text header lines
    source : the file read
    """

    acc: np.ndarray
    dt: float
    station_channel: int
    azimuth: float | None
    location: str
    key: str
    header: tuple[str, ...]
    source: str

    @property
    def npts(self) -> int:
        return int(self.acc.shape[0])

    def describe(self) -> str:
        az = "up" if self.azimuth is None else f"{self.azimuth:g} deg"
        return f"{self.key} (STA CHN {self.station_channel}, {az}, {self.location})"


def parse_v2(text: str, *, key: str, source: str) -> list[CsmipChannel]:
    """All channels of one V2 text (see the module docstring)."""
    lines = text.splitlines()
    if not lines or "CORRECTED ACCELEROGRAM" not in lines[0].upper():
        raise InputError(f"{key}: line 1 should read 'CORRECTED ACCELEROGRAM ...' (a CSMIP V2 file) and does not",
                         source=source)
    starts = [i for i, ln in enumerate(lines) if "CORRECTED ACCELEROGRAM" in ln.upper()
              and not ln.upper().lstrip().startswith("UNCORRECTED")]
    out = []
    for n, s in enumerate(starts):
        end = starts[n + 1] if n + 1 < len(starts) else len(lines)
        out.append(_channel(lines[s:end], s, key=key, source=source))
    return out


def _channel(lines: list[str], offset: int, *, key: str, source: str) -> CsmipChannel:
    where = f"{key} (line {offset + 1})"
    m = next((_CHAN.search(ln) for ln in lines[:12] if _CHAN.search(ln) and "STA" in ln.upper()), None)
    if m is None:
        raise InputError(f"{where}: no 'CHAN n: AZIMUTH (STA CHN: m) LOCATION: ...' line in the header", source=source)
    azimuth = float(m.group(2)) if m.group(2) is not None else None
    blk = next(((i, b) for i, ln in enumerate(lines) if (b := _BLOCK.match(ln))), None)
    if blk is None or blk[1].group(2).upper() != "ACCEL":
        raise InputError(f"{where}: no 'N POINTS OF ACCEL DATA EQUALLY SPACED AT DT SEC' line", source=source)
    i, b = blk
    npts, dt = int(b.group(1)), float(b.group(3))
    units = (b.group(4) or "CM/SEC/SEC").strip().upper().replace(" ", "")
    if units not in _UNITS:
        raise InputError(f"{where}: acceleration units of the data line not understood; expected CM/SEC/SEC",
                         source=source)
    if npts <= 0 or not dt > 0:
        raise InputError(f"{where}: {npts} points at {dt} s; expected positive numbers", source=source)
    nrows = -(-npts // 8)
    rows = lines[i + 1:i + 1 + nrows]
    if len(rows) < nrows:
        raise InputError(f"{where}: {npts} acceleration values announced but the data stop after {len(rows)} lines "
                         "(truncated file?)", source=source)
    values = []
    for r, ln in enumerate(rows):
        count = 8 if r < nrows - 1 else npts - 8 * (nrows - 1)
        for j in range(count):
            field = ln[10 * j:10 * (j + 1)].strip()
            try:
                values.append(float(field))
            except ValueError:
                raise InputError(f"{key} line {offset + i + r + 2}: value {j + 1}: expected a number in a "
                                 "10-character column", source=source) from None
    acc = np.asarray(values) * acceleration_factor(_UNITS[units])
    return CsmipChannel(acc=acc, dt=dt, station_channel=int(m.group(4)), azimuth=azimuth,
                        location=(m.group(5) or "").strip(), key=key, header=tuple(lines[:min(i, 30)]), source=source)


def _walk_zip(data: bytes, prefix: str, source: str, depth: int = 0,
              budget: list[int] | None = None) -> list[tuple[str, bytes]]:
    """(member path, bytes) of every .V2 file, descending into nested zips (in memory). All members
    together, nested ones too, inflate to at most ``HLAID_MAX_FILE_MB`` and at most the gzip rule's
    ratio (:data:`hlaid._inputs.GZIP_MAX_RATIO` times the archive beyond
    :data:`hlaid._inputs.GZIP_FREE_MB`), checked from the members' sizes before each is inflated."""
    if budget is None:
        from .._inputs import GZIP_FREE_MB, GZIP_MAX_RATIO
        from ..limits import max_file_bytes

        budget = [min(max_file_bytes(), max(GZIP_FREE_MB * 2**20, GZIP_MAX_RATIO * len(data)))]
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        raise InputError(f"{prefix or 'file'} is not a readable zip archive", source=source) from None
    out = []
    with zf:
        for info in zf.infolist():
            name = info.filename
            if info.is_dir():
                continue
            if info.file_size > MAX_MEMBER_BYTES:
                raise InputError(f"{prefix}{name} is {info.file_size} bytes; too large for a strong-motion record",
                                 source=source)
            wanted = name.lower().endswith(".v2") or (name.lower().endswith(".zip") and depth < 3)
            if wanted:
                budget[0] -= info.file_size
                if budget[0] < 0:
                    raise InputError(f"{prefix}{name}: the archive's members inflate far more than records compress "
                                     "(a zip bomb?) or past the file-size limit (set HLAID_MAX_FILE_MB to raise it)",
                                     source=source)
            if name.lower().endswith(".zip") and depth < 3:
                out += _walk_zip(_read_member(zf, info, prefix, source), f"{prefix}{name}/", source, depth + 1,
                                 budget)
            elif name.lower().endswith(".v2"):
                out.append((f"{prefix}{name}", _read_member(zf, info, prefix, source)))
    return out


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, prefix: str, source: str) -> bytes:
    try:
        return zf.read(info)
    except (zipfile.BadZipFile, OSError, EOFError, RuntimeError, ValueError, NotImplementedError) as err:
        raise InputError(f"cannot read {prefix}{info.filename} from the archive ({err})", source=source) from None


def read_csmip_channels(path: str | os.PathLike) -> list[CsmipChannel]:
    """Every channel in a V2 file, or in all V2 files of a (nested) CESMD zip."""
    src = str(path)
    p = Path(src)
    if not p.is_file():
        raise InputError("file not found" if not p.exists() else "is not a file", source=src)
    data = read_bytes(p)
    if data[:4] == b"PK\x03\x04" or p.suffix.lower() == ".zip":
        members = _walk_zip(data, "", src)
        if not members:
            raise InputError("archive holds no .V2 (CSMIP corrected accelerogram) files", source=src)
    else:
        members = [(p.name, data)]
    out = []
    for key, raw in members:
        if b"\x00" in raw[:4096]:
            raise InputError(f"{key} is a binary file; expected a CSMIP V2 text file", source=src)
        out += parse_v2(raw.decode("latin-1"), key=key, source=src)
    return out


def _select(chans: list[CsmipChannel], which: int | str, src: str) -> CsmipChannel:
    if isinstance(which, str) and not which.strip().isdigit():
        hits = [c for c in chans if c.key == which or c.key.endswith("/" + which)]
    else:
        hits = [c for c in chans if c.station_channel == int(which)]
    listing = "; ".join(c.describe() for c in chans)
    if not hits:
        raise InputError(f"no channel {which!r}; channels are: {listing}", source=src)
    if len(hits) > 1:
        raise InputError(f"channel {which!r} is ambiguous: {'; '.join(c.describe() for c in hits)}; "
                         "name it by its archive path", source=src)
    return hits[0]


def read_csmip(path: str | os.PathLike, channel: int | str | None = None, *, name: str | None = None) -> GroundMotion:
    """One CSMIP V2 channel as a :class:`~hlaid.motions.GroundMotion` [mm/s^2].

    Parameters
    ----------
    path : a V2 file or a CESMD zip
    channel : station channel number (``STA CHN``) or archive path such as
        ``"Free Field.zip/CHAN014.V2"``; needed when the file holds more than one channel
    """
    src = str(path)
    chans = read_csmip_channels(path)
    if channel is None:
        if len(chans) > 1:
            raise InputError(f"holds {len(chans)} channels; choose one with channel= "
                             f"({'; '.join(c.describe() for c in chans)})", source=src)
        ch = chans[0]
    else:
        ch = _select(chans, channel, src)
    return GroundMotion(dt=ch.dt, acc=ch.acc, name=name or f"{Path(src).stem}-ch{ch.station_channel}", source=src)


def csmip_measurement(path: str | os.PathLike, *, ground: int | str, floors: Sequence[int | str],
                      name: str | None = None) -> Measurement:
    """A measurement from chosen CSMIP channels along one horizontal axis.

    Parameters
    ----------
    path : a V2 file or CESMD zip
    ground : the input channel (station channel number or archive path)
    floors : the response channels, bottom to top. Each must be parallel to ``ground``
        (within 10 degrees) or opposite to it, in which case it is negated so that all share
        the ground channel's positive direction.
    """
    src = str(path)
    chans = read_csmip_channels(path)
    g = _select(chans, ground, src)
    fl = [_select(chans, f, src) for f in floors]
    if not fl:
        raise InputError("floors: give at least one response channel", source=src)
    if g.azimuth is None:
        raise InputError(f"ground channel {g.describe()} is vertical; choose a horizontal one", source=src)
    series, signs = [], []
    for c in fl:
        if c.npts != g.npts or abs(c.dt - g.dt) > 1e-9:
            raise InputError(f"{c.describe()} has {c.npts} samples at {c.dt:g} s but the ground channel has "
                             f"{g.npts} at {g.dt:g} s", source=src)
        if c.azimuth is None:
            raise InputError(f"{c.describe()} is vertical; choose channels along the ground channel's axis", source=src)
        d = abs((c.azimuth - g.azimuth) % 360.0)
        d = min(d, 360.0 - d)
        if d <= 10.0:
            s = 1.0
        elif d >= 170.0:
            s = -1.0
        else:
            raise InputError(f"{c.describe()} is not along the ground channel's axis ({g.azimuth:g} deg)", source=src)
        series.append(s * c.acc)
        signs.append(s)
    return Measurement(dt=g.dt, ground_acc=g.acc, floor_acc=np.stack(series, axis=1), source=src,
                       name=name or f"{Path(src).stem}-ch{g.station_channel}",
                       extra={"azimuth": g.azimuth, "ground_channel": g.describe(),
                              "floor_channels": [c.describe() for c in fl], "signs": signs})
