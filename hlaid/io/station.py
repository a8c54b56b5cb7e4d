"""Seismic station data (miniSEED, SAC, anything ObsPy reads) mapped channel by channel onto floors.

Needs the optional extra ``station`` (``pip install "hlaid[station]"``: ObsPy). A YAML file or
a ``station:`` block of a fleet config says which trace is the ground and which is each floor::

    files: [b001.mseed]              # or several SAC files, one per channel; relative to the YAML
    format: null                     # an ObsPy format name (MSEED, SAC, ...); null: detected
    ground: {channel: XX.B001.00.HNE, units: m/s^2, gain: 1.0}
    floors:                          # bottom to top; absolute accelerations
      - {channel: XX.B001.01.HNE, units: m/s^2}
      - {channel: XX.B001.02.HNE, units: m/s^2, gain: 418600.0}   # raw counts: 418600 counts per m/s^2
    offset: mean                     # none | mean | pre-event
    mass_t: [17.5, 17.5]             # optional (or in the fleet config)
    height_mm: [3000, 3000]          # optional

``channel`` is a SEED id ``NET.STA.LOC.CHA`` (shell wildcards allowed, e.g. ``*.B001.01.HN?``);
it must match exactly one trace of the files. Traces of one channel split into several records
are merged; a gap is an error. Every channel must have the same sample rate; the measurement is
the time window all channels cover.
"""

from __future__ import annotations

import fnmatch
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import _progress
from .._inputs import check_readable_file
from ..bounds import bounded, check_bounds, with_bounds
from ..config import load_config
from ..errors import InputError, quotable
from ..limits import check_count
from ..measurement import Measurement
from ..model.schema import STORY_BOUNDS
from ..units import acceleration_factor
from ._common import remove_offset


@dataclass(frozen=True, kw_only=True)
class StationChannel:
    """One trace: its SEED id (wildcards allowed), the acceleration units of ``samples / gain``,
    the gain (counts per unit; 1 when the samples are already in ``units``) and a sign (+1 or -1)."""

    channel: str
    units: str = "m/s^2"
    gain: float = bounded(1.0, lo=1e-12, hi=1e12)
    sign: float = bounded(1.0, lo=-1.0, hi=1.0)

    def __post_init__(self):
        check_bounds(self)
        if not self.channel.strip():
            raise InputError("channel: give a SEED id NET.STA.LOC.CHA (wildcards * and ? allowed)")
        if not (np.isfinite(self.gain) and self.gain != 0):
            raise InputError(f"gain = {self.gain}; expected a non-zero number (counts per unit)")
        if self.sign not in (1.0, -1.0):
            raise InputError(f"sign must be 1 or -1, got {self.sign}")
        try:
            acceleration_factor(self.units)
        except ValueError as err:
            raise InputError(f"channel {self.channel!r}: units: {err}") from None

    def factor(self) -> float:
        """What a sample is multiplied by to give mm/s^2."""
        return self.sign * acceleration_factor(self.units) / self.gain


@dataclass(frozen=True, kw_only=True)
class StationConfig:
    """Schema of a station mapping (see the module docstring)."""

    files: list[str]
    ground: StationChannel
    floors: list[StationChannel]
    format: str | None = None
    offset: str = "mean"
    pre_event_s: float = bounded(1.0, lo=1e-3, hi=3600.0, unit="s")
    mass_t: list[float] | None = with_bounds(STORY_BOUNDS["mass"], None)
    height_mm: list[float] | None = with_bounds(STORY_BOUNDS["height"], None)
    name: str = ""
    options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        check_bounds(self)
        if not self.files:
            raise InputError("files: list at least one miniSEED/SAC file")
        if not self.floors:
            raise InputError("floors: list at least one floor channel, bottom to top")
        if self.offset not in ("none", "mean", "pre-event"):
            raise InputError(f"offset = {self.offset!r}; expected one of 'none', 'mean', 'pre-event'")
        if not self.pre_event_s > 0:
            raise InputError(f"pre_event_s = {self.pre_event_s}; expected a positive duration [s]")
        for key in ("mass_t", "height_mm"):
            v = getattr(self, key)
            if v is not None and len(v) != len(self.floors):
                raise InputError(f"{key} has {len(v)} values but floors lists {len(self.floors)} channels")


def _obspy():
    try:
        import obspy
    except ImportError:
        raise InputError("reading miniSEED/SAC station data needs ObsPy: pip install \"hlaid[station]\"") from None
    return obspy


def _where(paths: list[Path]) -> str:
    names = [str(p) for p in paths]
    return names[0] if len(names) == 1 else f"{names[0]} (+{len(names) - 1} more file(s))"


def _read_traces(paths: list[Path], fmt: str | None, options: dict) -> list[tuple[Any, Path]]:
    obspy = _obspy()
    out = []
    for p in paths:
        if not p.exists():
            raise InputError("station file not found", source=str(p))
        check_readable_file(p)
        try:
            st = obspy.read(str(p), format=fmt, **options)
        except Exception as err:  # noqa: BLE001 - ObsPy raises many kinds for a file it cannot read
            raise InputError(f"ObsPy cannot read it as {fmt or 'seismic data'} ({type(err).__name__})",
                             source=str(p)) from None
        out += [(tr, p) for tr in st]
    return out


def _id(tr) -> str:
    """A trace id read from a file, for a message (quoted only when it is a plain label)."""
    return tr.id if quotable(tr.id) else "(an unprintable id)"


