"""How a clone's full replay meets its own events: the record each event keeps (``replay``).

A clone is used under the whole ground motion (demands, IDA, collapse, losses rest on its peak
story drifts), so after it is identified each of its own events is replayed from the state the
clone carried into it and compared with what the building recorded in the band the event's floor
records hold (:func:`hlaid.identify.auto.records_band`): per story the signed peak-drift error and
the story-drift correlation (:func:`own_replay`, the contract of
:func:`hlaid.model.schema.check_replay`). :meth:`hlaid.clone.Clone.own_replay_miss` reads the
worst of them back; :func:`summary_line` is what ``hlaid identify`` prints.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..measurement import Measurement
from ..model import Building
from ..model.state import BuildingState
from ..record import EventRecord, OwnReplay


def own_replay(building: Building, meas: Measurement, before: BuildingState | None = None, *,
               mass_normalised: bool = False) -> OwnReplay | None:
    """The replay record of one of a clone's own events: ``building`` replayed under ``meas``
    from ``before`` (None: at rest) and compared in the band the event's floor records hold
    (per story the peak-drift error and the drift R); None
    where the record cannot be compared (too short for the band's filters: a debug note)."""
    from .. import _progress
    from ..clone import Clone
    from ..errors import InputError
    from .predict import predict_event

    clone = Clone(building=building, state=before, mass_normalised=mass_normalised)
    try:
        p = predict_event(clone, meas, start="carried" if before is not None else "undamaged")
    except InputError as err:
        _progress.debug(f"{meas.name or 'an event'}: its full replay is not assessed ({err})")
        return None
    lo, hi = (float(v) for v in p.band_hz)
    return OwnReplay(band_hz=(lo, hi),
                     peak_drift_error=tuple(float(v) for v in np.nan_to_num(p.peak_drift_error, nan=0.0)),
                     drift_r=tuple(float(v) for v in np.nan_to_num(p.drift_r, nan=0.0)))


def with_replays(records: Sequence[EventRecord], building: Building, meas: Sequence[Measurement],
                 befores: Sequence[BuildingState | None], *, mass_normalised: bool = False
                 ) -> tuple[EventRecord, ...]:
    """``records`` (the last ``len(meas)`` of them the records of ``meas``) with each of those
    holding its ``replay`` (:func:`own_replay` from the state in ``befores``)."""
    out = list(records)
    first = len(out) - len(meas)
    for k, (m, y) in enumerate(zip(meas, befores)):
        r = own_replay(building, m, y, mass_normalised=mass_normalised)
        if r is not None:
            out[first + k] = dataclasses.replace(out[first + k], replay=r)
    return tuple(out)


def summary_line(events: Sequence[EventRecord]) -> str | None:
    """One line: per own event the full replay's peak-drift errors (and the band), None where no
    event holds a replay record."""
    parts, band = [], None
    for k, e in enumerate(events):
        r = e.replay
        if r is None or not r.peak_drift_error:
            continue
        band = r.band_hz
        errs = "/".join(f"{100 * float(v):+.0f}" for v in r.peak_drift_error)
        dr = r.drift_r
        parts.append(f"{e.label(k)} {errs} %"
                     + (f" (drift R {float(np.mean(dr)):.2f})" if dr else ""))
    if not parts:
        return None
    where = f" in {band[0]:g}-{band[1]:g} Hz" if band else ""
    return f"full replay of its own events{where}, peak story drift error per story: " + "; ".join(parts)


__all__ = ["own_replay", "with_replays", "summary_line"]
