"""Survival as evidence: every event a clone was identified from, the building survived.

A clone is identified from records of a building that is still standing. Its ensemble (the
buildings drawn from its posterior, :func:`hlaid.uncertainty.clone_ensemble`) and the nominal clone
must survive those records too, with the collapse law the assessment runs. :func:`survivors` is
the one place this is applied, for every consumer of an ensemble (the ensemble assessment
:func:`hlaid.ida.assess`, the demands :func:`hlaid.loss.clone_demands`, the predictive band of
:func:`hlaid.events.predict_event`, the IDA of the nominal clone, ``hlaid run`` and ``hlaid fleet``):

1. the ground motions of the clone's events (:func:`event_motions`): those passed in (matched to
   the events by sample interval, length and peak), else read again from each event's ``source``
   when the file is unchanged (its SHA-256 as recorded) and holds that event;
2. every building replayed through them in time order, each event from the state the previous
   one left (after a free vibration), the ground low-passed as the identification saw it, with the
   collapse law in force and the IDA's drift limit as the collapse criterion
   (:func:`replay_events`);
3. draws that collapse under an event the building survived are rejected and replaced by new
   draws (rejection sampling: the posterior conditioned on survival), at most
   :data:`MAX_DRAWS_PER_MEMBER` draws per member wanted; the counts are kept.

The collapse law itself is made consistent with the drifts the building survived where the IDA
prepares a clone (:func:`hlaid.model.collapse.accommodate`, called by
:func:`hlaid.ida.prepare_building`): a capping drift below a survived drift is moved to it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import _progress
from ..errors import InputError, escape_controls, one_line
from ..model import Building
from ..model.state import at_rest, settle_time
from ..motions import GroundMotion

if TYPE_CHECKING:
    from ..clone import Clone
    from ..hla import HLAResult
    from ..measurement import Measurement
    from ..record import EventRecord

MAX_DRAWS_PER_MEMBER = 10
"""Rejection sampling draws at most this many candidates per ensemble member wanted."""


def measured_peak_drift(meas: Measurement, hla: HLAResult | None = None) -> list[float] | None:
    """``(story,)`` the largest inter-story drift the building went through in ``meas`` [mm]: the
    larger of HLA's (the drift it analysed, band-passed) and the file's own floor displacements'
    where it has them; None where neither is known."""
    peaks = []
    if hla is not None:
        peaks.append(np.max(np.abs(hla.stacked("drift")), axis=0))
    if meas.floor_disp is not None:
        u = np.asarray(meas.floor_disp, dtype=float)
        drift = np.diff(np.concatenate([np.zeros((u.shape[0], 1)), u], axis=1), axis=1)
        peaks.append(np.nanmax(np.abs(drift), axis=0))
    if not peaks:
        return None
    out = np.max(peaks, axis=0)
    return [float(v) for v in out] if np.all(np.isfinite(out)) else None


# ---------------------------------------------------------------------------- the events' motions
@dataclass(frozen=True, eq=False)
class EventMotions:
    """The ground motions of a clone's events, in time order.

    Attributes
    ----------
    names : every event's name
    motions : per event its ground motion [mm/s^2] (None: not available)
    starts : per event ``"carried"`` or ``"undamaged"`` (where an update found the building
        recovered before it)
    missing : one line per event whose motion is not available, saying why
    """

    names: tuple[str, ...]
    motions: tuple[GroundMotion | None, ...]
    starts: tuple[str, ...]
    missing: tuple[str, ...]

    @property
    def available(self) -> list[tuple[str, GroundMotion]]:
        return [(n, m) for n, m in zip(self.names, self.motions) if m is not None]


def recorded_with(event: EventRecord, motion: GroundMotion) -> bool:
    """Whether ``motion`` is the ground motion ``event`` (a clone's event record) was recorded with."""
    if event.dt is None or event.duration_s is None or event.pga_g is None:
        return False
    dt, dur, pga = float(event.dt), float(event.duration_s), float(event.pga_g)
    if not (dt > 0 and dur > 0):
        return False
    same_peak = abs(motion.pga_g - pga) <= 1e-6 * max(pga, 1e-12)
    return abs(motion.dt / dt - 1.0) < 1e-9 and abs(motion.npts * motion.dt / dur - 1.0) < 1e-6 and same_peak


def read_event(event: EventRecord, base: Path | None = None, name: str | None = None
               ) -> tuple[Measurement | None, str | None]:
    """The measurement of a clone's ``event`` (its record in ``clone.events``) read again from its
    ``source`` (a relative path also from ``base``), checked against the SHA-256 of the file and
    of its ground record where the event keeps them; or None and why not."""
    from .._inputs import file_sha256
    from ..io import read
    from ..measurement import Measurement, ground_digest

    name = escape_controls(name or event.name or "an event")
    src = event.source
    if not src:
        return None, f"{name}: its file (none recorded) is not there"
    path = Path(str(src))
    src = escape_controls(src)  # as the messages show it
    if len(src) > 200:
        src = f"{src[:90]}...{src[-90:]}"
    try:
        if not path.exists() and base is not None and not path.is_absolute():
            path = base / path
        if not path.is_file():
            return None, f"{name}: its file {src} is not found"
    except (OSError, ValueError) as err:  # a name longer than the file system allows, a NUL in it
        return None, f"{name}: its file {src} cannot be looked up ({getattr(err, 'strerror', None) or err})"
    sha = event.sha256
    try:
        if sha and file_sha256(path) != sha:
            return None, f"{name}: its file {src} changed since the clone was identified (SHA-256)"
        meas = read(str(path), "measurement")
    except InputError as err:
        return None, f"{name}: its file could not be read again ({one_line(err, 120)})"
    if not isinstance(meas, Measurement):
        return None, f"{name}: its file {src} holds no measurement"
    if event.ground_sha256 is not None and ground_digest(meas) != event.ground_sha256:
        return None, (f"{name}: {src} is not the event the clone learnt from (SHA-256 of its ground record "
                      "differs)")
    return meas, None


def _read_event(event: EventRecord, base: Path | None) -> tuple[GroundMotion | None, str | None]:
    """The ground motion of ``event`` read again from its source (:func:`read_event`), or None and why not."""
    meas, why = read_event(event, base)
    if meas is None:
        return None, why
    name, src = event.name or "an event", event.source
    motion = meas.ground_motion(name=str(name), source=str(meas.source or src))
    if not recorded_with(event, motion):
        return None, (f"{escape_controls(name)}: its file {escape_controls(src)} read with the default reader does "
                      "not hold this event (a file of several events, or reader options): pass the motion")
    return motion, None


def event_motions(clone: Clone, given: Sequence[GroundMotion | None] = ()) -> EventMotions:
    """The ground motions of ``clone``'s events: a motion of ``given`` matching the event, else
    the event's source file read again when it is unchanged and holds it (see the module doc)."""
    at_hand = [m for m in given if m is not None]
    base = Path(clone.building.source).parent if clone.building.source else None
    names, motions, starts, missing = [], [], [], []
    for k, e in enumerate(clone.events):
        name = e.label(k)
        m = next((g for g in at_hand if recorded_with(e, g)), None)
        why = None
        if m is None:
            m, why = _read_event(e, base)
        names.append(name)
        motions.append(m)
        starts.append("undamaged" if e.start == "undamaged" else "carried")
        if why:
            missing.append(why)
    return EventMotions(names=tuple(names), motions=tuple(motions), starts=tuple(starts), missing=tuple(missing))


# ---------------------------------------------------------------------------- the replay
@dataclass(frozen=True, eq=False)
class EventReplay:
    """Buildings replayed through a clone's events.

    Attributes
    ----------
    collapsed : (building,) the run reached the drift limit or diverged under some event
    first : (building,) index of the first event it collapsed under (-1: none)
    peak : (building, story) largest |drift| over the events [mm] (up to the collapse)
    """

    collapsed: np.ndarray
    first: np.ndarray
    peak: np.ndarray


def input_corner(clone: Clone) -> float | None:
    """The upper corner [Hz] of the band the clone was fitted in (its identification config's
    ``refine.band_hz``), None where the clone does not say."""
    band = None if clone.settings is None else clone.settings.value("refine.band_hz")
    try:
        hi = float(band[1])  # type: ignore[index]  # a missing band is caught below
    except (TypeError, ValueError, IndexError):
        return None
    return hi if hi > 0 else None


def replay_events(buildings: Sequence[Building], motions: Sequence[GroundMotion], *, drift_limit: float = 0.10,
                  max_step: float = 0.0025, starts: Sequence[str] = (), lowpass_hz: float | None = None
                  ) -> EventReplay:
    """Replay ``buildings`` through ``motions`` in time order, each event from the state the
    previous one left after a free vibration (``starts[k] == "undamaged"``: event ``k`` from
    rest), the ground low-passed at ``lowpass_hz`` (None: as given). A building collapses where a
    story's drift ratio passes ``drift_limit`` or the run diverges (stories without heights: only
    where it diverges)."""
    from ..signal import cap_corner, lowpass
    from ..simulate import simulate_response

    n, nb = buildings[0].n_stories, len(buildings)
    heights = [b.height for b in buildings]
    h = None if any(x is None for x in heights) else np.array([np.asarray(x, dtype=float) for x in heights])
    stop = None if h is None else drift_limit * h
    tail = max(settle_time(b) for b in buildings)
    collapsed = np.zeros(nb, dtype=bool)
    first = np.full(nb, -1)
    peak = np.zeros((nb, n))
    y = None
    for k, m in enumerate(motions):
        if lowpass_hz is not None and cap_corner(lowpass_hz, m.dt) < 0.45 / m.dt:
            m = GroundMotion(dt=m.dt, acc=lowpass(np.asarray(m.acc), m.dt, cap_corner(lowpass_hz, m.dt)),
                             name=m.name, source=m.source)
        if k < len(starts) and starts[k] == "undamaged":
            y = None
        sub = max(1, int(np.ceil(m.dt / max_step - 1e-9)))
        r = simulate_response(list(buildings), m, substeps=sub, outputs="peaks", stop_drift=stop, y0=y,
                              free_vibration=tail)
        pk = np.nan_to_num(np.asarray(r.peak_drift, dtype=float), nan=np.inf)
        over = (r.status != 0) | (np.any(pk / h > drift_limit, axis=1) if h is not None else False)
        new = over & ~collapsed
        first[new] = k
        peak = np.where(collapsed[:, None], peak, np.maximum(peak, pk))
        collapsed |= over
        y = at_rest(np.where(np.isfinite(r.final_state), r.final_state, 0.0), n)
    return EventReplay(collapsed=collapsed, first=first, peak=peak)


# ---------------------------------------------------------------------------- the ensemble
@dataclass(frozen=True, eq=False)
class Survival:
    """An ensemble conditioned on the clone's events: the members that survive them.

    Attributes
    ----------
    members : the surviving members (the clone's buildings, not yet prepared for an IDA)
    n_wanted, n_drawn, n_rejected : members asked for, candidates drawn, candidates rejected
        (collapsed under an event the building survived)
    events : the events checked (names, in time order); unchecked : one line per event not
        checked and why
    nominal_survives : the nominal clone survives every event checked (None: none checked)
    nominal_collapsed_in : the event the nominal clone collapses under (None: none)
    nominal_peak : (story,) the nominal clone's largest drift over the events [mm] (None: none checked)
    motions : the events' ground motions (:class:`EventMotions`)
    notes : what was done, in words
    """

    members: tuple[Building, ...]
    n_wanted: int
    n_drawn: int
    n_rejected: int
    events: tuple[str, ...]
    unchecked: tuple[str, ...]
    nominal_survives: bool | None
    nominal_collapsed_in: str | None
    nominal_peak: np.ndarray | None
    motions: EventMotions
    notes: tuple[str, ...]

    def to_dict(self) -> dict:
        """JSON-able counts, events and notes."""
        return {"n_wanted": self.n_wanted, "n_drawn": self.n_drawn, "n_rejected": self.n_rejected,
                "n_members": len(self.members), "events": list(self.events), "unchecked": list(self.unchecked),
                "nominal_survives": self.nominal_survives, "nominal_collapsed_in": self.nominal_collapsed_in,
                "nominal_peak_drift_mm": None if self.nominal_peak is None else self.nominal_peak.tolist(),
                "notes": list(self.notes)}


def _identity(clone: Clone) -> Building:
    return clone.building


def survivors(clone: Clone, n: int, *, seed: int = 0, prepare: Callable[[Clone], Building] | None = None,
              motions: Sequence[GroundMotion | None] = (), drift_limit: float = 0.10, max_step: float = 0.0025,
              max_draws: int | None = None) -> Survival:
    """``n`` members of ``clone``'s ensemble that survive the clone's events, and the nominal
    clone's own check.

    Parameters
    ----------
    clone : the clone (its ``events`` say what it was identified from)
    n : members wanted (0: only the nominal clone is checked)
    seed : of the draws (the first ``n`` draws are :func:`hlaid.uncertainty.clone_ensemble`'s)
    prepare : the building an assessment runs for a clone (P-Delta, heights, the collapse law in
        force: :func:`hlaid.ida.prepare_building` with its settings); None: the clone's building
    motions : ground motions of the events at hand (the run's measurement), matched to the events;
        the others are read from the events' files (:func:`event_motions`)
    drift_limit, max_step : the IDA's collapse drift ratio and largest step [s]
    max_draws : at most this many candidates (None: :data:`MAX_DRAWS_PER_MEMBER` x ``n``)

    Returns
    -------
    Survival. Where no candidate survives, the unconditioned draws are kept and a note says so
    (the evidence and the clone contradict each other: check the story heights, the collapse law).
    """
    from ..uncertainty.ensemble import clone_ensemble

    prep = prepare or _identity
    em = event_motions(clone, motions)
    avail = em.available
    idx = [k for k, m in enumerate(em.motions) if m is not None]
    starts = [em.starts[k] for k in idx]
    corner = input_corner(clone)
    notes = list(em.missing)
    nominal_ok, where, nominal_peak = (_nominal(clone, prep, avail, starts, corner, drift_limit, max_step, notes)
                                       if avail else (None, None, None))
    if n == 0:
        return Survival(members=(), n_wanted=0, n_drawn=0, n_rejected=0, events=tuple(a for a, _ in avail),
                        unchecked=em.missing, nominal_survives=nominal_ok, nominal_collapsed_in=where,
                        nominal_peak=nominal_peak, motions=em, notes=tuple(notes))
    limit = max_draws if max_draws is not None else MAX_DRAWS_PER_MEMBER * n
    if not avail:
        members = clone_ensemble(clone, n, seed=seed)
        return Survival(members=tuple(members), n_wanted=n, n_drawn=n, n_rejected=0, events=(), unchecked=em.missing,
                        nominal_survives=None, nominal_collapsed_in=None, nominal_peak=None, motions=em,
                        notes=tuple(notes + ["survival not checked: no event's ground motion at hand"]))
    kept: list[Building] = []
    drawn = bad = 0
    batch = n
    while len(kept) < n and drawn < limit:
        take = min(batch, limit - drawn)
        cand = clone_ensemble(clone, drawn + take, seed=seed)[drawn:]  # the same stream, extended
        drawn += take
        built = [prep(clone.member(b)) for b in cand]
        rep = replay_events(built, [m for _, m in avail], drift_limit=drift_limit, max_step=max_step,
                            starts=starts, lowpass_hz=corner)
        kept += [b for b, c in zip(cand, rep.collapsed) if not c]
        bad += int(rep.collapsed.sum())
        batch = max(n - len(kept), 1) * 2
    names = ", ".join(a for a, _ in avail)
    members = kept[:n]
    if not kept:
        members = clone_ensemble(clone, n, seed=seed)
        notes.append(f"no member of {drawn} drawn survives {names} with the collapse law in force: the ensemble is "
                     "kept unconditioned (the clone, its law and the records contradict each other; check the story "
                     "heights and the collapse law)")
        _progress.warn(notes[-1])
    else:
        notes.append(f"survival: {len(members)} member(s) kept; {bad} of {drawn} drawn rejected for collapsing under "
                     f"{names} (events the building survived)")
        if len(kept) < n:
            notes.append(f"only {len(kept)} of the {n} members wanted survive after {drawn} draws")
    return Survival(members=tuple(members), n_wanted=n, n_drawn=drawn, n_rejected=bad,
                    events=tuple(a for a, _ in avail), unchecked=em.missing, nominal_survives=nominal_ok,
                    nominal_collapsed_in=where, nominal_peak=nominal_peak, motions=em, notes=tuple(notes))


def _nominal(clone: Clone, prep, avail, starts, corner, drift_limit: float, max_step: float, notes: list[str]):
    """Whether the nominal clone, prepared as the assessment runs it, survives the events at hand
    ``avail`` (``(name, motion)``); the event it collapses in (or None) and its peak drifts
    ``(story,)`` [mm]. A collapse is noted and warned of."""
    nominal = prep(clone)
    _check_drift_limit(clone, nominal, drift_limit)
    rep = replay_events([nominal], [m for _, m in avail], drift_limit=drift_limit, max_step=max_step,
                        starts=starts, lowpass_hz=corner)
    ok = not bool(rep.collapsed[0])
    where = None
    if not ok:
        where = avail[int(rep.first[0])][0]
        notes.append(f"the clone collapses under {where}, an event it was identified from (the building "
                     "survived it): its collapse risk is overstated; check the story heights and the collapse law")
        _progress.warn(notes[-1])
    return ok, where, rep.peak[0]


def _check_drift_limit(clone: Clone, building: Building, drift_limit: float) -> None:
    """Refuse a clone whose measured drifts reach the IDA's drift limit (its collapse criterion)
    at the story heights given: the building survived them, so the heights or the limit are wrong."""
    if building.height is None:
        return
    survived = clone.survived_drift(measured_only=True)
    if survived is None:
        return
    h = np.asarray(building.height, dtype=float)
    ratio = np.asarray(survived) / h
    if np.any(ratio >= drift_limit):
        i = int(np.argmax(ratio))
        drifts = ", ".join(f"{d:.1f}" for d in survived)
        raise InputError(f"the building survived drifts of {drifts} mm (story {i + 1}: {ratio[i]:.1%} of its height "
                         f"{h[i]:g} mm), at or beyond the drift limit {drift_limit:.0%} that counts as collapse: check "
                         "the story heights (heights_mm, --heights) or raise drift_limit",
                         source=building.source or None)


__all__ = ["EventMotions", "EventReplay", "MAX_DRAWS_PER_MEMBER", "Survival", "event_motions", "input_corner",
           "measured_peak_drift", "replay_events", "survivors"]
