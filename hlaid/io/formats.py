"""Measurement formats by name, and telling a file's format from its name and first lines."""

from __future__ import annotations

import os
import zipfile
from collections.abc import Callable
from pathlib import Path

from .._inputs import NotTextError, check_readable_file, read_head
from ..errors import InputError
from ..measurement import Measurement
from .columns import read_columns
from .csmip import csmip_measurement, read_csmip_channels
from .hotel import hotel_events, read_hotel
from .mini_shake_table import read_mini_shake_table, sniff_mini_shake_table
from .native import read_native
from .smc import smc_measurement, sniff_smc
from .station import read_station
from .steel_frame import read_steel_frame, sniff_steel_frame

__all__ = ["MEASUREMENT_READERS", "detect_format", "read_by_format"]

MEASUREMENT_READERS: dict[str, Callable[..., Measurement]] = {
    "npz": read_native,
    "csv": read_native,
    "steel-frame": read_steel_frame,
    "mini-shake-table": read_mini_shake_table,
    "smc": smc_measurement,
    "csmip": csmip_measurement,
    "columns": read_columns,
    "hotel": read_hotel,
    "station": read_station,
}
"""Measurement readers by name; each takes the path first and keyword options after it."""


def _head(p: Path) -> str:
    """The first 40 lines of ``p`` ("" for a binary file); a file that cannot be read is an error."""
    try:
        return "\n".join(read_head(p).splitlines()[:40])  # the head alone: a 10^7-row file is not read here
    except NotTextError:
        return ""


def detect_format(path: str | os.PathLike) -> str:
    """The :data:`MEASUREMENT_READERS` name for ``path``, from its extension and first lines.

    Raises InputError, naming the file, when the format cannot be told.
    """
    p = Path(path)
    src = str(p)
    if not p.exists():
        raise InputError("file not found", source=src)
    if p.is_dir():
        if any(q.suffix.lower() == ".smc" for q in p.iterdir()):
            return "smc"
        raise InputError("folder holds no .smc files; give a file or format=", source=src)
    check_readable_file(p)  # a regular file within the size limit (hlaid.limits) before sniffing it
    name = p.name.lower()
    bare = name.removesuffix(".gz")
    if bare.endswith((".yaml", ".yml")):
        return "columns"
    if bare.endswith(".npz"):
        return "npz"
    if bare.endswith((".mseed", ".miniseed", ".sac")):
        raise InputError("is seismic station data (miniSEED/SAC): describe which channel is the ground and which "
                         "each floor in a YAML file and read that with format 'station' (see hlaid.io.station)",
                         source=src)
    if bare.endswith(".mat"):
        return "hotel"
    if bare.endswith(".smc"):
        return "smc"
    if bare.endswith(".zip") or bare.endswith(".v2"):
        return "csmip"
    if zipfile.is_zipfile(p):
        try:
            with zipfile.ZipFile(p) as zf:
                names = zf.namelist()
        except (zipfile.BadZipFile, OSError):
            names = []
        return "npz" if any(n.endswith(".npy") for n in names) else "csmip"
    head = _head(p)
    if sniff_steel_frame(head):
        return "steel-frame"
    if sniff_mini_shake_table(head):
        return "mini-shake-table"
    if sniff_smc(head):
        return "smc"
    if "CORRECTED ACCELEROGRAM" in head[:200].upper():
        return "csmip"
    if bare.endswith(".csv") and "ground_acc" in head and "floor_acc_1" in head:
        return "csv"
    raise InputError("cannot tell the data format from the name or the first lines; give format= (one of "
                     f"{', '.join(sorted(MEASUREMENT_READERS))}) or describe the columns in a YAML file "
                     "(see hlaid.io.columns)", source=src)


def read_by_format(path: str | os.PathLike, format: str | None = None, **kw) -> Measurement:
    """Read a measurement with the reader named ``format``, or the one :func:`detect_format` picks
    (what ``hlaid.io.read(path, kind="measurement")`` does, less its sample-rate warning).

    Parameters
    ----------
    path : file or folder (a folder of ``.smc`` channels)
    format : a key of :data:`MEASUREMENT_READERS`
    **kw : options of that reader (e.g. ``event=13`` for ``hotel``, ``ground=3, floors=[7]``
        for ``csmip``)
    """
    src = str(path)
    fmt = format or detect_format(path)
    if fmt not in MEASUREMENT_READERS:
        raise InputError(f"unknown measurement format {fmt!r}; "
                         f"expected one of {', '.join(sorted(MEASUREMENT_READERS))}", source=src)
    if fmt == "hotel" and "event" not in kw:
        raise InputError(f"holds one record per earthquake; choose one, read(path, event=N), N one of "
                         f"{hotel_events(path)}", source=src)
    if fmt == "csmip" and ("ground" not in kw or "floors" not in kw):
        chans = "; ".join(c.describe() for c in read_csmip_channels(path))
        raise InputError("a CSMIP record holds many channels; choose them, read(path, ground=N, floors=[N, ...]) "
                         f"(channels: {chans})", source=src)
    try:
        return MEASUREMENT_READERS[fmt](path, **kw)
    except TypeError as err:
        if "unexpected keyword" in str(err) or "positional argument" in str(err):
            raise InputError(f"format {fmt!r}: {err}", source=src) from None
        raise
