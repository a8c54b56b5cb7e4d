"""Measurements: ground and floor accelerations of a building, from a file or a simulation.

:meth:`Measurement.save` writes hlaid's NPZ or CSV layout (described in :mod:`hlaid.io.native`);
:func:`hlaid.io.read` reads it back, and the other formats of :mod:`hlaid.io`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._fileio import atomic_write, write_npz
from .errors import InputError
from .limits import check_count
from .model import Building
from .model.schema import STORY_BOUNDS
from .motions.record import GroundMotion
from .record import EventRecord
from .units import G_MM_S2

TRUTH_FIELDS = ("disp", "drift", "force", "z", "eta")
MIN_SAMPLES = 16
PGA_PLAUSIBLE_MM_S2 = (10.0, 5.0 * G_MM_S2)
"""A ground PGA outside this range [mm/s^2] (0.001 g to 5 g) means the units are almost surely wrong:
a record in g or m/s^2 read as mm/s^2 falls far below it, one in mm/s^2 read as g far above."""
RATE_LIMITS_HZ = (5.0, 100_000.0)
"""Hard limits of a measurement's sample rate ``1/dt`` [Hz]. Outside them ``dt`` is surely wrong
(milliseconds read as seconds, a time column in samples or in ms) and the measurement is refused:
below 5 Hz the modes of a building (0.1-10 Hz) cannot be resolved, above 100 kHz no accelerometer
network records (and ``k0`` identified at a wrong rate is wrong by the rate ratio squared)."""
RATE_USUAL_HZ = (20.0, 2_000.0)
"""Sample rates of structural monitoring and shake-table records (50-1000 Hz typically). A rate
inside :data:`RATE_LIMITS_HZ` but outside this range is read with a warning: check ``dt``."""


@dataclass(frozen=True, eq=False)
class Truth:
    """Noise-free response of a simulated measurement, each ``(time, story)``."""

    building: Building
    disp: np.ndarray
    drift: np.ndarray
    force: np.ndarray
    z: np.ndarray
    eta: np.ndarray


@dataclass(frozen=True, eq=False)
class Measurement:
    """Accelerations recorded at the ground and at every floor of a building.

    Attributes
    ----------
    dt : sample interval [s]
    ground_acc : (time,) ground acceleration [mm/s^2]
    floor_acc : (time, floor) absolute floor accelerations [mm/s^2], bottom to top
    mass : (floor,) floor masses [t], or None when unknown (mass-normalised analysis)
    height : (story,) story heights [mm], or None
    pdelta : whether the story forces carry the P-Delta share ``-P x / h`` (None: when
        heights are known, as for a real building)
    truth : the noise-free response when the data were simulated
    noise_rms : the noise level of simulated data (fraction of channel RMS)
    floor_disp : (time, floor) floor displacements relative to the ground [mm] when the data
        include measured displacements (e.g. shake-table LVDTs), else None
    source : file the data came from, named in error messages
    name : a label (the file's stem by default)
    recorded : when the record starts, ISO 8601 (``2018-01-04T10:39:37Z``), where the file says;
        events of one building must be given in this order
    """

    dt: float
    ground_acc: np.ndarray
    floor_acc: np.ndarray
    mass: np.ndarray | None = None
    height: np.ndarray | None = None
    pdelta: bool | None = None
    truth: Truth | None = None
    noise_rms: float | None = None
    floor_disp: np.ndarray | None = None
    source: str = ""
    name: str = ""
    extra: dict = field(default_factory=dict, repr=False)
    recorded: str | None = None

    def __post_init__(self):
        src = self.source or None
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise InputError(f"dt = {self.dt}; expected a positive sample interval in seconds", source=src)
        lo, hi = RATE_LIMITS_HZ
        if not lo <= 1.0 / self.dt <= hi:
            raise InputError(f"dt = {self.dt:g} s is a sample rate of {1.0 / self.dt:.3g} Hz, outside the {lo:g} Hz "
                             f"to {hi:g} Hz of structural records; check dt (seconds per sample)", source=src)
        for name in ("ground_acc", "floor_acc"):
            if np.iscomplexobj(getattr(self, name)):
                raise InputError(f"{name} holds complex numbers; expected real accelerations", source=src)
        g = np.asarray(self.ground_acc, dtype=np.float64)
        f = np.asarray(self.floor_acc, dtype=np.float64)
        if g.ndim != 1:
            raise InputError(f"ground_acc has shape {g.shape}; expected (time,)", source=src)
        if f.ndim == 1:
            f = f[:, None]
        if f.ndim != 2 or f.shape[1] == 0:
            raise InputError(f"floor_acc has shape {f.shape}; expected (time, floor) with at least one floor",
                             source=src)
        if f.shape[0] != g.shape[0]:
            raise InputError(f"floor and ground channels have different lengths ({f.shape[0]} and {g.shape[0]} "
                             "samples); they must share one time axis", source=src)
        if g.shape[0] < MIN_SAMPLES:
            raise InputError(f"record has {g.shape[0]} samples; expected at least {MIN_SAMPLES}", source=src)
        check_count(g.shape[0], "SAMPLES", "samples", source=src)
        check_count(f.shape[1], "STORIES", "floor channels", source=src)
        for name, a in (("ground_acc", g), ("floor_acc", f)):
            bad = ~np.isfinite(a)
            if bad.any():
                i = int(np.argwhere(bad)[0][0])
                raise InputError(f"{name} has {int(bad.sum())} NaN or inf samples (first at t = {i * self.dt:g} s)",
                                 source=src)
        pga = np.abs(g).max()
        lo, hi = PGA_PLAUSIBLE_MM_S2
        if not lo <= pga <= hi:
            raise InputError(f"ground_acc peak is {pga:.3g} mm/s^2 ({pga / G_MM_S2:.3g} g), not a plausible "
                             "earthquake; check the units (expected mm/s^2)", source=src)
        if self.floor_disp is not None:
            d = np.asarray(self.floor_disp, dtype=np.float64)
            d = d[:, None] if d.ndim == 1 else d
            if d.shape != f.shape:
                raise InputError(f"floor_disp has shape {d.shape}; expected {f.shape} like floor_acc", source=src)
            if not np.all(np.isfinite(d)):
                raise InputError("floor_disp has NaN or inf samples", source=src)
            d.setflags(write=False)
            object.__setattr__(self, "floor_disp", d)
        for name in ("mass", "height"):
            a = getattr(self, name)
            if a is None:
                continue
            a = np.asarray(a, dtype=np.float64).reshape(-1)
            if np.all(np.isnan(a)):
                object.__setattr__(self, name, None)
                continue
            if a.shape[0] != f.shape[1]:
                raise InputError(f"{name} has {a.shape[0]} values but there are {f.shape[1]} floor channels",
                                 source=src)
            wrong = np.flatnonzero(~(np.isfinite(a) & (a > 0)))
            if wrong.size:
                more = f" (and {wrong.size - 1} more)" if wrong.size > 1 else ""
                raise InputError(f"{name} must be positive numbers: {name}[{wrong[0]}] = {a[wrong[0]]:g}{more}",
                                 source=src)
            bad = STORY_BOUNDS[name].offending(a)
            if bad is not None:
                raise InputError(STORY_BOUNDS[name].message(f"{name}[{bad[0]}]", bad[1]), source=src)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        g.setflags(write=False)
        f.setflags(write=False)
        object.__setattr__(self, "ground_acc", g)
        object.__setattr__(self, "floor_acc", f)

    @property
    def n_floors(self) -> int:
        return int(self.floor_acc.shape[1])

    @property
    def n_samples(self) -> int:
        return int(self.ground_acc.shape[0])

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.n_samples) * self.dt

    @property
    def mass_known(self) -> bool:
        return self.mass is not None

    @property
    def pdelta_active(self) -> bool:
        return bool(self.height is not None if self.pdelta is None else self.pdelta)

    def ground_motion(self, name: str | None = None, source: str | None = None) -> GroundMotion:
        """The recorded ground acceleration as a :class:`~hlaid.motions.GroundMotion` (as recorded,
        unfiltered), named ``name`` (None: the measurement's name, or ``"measured"``), from
        ``source`` (None: the measurement's file)."""
        return GroundMotion(dt=self.dt, acc=self.ground_acc, name=(self.name or "measured") if name is None else name,
                            source=self.source if source is None else source)

    # ------------------------------------------------------------------ writing
    def _columns(self) -> dict[str, np.ndarray]:
        d = {"dt": np.float64(self.dt), "ground_acc": self.ground_acc, "floor_acc": self.floor_acc,
             "mass": self.mass if self.mass is not None else np.full(self.n_floors, np.nan)}
        if self.height is not None:
            d["height"] = self.height
        if self.noise_rms is not None:
            d["noise_rms"] = np.float64(self.noise_rms)
        if self.pdelta is not None:
            d["pdelta"] = np.bool_(self.pdelta)
        if self.recorded is not None:
            d["recorded"] = np.array(str(self.recorded))
        if self.floor_disp is not None:
            d["floor_disp"] = self.floor_disp
        if self.truth is not None:
            for k in TRUTH_FIELDS:
                d[f"true_{k}"] = getattr(self.truth, k)
            d["true_params"] = np.array(json.dumps(self.truth.building.to_dict()))
        return d

    def save(self, path: str | os.PathLike, *, force: bool = False) -> Path:
        """Write NPZ or CSV (by extension), atomically; an existing file is replaced only with
        ``force``."""
        path = Path(path)
        if path.suffix.lower() == ".csv":
            return atomic_write(path, lambda tmp: tmp.write_text(self._csv_text()), force=force)
        return write_npz(path, self._columns(), force=force)

    def _csv_text(self) -> str:
        n = self.n_floors
        head = ["# hlaid measurement (accelerations in mm/s^2, absolute)", f"# dt_s: {self.dt!r}"]
        if self.mass is not None:
            head.append("# mass_t: " + ", ".join(repr(float(m)) for m in self.mass))
        if self.height is not None:
            head.append("# height_mm: " + ", ".join(repr(float(h)) for h in self.height))
        if self.noise_rms is not None:
            head.append(f"# noise_rms: {self.noise_rms!r}")
        if self.pdelta is not None:
            head.append(f"# pdelta: {str(self.pdelta).lower()}")
        if self.recorded is not None:
            head.append(f"# recorded: {self.recorded}")
        cols = [self.time[:, None], self.ground_acc[:, None], self.floor_acc]
        names = ["time_s", "ground_acc"] + [f"floor_acc_{j + 1}" for j in range(n)]
        if self.floor_disp is not None:
            cols.append(self.floor_disp)
            names += [f"floor_disp_{j + 1}" for j in range(n)]
        if self.truth is not None:
            head.append("# true_params: " + json.dumps(self.truth.building.to_dict()))
            for k in TRUTH_FIELDS:
                cols.append(getattr(self.truth, k))
                names += [f"true_{k}_{j + 1}" for j in range(n)]
        data = np.hstack(cols)
        body = "\n".join(",".join(repr(float(x)) for x in row) for row in data)
        return "\n".join(head) + "\n" + ",".join(names) + "\n" + body + "\n"


def building_name(meas: Measurement) -> str:
    """What the building a measurement is of is called (a clone identified from it takes the name):
    the simulated building's name, else the folder its file lies in (a building's records kept
    together, e.g. ``shake_table_3story_steel_mrf_fixedbase``; the folder itself for a folder of
    channels), else the measurement's own name. Not the event's name: the clone outlives its first
    event."""
    if meas.truth is not None and meas.truth.building.name:
        return meas.truth.building.name
    src = meas.source
    if src and ":" not in src.split(os.sep)[0]:  # a file or folder, not simulated:... or builtin:...
        p = Path(src).absolute()
        name = p.name if p.is_dir() else p.parent.name
        if name:
            return name
    return meas.name


def warn_unusual_rate(meas: Measurement) -> None:
    """Warn (loudly: always shown) when the sample rate is legal but outside :data:`RATE_USUAL_HZ`."""
    rate = 1.0 / meas.dt
    lo, hi = RATE_USUAL_HZ
    if not lo <= rate <= hi:
        from . import _progress
        _progress.warn(f"{meas.source or 'measurement'}: dt = {meas.dt:g} s is a sample rate of {rate:.6g} Hz, unusual "
                       f"for structural records ({lo:g} to {hi:g} Hz); check dt: identified stiffnesses scale with "
                       "the rate squared")


def check_band(meas: Measurement, band_hz, field: str, *, default=None) -> None:
    """Refuse band-pass corners ``band_hz`` (the setting ``field``, e.g. ``"hla.preprocess.band_hz"``)
    that are not finite, whose low corner is not below 0.45 x the sample rate of ``meas`` or, where
    the corners were given (not the setting's ``default``, which is capped there), whose high
    corner is above it: before a filter design fails on them, and instead of changing them.
    ``None`` and ``"auto"`` (chosen from the record) pass."""
    if band_hz is None or isinstance(band_hz, str):
        return
    from .signal import max_corner, min_corner

    lo, hi = (float(v) for v in band_hz)
    src = meas.source or None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(f"{field}: corners {lo:g} {hi:g} Hz; expected finite frequencies", source=src)
    top = max_corner(meas.dt)
    rule = f"{top:.4g} Hz (0.9 x the Nyquist frequency of this {1.0 / meas.dt:.4g} Hz measurement)"
    if not lo < top:
        raise InputError(f"{field}: low corner {lo:g} Hz is not below {rule}; lower it", source=src)
    low = min_corner(meas.dt)
    if hi < low or 0 < lo < low or lo < 0 or not lo < hi:
        raise InputError(f"{field}: corners {lo:g} {hi:g} Hz; expected 0 (no high-pass) or at least {low:g} Hz for the "
                         f"low corner, and a high corner above it of at least {low:g} Hz", source=src)
    given = default is None or isinstance(default, str) or tuple(float(v) for v in default) != (lo, hi)
    if given and hi > top:
        raise InputError(f"{field}: high corner {hi:g} Hz is above {rule}, the highest corner hlaid uses; lower "
                         "it", source=src)


def check_series(measurements) -> None:
    """One line (InputError naming the file) where the measurements cannot be events of one
    building in time order: another number of floors, other masses or story heights, one record
    given twice, or start times (where the files give them) out of order. Needs numpy only: it
    runs before the identification's libraries load."""
    first = measurements[0]
    for m in measurements[1:]:
        where = m.source or m.name or None
        if m.n_floors != first.n_floors:
            raise InputError(f"{m.n_floors} floor channels, but {first.source or first.name or 'the first event'} "
                             f"has {first.n_floors}: the events must be records of one building", source=where)
        for name in ("mass", "height"):
            a, b = getattr(first, name), getattr(m, name)
            if (a is None) != (b is None) or (a is not None and not np.allclose(a, b, rtol=1e-6)):
                raise InputError(f"its floor {name}es differ from the first event's: the events must be records "
                                 "of one building", source=where)
    times = [m.recorded for m in measurements]
    if all(t is not None for t in times):
        for a, b in zip(measurements[:-1], measurements[1:]):
            if str(b.recorded) <= str(a.recorded):
                raise InputError(f"recorded {b.recorded}, not after the previous event ({a.recorded}): give the events "
                                 "in time order", source=b.source or b.name or None)
    seen: dict[str, Measurement] = {}
    for m in measurements:
        key = ground_digest(m)
        if key in seen:
            raise InputError(f"the same ground motion as {seen[key].source or seen[key].name or 'an earlier event'}: "
                             "each event once", source=m.source or m.name or None)
        seen[key] = m


def check_moving(meas: Measurement) -> None:
    """Refuse a measurement whose ground or a floor channel is constant (every sample the same):
    no record of a shaken building, and its replay's correlations would be NaN. The commands that
    analyse a measurement call it; the readers do not (a channel may be read to be looked at)."""
    if not isinstance(meas, Measurement):
        return
    src = meas.source or None
    g, f = np.asarray(meas.ground_acc), np.asarray(meas.floor_acc)
    if np.ptp(g) == 0:
        raise InputError(f"ground_acc is constant ({float(g[0]):g} mm/s^2 at every sample): not a record of "
                         "ground motion", source=src)
    still = [j + 1 for j in range(f.shape[1]) if np.ptp(f[:, j]) == 0]
    if still:
        v = float(f[0, still[0] - 1])
        raise InputError(f"floor_acc of floor {still[0]} is constant ({v:g} mm/s^2 at every sample): no floor of a "
                         "shaken building keeps still; check the channel", source=src)
    pga = float(np.abs(g).max())
    peaks = np.abs(f).max(axis=0)
    worst = int(np.argmax(peaks))
    if peaks[worst] > FLOOR_AMPLIFICATION_MAX * pga:
        raise InputError(f"floor_acc of floor {worst + 1} peaks at {peaks[worst]:.3g} mm/s^2, {peaks[worst] / pga:.3g} "
                         f"times the ground's peak ({pga:.3g} mm/s^2): no building amplifies the ground more than "
                         f"{FLOOR_AMPLIFICATION_MAX:g} times; check that channel's units and scale (and a spike in it)",
                         source=src)


FLOOR_AMPLIFICATION_MAX = 50.0
"""Largest ratio of a floor's peak acceleration to the ground's that :func:`check_moving` accepts:
buildings amplify the ground a few times (10-20 at resonance under a weak record); a floor 1000x
the ground is a channel in other units, scaled, or a spike."""


def ground_digest(meas: Measurement) -> str:
    """SHA-256 of the ground record's samples (float64): the same event, however its file was written."""
    return hashlib.sha256(np.ascontiguousarray(meas.ground_acc, dtype=np.float64).tobytes()).hexdigest()


PROFILE_WINDOWS = 32
"""Windows of :func:`ground_profile`."""

PROFILE_TOL = 0.02
"""Largest difference of two :func:`ground_profile` s of one record written differently (rounded
to 6 digits, trimmed or padded by a sample, scaled by 1 + 1e-12: under 1e-3)."""


def ground_profile(meas: Measurement) -> list[float]:
    """The ground record's RMS in :data:`PROFILE_WINDOWS` equal windows over its duration, as a
    fraction of its overall RMS (4 decimals): the same for one record however it was written (a
    sample more or less, rounded, rescaled by a hair), different for different records even of one
    peak and duration."""
    g = np.asarray(meas.ground_acc, dtype=np.float64)
    total = float(np.sqrt(np.mean(g * g))) or 1.0
    edges = np.linspace(0, g.size, PROFILE_WINDOWS + 1).round().astype(int)
    return [round(float(np.sqrt(np.mean(g[a:b] ** 2))) / total, 4) if b > a else 0.0
            for a, b in zip(edges[:-1], edges[1:])]


def _same_record(e: EventRecord, meas: Measurement) -> bool:
    """Whether ``meas`` holds the ground record of the clone's event ``e`` written differently: the
    same sample interval, a duration within 2 samples, a peak within 0.1 % and the same
    :func:`ground_profile` (a clone that kept none: not told this way)."""
    prof = e.ground_profile
    if prof is None or e.pga_g is None or e.dt is None or e.duration_s is None:
        return False
    if not math.isclose(e.dt, meas.dt, rel_tol=1e-6):
        return False
    if abs(e.duration_s - meas.n_samples * meas.dt) > 2.01 * meas.dt:
        return False
    pga = float(np.max(np.abs(meas.ground_acc)) / G_MM_S2)
    if not math.isclose(e.pga_g, pga, rel_tol=1e-3):
        return False
    mine = ground_profile(meas)
    return len(mine) == len(prof) and max(abs(a - b) for a, b in zip(mine, prof)) <= PROFILE_TOL


def check_not_learnt(events: Sequence[EventRecord], meas: Measurement | None = None, sha256: str | None = None,
                     source: str | None = None) -> None:
    """Refuse an event a clone has learnt from already (``events``: its ``events[]`` records): the
    same file (``sha256`` of the file at ``source``) or the same ground record (``meas``), also
    written differently (rounded, a sample trimmed or padded, rescaled by a hair:
    :func:`ground_profile`), also in a clone that kept no digest of its ground record (same peak,
    duration and sample interval)."""
    for k, e in enumerate(events):
        name = e.label(k)
        same = sha256 is not None and e.sha256 == sha256
        if meas is not None and not same:
            if e.ground_sha256 is not None:
                same = e.ground_sha256 == ground_digest(meas) or _same_record(e, meas)
            elif e.pga_g is not None and e.dt is not None and e.duration_s is not None:
                pga = float(np.max(np.abs(meas.ground_acc)) / G_MM_S2)
                same = (math.isclose(e.pga_g, pga, rel_tol=1e-9) and math.isclose(e.dt, meas.dt, rel_tol=1e-9)
                        and math.isclose(e.duration_s, meas.n_samples * meas.dt, rel_tol=1e-9))
        if same:
            raise InputError(f"the clone has learnt from this event already ({name}, its event {k + 1}): each event "
                             "once", source=source or (meas.source if meas is not None else None) or None)


MASS_RTOL = 0.01
"""Floor masses of a measurement may differ this much (relative) from its clone's."""


def check_of_building(meas: Measurement, building: Building, *, mass_normalised: bool = False,
                      what: str = "the clone") -> None:
    """Refuse a measurement that is not of ``building``: another number of floors, or floor masses
    (where both are known, and the clone's are not normalised) more than :data:`MASS_RTOL` off."""
    src = meas.source or None
    if meas.n_floors != building.n_stories:
        raise InputError(f"{meas.n_floors} floor channels, but {what} has {building.n_stories} stories: the "
                         "measurement is not of this building", source=src)
    if meas.mass is not None and not mass_normalised:
        ratio = np.asarray(meas.mass) / np.asarray(building.mass)
        worst = int(np.argmax(np.abs(ratio - 1.0)))
        if abs(ratio[worst] - 1.0) > MASS_RTOL:
            raise InputError(f"floor {worst + 1}'s mass is {float(meas.mass[worst]):.4g} t, {what}'s "
                             f"{float(building.mass[worst]):.4g} t: the measurement is not of this building",
                             source=src)


def measured_ground(meas: Measurement, hi_hz: float, *, name: str = "measured") -> GroundMotion:
    """The ground acceleration of ``meas`` low-passed (zero phase, order 4) at ``hi_hz`` [Hz]:
    the input under which a clone is replayed against the measured floors.

    ``hi_hz`` is used as given; pass ``cap_corner(band[1], meas.dt)`` for the Nyquist rule.
    """
    from .signal import lowpass  # scipy: only where a ground motion is filtered

    return GroundMotion(dt=meas.dt, acc=lowpass(np.asarray(meas.ground_acc), meas.dt, hi_hz), name=name)
