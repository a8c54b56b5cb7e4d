"""Reading every kind of input hlaid takes, through one function: :func:`read`.

``read(path, kind=...)`` returns, by ``kind``:

- ``"measurement"``: a :class:`~hlaid.measurement.Measurement` of a building (ground and
  floor accelerations). Accelerations come back absolute in mm/s^2, floor displacements
  relative to the ground in mm, ``mass=None`` when the file does not give masses. Formats
  (:data:`MEASUREMENT_READERS`, detected by :func:`detect_format` unless ``format=`` names one):

  - ``npz``, ``csv``: hlaid's own measurement files (:mod:`hlaid.io.native`)
  - ``steel-frame``: shake-table TSV ``Time, aextx, s2..s5`` (:func:`read_steel_frame`)
  - ``mini-shake-table``: Xsens IMU CSV ``t_s, ground_AccX, floor1_AccX, ...`` (:func:`read_mini_shake_table`)
  - ``smc``: a folder (or list) of USGS ``.smc`` channels of one building (:func:`smc_measurement`)
  - ``csmip``: a CSMIP V2 file or CESMD zip, channels chosen by the caller (:func:`csmip_measurement`)
  - ``columns``: any table, mapped by a YAML file (:func:`read_columns`)
  - ``hotel``: the PhyCNN 6-story hotel ``.mat``, one earthquake chosen by the caller (:func:`read_hotel`)
  - ``station``: miniSEED/SAC station data through ObsPy (optional extra), channels mapped onto
    floors by a YAML file (:func:`read_station`)

- ``"motion"``: one ground motion :class:`~hlaid.motions.GroundMotion` [mm/s^2] from a PEER
  ``.AT2``, a text or a CSV file, or ``builtin:NAME`` (:mod:`hlaid.io.motion`, formats
  :data:`MOTION_READERS`).
- ``"records"``: a list of ground motions: a folder of record files, ``"builtin-suite"``, or a
  list of files, ``builtin:NAME`` and motions (:mod:`hlaid.io.records`).

What each shipped dataset is, and the evidence for it, is in ``docs/data.md``.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError
from ..measurement import warn_unusual_rate
from ..motions.builtin import SUITE
from .columns import ChannelSpec, ColumnsConfig, load_columns_config, read_columns
from .csmip import CsmipChannel, csmip_measurement, read_csmip, read_csmip_channels
from .formats import MEASUREMENT_READERS, detect_format, read_by_format
from .hotel import hotel_events, read_hotel
from .mini_shake_table import read_mini_shake_table
from .motion import MOTION_READERS, read_record
from .records import RECORD_SUFFIXES, read_records
from .smc import SmcChannel, read_smc, read_smc_channel, smc_measurement
from .station import StationChannel, StationConfig, read_station
from .steel_frame import read_steel_frame

KINDS = ("measurement", "motion", "records")
"""What :func:`read` reads."""

__all__ = ["read", "infer_kind", "KINDS", "MEASUREMENT_READERS", "MOTION_READERS", "detect_format",
           "read_steel_frame", "read_mini_shake_table", "read_smc", "read_smc_channel", "smc_measurement",
           "SmcChannel", "read_csmip", "read_csmip_channels", "csmip_measurement", "CsmipChannel", "read_columns",
           "load_columns_config", "ColumnsConfig", "ChannelSpec", "read_hotel", "hotel_events", "read_station",
           "StationConfig", "StationChannel"]


def infer_kind(path, format: str | None = None) -> str:
    """The :data:`KINDS` entry :func:`read` takes ``path`` for when no ``kind`` is given.

    - a list or tuple of specs, a :class:`~hlaid.motions.GroundMotion` or ``"builtin-suite"``: ``"records"``
    - ``"builtin:NAME"``: ``"motion"``
    - with ``format``: ``"measurement"`` for a :data:`MEASUREMENT_READERS` name (``csv`` included),
      ``"motion"`` for the other :data:`MOTION_READERS` names
    - a folder: ``"measurement"`` when it holds ``.smc`` channels, else ``"records"``
    - a file ending in ``.AT2`` (optionally ``.gz``): ``"motion"``; one ending in another record
      suffix (``.txt``, ``.dat``, ``.acc``, ``.csv``): ``"measurement"`` when :func:`detect_format`
      recognises it, else ``"motion"``
    - anything else: ``"measurement"``
    """
    if not isinstance(path, (str, os.PathLike)):
        return "records"
    s = str(path)
    if s == SUITE:
        return "records"
    if s.startswith("builtin:"):
        return "motion"
    if format is not None:
        return "measurement" if format in MEASUREMENT_READERS or format not in MOTION_READERS else "motion"
    p = Path(s)
    if p.is_dir():
        return "measurement" if any(q.suffix.lower() == ".smc" for q in p.iterdir()) else "records"
    bare = p.name.lower().removesuffix(".gz")
    if bare.endswith(".at2"):
        return "motion"
    if bare.endswith(RECORD_SUFFIXES) and p.is_file():
        try:
            detect_format(p)
        except InputError:
            return "motion"
    return "measurement"


def read(path, kind: str | None = None, *, format: str | None = None, **options):
    """Read a measurement, a ground motion or a record suite.

    Parameters
    ----------
    path : a file or folder; ``builtin:NAME`` for a record shipped with hlaid; for
        ``kind="records"`` also ``"builtin-suite"``, a motion, or a list of these
    kind : one of :data:`KINDS`, or None: taken from ``path`` as :func:`infer_kind` says
    format : for a measurement a :data:`MEASUREMENT_READERS` name, for a motion a
        :data:`MOTION_READERS` name (default: told from the file)
    **options : options of that reader, e.g. ``event=13`` (``hotel``), ``ground=3, floors=[7]``
        (``csmip``); ``units``, ``dt``, ``column`` for a text or CSV motion; ``units``, ``dt`` for records

    Returns
    -------
    Measurement, GroundMotion, or list of GroundMotion (``"records"``: unique names; an
    unreadable file is skipped with a warning naming it, and none readable is an error)

    A measurement whose sample rate is legal but unusual is read with a warning (see
    :data:`hlaid.measurement.RATE_USUAL_HZ`). Every problem with a file is an
    :class:`~hlaid.errors.InputError` naming it.
    """
    kind = infer_kind(path, format) if kind is None else kind
    if kind == "measurement":
        meas = read_by_format(path, format, **options)
        warn_unusual_rate(meas)
        return meas
    if kind == "motion":
        return read_record(path, format=format, **options)
    if kind == "records":
        if format is not None:
            raise InputError("format= applies to one file; a record set is read by extension", source=str(path))
        return read_records(path, **options)
    raise InputError(f"unknown kind {kind!r}; expected one of {', '.join(KINDS)}")
