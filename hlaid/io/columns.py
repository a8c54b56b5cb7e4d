"""A general column-mapped reader: monitoring data in CSV/TSV/whitespace tables, described in YAML.

Example (``station.yaml``, next to ``station.csv``)::

    file: station.csv              # relative to this YAML file
    delimiter: csv                 # csv | tsv | whitespace; default: from the file name (.csv, .tsv, else whitespace)
    time: t                        # a time column [s] ... or `dt: 0.01` when there is none
    ground: {column: ch0, units: g}
    floors:                        # bottom to top; absolute accelerations
      - {column: ch1, units: cm/s^2}
      - {column: ch2, units: cm/s^2, sign: -1}   # sensor mounted the other way round
    floor_disp:                    # optional, one per floor
      - {column: d1, units: in}
      - {column: d2, units: in}
    ground_disp: {column: d0, units: in}   # optional: floor_disp are absolute, subtract this
    mass_t: [17.5, 17.5]           # optional (or weight_kN)
    height_mm: [3000, 3000]        # optional
    offset: pre-event              # none | mean | pre-event: remove each channel's static bias
    pre_event_s: 2.0

``configs/columns_example.yaml`` is a complete example (with its table). ``format:`` is the older
name of ``delimiter:`` (still read; any other value than a delimiter is refused). Columns are
named (header row) or 0-based indices (``header: false``). Units are any of
:data:`hlaid.units.ACCELERATION_UNITS` (accelerations) and :data:`hlaid.units.LENGTH_UNITS`
(displacements). An irregular time column is put on a uniform grid
(:func:`hlaid.io._common.uniform_time`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np

from .._inputs import DATA_LINES, read_text
from ..bounds import bounded, check_bounds, with_bounds
from ..config import load_config
from ..errors import InputError, quotable
from ..measurement import Measurement
from ..model.schema import STORY_BOUNDS, WEIGHT_KN
from ..units import acceleration_factor, length_factor, weight_kn_to_mass_t
from ._common import parse_table, remove_offset, uniform_time

_DELIMITERS = {"csv": ",", "tsv": "\t", "whitespace": None}


@dataclass(frozen=True, kw_only=True)
class ChannelSpec:
    """One column: its name or 0-based index, its units and its sign (+1 or -1)."""

    column: str | int = bounded(lo=0, hi=100_000)
    units: str
    sign: float = bounded(1.0, lo=-1.0, hi=1.0)

    def __post_init__(self):
        check_bounds(self)
        if self.sign not in (1.0, -1.0):
            raise InputError(f"sign must be 1 or -1, got {self.sign}")
        if isinstance(self.column, int) and self.column < 0:
            raise InputError(f"column index must be 0 or more, got {self.column}")


@dataclass(frozen=True, kw_only=True)
class ColumnsConfig:
    """Schema of a column-mapped measurement file (see the module docstring)."""

    file: str
    ground: ChannelSpec
    floors: list[ChannelSpec]
    time: str | int | None = bounded(None, lo=0, hi=100_000)
    dt: float | None = bounded(None, lo=1e-6, hi=1.0, unit="s")
    delimiter: Literal["csv", "tsv", "whitespace"] | None = None
    format: str | None = None
    header: bool = True
    comment: str = "#"
    floor_disp: list[ChannelSpec] | None = None
    ground_disp: ChannelSpec | None = None
    mass_t: list[float] | None = with_bounds(STORY_BOUNDS["mass"], None)
    weight_kN: list[float] | None = with_bounds(WEIGHT_KN, None)
    height_mm: list[float] | None = with_bounds(STORY_BOUNDS["height"], None)
    offset: Literal["none", "mean", "pre-event"] = "none"
    pre_event_s: float = bounded(1.0, lo=1e-3, hi=3600.0, unit="s")
    name: str = ""

    def __post_init__(self):
        check_bounds(self)
        if self.format is not None:  # the older name of delimiter
            if self.format not in _DELIMITERS:
                shown = repr(self.format) if quotable(self.format) else "its value"
                raise InputError(f"format: {shown} is not a delimiter; this key (now delimiter:) names how the "
                                 "table's columns are separated: csv, tsv or whitespace (the file is read as a "
                                 "columns table already; leave the key out to tell the delimiter from the file name)")
            if self.delimiter is not None:
                raise InputError("give delimiter only (format is its older name)")
            object.__setattr__(self, "delimiter", self.format)
            object.__setattr__(self, "format", None)
        if (self.time is None) == (self.dt is None):
            raise InputError("give exactly one of time (a time column) or dt (the sample interval in s)")
        if self.dt is not None and not self.dt > 0:
            raise InputError(f"dt must be positive, got {self.dt}")
        if not self.floors:
            raise InputError("floors: list at least one floor channel, bottom to top")
        for spec in [self.ground, *self.floors]:
            _factor(acceleration_factor, spec)
        if self.floor_disp is not None:
            if len(self.floor_disp) != len(self.floors):
                raise InputError(f"floor_disp lists {len(self.floor_disp)} columns but floors lists "
                                 f"{len(self.floors)}; give one displacement per floor")
            for spec in self.floor_disp:
                _factor(length_factor, spec)
        if self.ground_disp is not None:
            if self.floor_disp is None:
                raise InputError("ground_disp needs floor_disp")
            _factor(length_factor, self.ground_disp)
        if self.mass_t is not None and self.weight_kN is not None:
            raise InputError("give mass_t or weight_kN, not both")
        for key in ("mass_t", "weight_kN", "height_mm"):
            v = getattr(self, key)
            if v is not None and len(v) != len(self.floors):
                raise InputError(f"{key} has {len(v)} values but there are {len(self.floors)} floors")
        if self.header is False and any(isinstance(s.column, str) for s in self._specs()):
            raise InputError("with header: false, columns must be 0-based indices")
        if not self.pre_event_s > 0:
            raise InputError(f"pre_event_s must be positive, got {self.pre_event_s}")

    def _specs(self) -> list[ChannelSpec]:
        return [self.ground, *self.floors, *(self.floor_disp or []), *([self.ground_disp] if self.ground_disp else [])]


def _factor(fn, spec: ChannelSpec) -> float:
    try:
        return fn(spec.units)
    except ValueError as err:
        raise InputError(f"column {spec.column!r}: {err}") from None


def _delimiter(cfg: ColumnsConfig, data_path: Path) -> str | None:
    if cfg.delimiter is not None:
        return _DELIMITERS[cfg.delimiter]
    name = data_path.name.lower().removesuffix(".gz")
    if name.endswith(".csv"):
        return ","
    if name.endswith(".tsv"):
        return "\t"
    return None


def load_columns_config(path: str | os.PathLike) -> ColumnsConfig:
    """Load and validate a columns YAML file (unknown keys and wrong types give FILE:LINE errors)."""
    return load_config(path, ColumnsConfig)


def read_columns(config: str | os.PathLike | ColumnsConfig, *, base: str | os.PathLike | None = None,
                 name: str | None = None) -> Measurement:
    """Read a measurement described by a columns config.

    Parameters
    ----------
    config : path of the YAML file, or a :class:`ColumnsConfig`
    base : folder that a relative ``file`` is resolved against (default: the YAML's folder,
        or the working folder for a config object)

    Returns
    -------
    Measurement
        accelerations in mm/s^2 (absolute, signs applied), ``floor_disp`` relative to the
        ground in mm when displacement columns are given, masses [t] and heights [mm] when given.
    """
    if isinstance(config, ColumnsConfig):
        cfg, folder = config, Path(base) if base is not None else Path(".")
    else:
        cfg = load_columns_config(config)
        folder = Path(base) if base is not None else Path(config).parent
    data_path = Path(cfg.file)
    if not data_path.is_absolute():
        data_path = folder / data_path
    src = str(data_path)
    text = read_text(data_path, max_lines=DATA_LINES)  # refused while read beyond HLAID_MAX_SAMPLES rows
    table = parse_table(text, src, delimiter=_delimiter(cfg, data_path), comment=cfg.comment,
                        header=cfg.header)
    specs = [cfg.ground, *cfg.floors]
    acc = np.stack([table.column(s.column, src) * s.sign * acceleration_factor(s.units) for s in specs], axis=1)
    nf = len(cfg.floors)
    disp = None
    if cfg.floor_disp is not None:
        disp = np.stack([table.column(s.column, src) * s.sign * length_factor(s.units) for s in cfg.floor_disp],
                        axis=1)
        if cfg.ground_disp is not None:
            g = cfg.ground_disp
            disp = disp - (table.column(g.column, src) * g.sign * length_factor(g.units))[:, None]
    values = acc if disp is None else np.concatenate([acc, disp], axis=1)
    extra: dict[str, Any]
    if cfg.time is not None:
        axis, values = uniform_time(table.column(cfg.time, src), values, src, column=str(cfg.time))
        dt, extra = axis.dt, {"time_jitter_s": axis.jitter, "resampled": axis.resampled}
    else:
        dt, extra = float(cast(float, cfg.dt)), {}  # dt is given when time is not (checked in the config)
    values, bias = remove_offset(values, dt, cfg.offset, cfg.pre_event_s, src)
    extra["offset_removed"] = bias
    mass = cfg.mass_t if cfg.mass_t is not None else (
        [weight_kn_to_mass_t(w) for w in cfg.weight_kN] if cfg.weight_kN is not None else None)
    # mass and height may be lists: Measurement makes them arrays
    return Measurement(dt=dt, ground_acc=values[:, 0], floor_acc=values[:, 1:1 + nf],
                       floor_disp=None if disp is None else values[:, 1 + nf:], mass=cast("np.ndarray | None", mass),
                       height=cast("np.ndarray | None", cfg.height_mm),
                       source=src, name=name or cfg.name or data_path.name.split(".")[0], extra=extra)