def _pick(traces, spec: StationChannel, role: str, where: str):
    hits = [(tr, p) for tr, p in traces if fnmatch.fnmatchcase(tr.id, spec.channel)]
    ids = sorted({tr.id for tr, _ in hits})
    label = repr(spec.channel[:60])  # the config's own text (ids read from the files are quoted only if plain)
    if not ids:
        have = sorted({tr.id for tr, _ in traces})
        shown = ", ".join(i for i in have[:12] if quotable(i))
        raise InputError(f"{role}: channel {label} is not in the file(s); they hold {len(have)} channel(s)"
                         + (f": {shown}" if shown else ""), source=where)
    if len(ids) > 1:
        shown = ", ".join(i for i in ids[:6] if quotable(i))
        raise InputError(f"{role}: channel {label} matches {len(ids)} channels ({shown}); "
                         "give one SEED id", source=where)
    obspy = _obspy()
    st = obspy.Stream([tr for tr, _ in hits])
    src = _where(sorted({p for _, p in hits}))
    rates = {float(tr.stats.sampling_rate) for tr in st}
    if len(rates) > 1:
        raise InputError(f"{role}: channel {_id(st[0])} has records at different sample rates {sorted(rates)} Hz",
                         source=src)
    if len(st) > 1:
        try:
            st.merge(method=0, fill_value=None)
        except Exception as err:  # noqa: BLE001
            raise InputError(f"{role}: channel {_id(st[0])}: its records cannot be merged ({type(err).__name__})",
                             source=src) from None
    tr = st[0]
    if len(st) > 1 or np.ma.isMaskedArray(tr.data) and np.ma.getmaskarray(tr.data).any():
        raise InputError(f"{role}: channel {_id(st[0])} has a gap; give gap-free records", source=src)
    return tr, src


def read_station(config: str | os.PathLike | StationConfig, *, base: str | os.PathLike | None = None,
                 mass_t=None, height_mm=None, name: str | None = None) -> Measurement:
    """Read station data (miniSEED/SAC through ObsPy) into a :class:`~hlaid.measurement.Measurement`.

    Parameters
    ----------
    config : path of a station YAML, or a :class:`StationConfig`
    base : folder that relative ``files`` are resolved against (default: the YAML's folder, or
        the working folder for a config object)
    mass_t, height_mm : (floor,) masses [t] and story heights [mm] replacing the config's

    Returns
    -------
    Measurement
        ground and absolute floor accelerations [mm/s^2] on the window all channels cover.

    Raises
    ------
    InputError
        one line naming the file and the channel: a channel missing or ambiguous, a gap,
        different sample rates, no common time window.
    """
    if isinstance(config, StationConfig):
        cfg, folder = config, Path(base) if base is not None else Path(".")
    else:
        cfg = load_config(config, StationConfig)
        folder = Path(base) if base is not None else Path(config).parent
    paths = [Path(f) if Path(f).is_absolute() else folder / f for f in cfg.files]
    where = _where(paths)
    traces = _read_traces(paths, cfg.format, cfg.options)
    specs = [("ground", cfg.ground)] + [(f"floors[{i}]", s) for i, s in enumerate(cfg.floors)]
    check_count(len(cfg.floors), "STORIES", "floor channels", source=where)
    picked = [(role, spec, *_pick(traces, spec, role, where)) for role, spec in specs]
    rate = float(picked[0][2].stats.sampling_rate)
    for role, _spec, tr, src in picked[1:]:
        if abs(float(tr.stats.sampling_rate) / rate - 1) > 1e-9:
            raise InputError(f"{role}: channel {_id(tr)} is sampled at {tr.stats.sampling_rate:g} Hz but the ground "
                             f"channel at {rate:g} Hz; resample first", source=src)
    dt = 1.0 / rate
    t0 = max(tr.stats.starttime for _, _, tr, _ in picked)
    t1 = min(tr.stats.endtime for _, _, tr, _ in picked)
    if t1 - t0 < 16 * dt:
        raise InputError("the channels share no common time window (check the mapping: the channels must be "
                         "recorded during the same event)", source=where)
    n = int(np.floor((t1 - t0) / dt + 1e-6)) + 1
    check_count(n, "SAMPLES", "samples", source=where)
    cols = []
    for role, spec, tr, src in picked:
        shift = (t0 - tr.stats.starttime) / dt
        i0 = int(round(shift))
        if abs(shift - i0) > 0.1:
            _progress.warn(f"{src}: {role}: channel {_id(tr)} is sampled {abs(shift - i0):.2f} samples off the "
                           "ground channel's instants; taken as simultaneous")
        data = np.asarray(tr.data[i0:i0 + n], dtype=np.float64)
        if data.size < n:
            raise InputError(f"{role}: channel {_id(tr)} ends before the common window", source=src)
        if not np.all(np.isfinite(data)):
            raise InputError(f"{role}: channel {_id(tr)} has NaN or inf samples", source=src)
        cols.append(data * spec.factor())
    values = np.stack(cols, axis=1)
    values, bias = remove_offset(values, dt, cfg.offset, cfg.pre_event_s, where)
    mass = mass_t if mass_t is not None else cfg.mass_t
    height = height_mm if height_mm is not None else cfg.height_mm
    extra = {"channels": [tr.id for _, _, tr, _ in picked], "starttime": str(t0), "offset_removed": bias}
    # mass and height may be lists: Measurement makes them arrays
    return Measurement(dt=dt, ground_acc=values[:, 0], floor_acc=values[:, 1:],
                       mass=cast("np.ndarray | None", mass), height=cast("np.ndarray | None", height),
                       source=where, name=name or cfg.name or paths[0].name.split(".")[0], extra=extra)


__all__ = ["StationChannel", "StationConfig", "read_station"]
