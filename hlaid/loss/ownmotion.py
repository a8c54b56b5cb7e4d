"""The clone and its posterior ensemble replaying a recorded event's own ground motion: the one
computation of ``P(collapse | the event's own motion)`` and of the replay's residual drift beside
the measured one (:class:`hlaid.ida.ownevent.OwnMotionCheck`), for every recorded event of a
building (:func:`event_checks`) and, where the story heights are assumed, at 0.8 and 1.2 x them
(:func:`height_range`). The replays are the demands of :func:`hlaid.loss.clone_demands`.
"""

from __future__ import annotations

import numpy as np

from ..ida.ownevent import OwnMotionCheck, check_of_demands, measured_drift_ratios


def own_motion_check(clone, name: str, motion, *, measured=None, ida_config=None, n_ensemble: int = 0,
                     seed: int = 0, in_clone: bool = False, heights_assumed: bool = False) -> OwnMotionCheck:
    """Replay ``motion`` (a recorded event's own ground motion) with ``clone`` (and ``n_ensemble``
    members of its posterior conditioned on the events it survived): the one computation of
    ``P(collapse | this motion)`` and of the replay's residual drift. ``measured``: ``(peak,
    residual)`` ``(story,)`` drift ratios of the record (None: unknown)."""
    from ..errors import InputError
    from .demands import clone_demands

    try:
        d0 = clone_demands(clone, [motion], n_ensemble=0, ida_config=ida_config, event_motions=[motion])
        d = None
        if n_ensemble and getattr(clone, "uncertainty", None) is not None:
            d = clone_demands(clone, [motion], n_ensemble=n_ensemble, seed=seed, ida_config=ida_config,
                              event_motions=[motion])
    except InputError as err:
        return OwnMotionCheck(name=name, in_clone=in_clone, p_collapse=None, why=str(err))
    return check_of_demands(name, d0, d, measured=measured, in_clone=in_clone, heights_assumed=heights_assumed)


def recorded_events(clone, extra=(), *, at_hand=(), read_options=None):
    """Every recorded event of ``clone``'s building: its own events (a measurement of ``at_hand``
    holding the event, else read again from its file, :func:`hlaid.events.evidence.read_event`) and
    the measurements ``extra`` (files or Measurements of later events it was not identified from);
    per event ``(name, measurement or None, in_clone, why)``."""
    from pathlib import Path

    from ..events.evidence import read_event, recorded_with
    from ..io import read
    from ..measurement import Measurement

    base = Path(clone.building.source).parent if clone.building.source else None
    out = []
    for k, e in enumerate(clone.events):
        meas = next((m for m in at_hand if recorded_with(e, m.ground_motion())), None)
        why = None
        if meas is None:
            meas, why = read_event(e, base)
        out.append((e.label(k), meas, True, why or ""))
    for x in extra:
        meas = x if isinstance(x, Measurement) else read(str(x), "measurement", **(read_options or {}))
        out.append((str(meas.name or Path(str(x)).name), meas, False, ""))
    return out


def event_checks(clone, events, *, ida_config, heights, heights_assumed: bool, n_ensemble: int = 0,
                 seed: int = 0) -> tuple[OwnMotionCheck, ...]:
    """:func:`own_motion_check` of every ``(name, measurement, in_clone, why)`` of
    :func:`recorded_events`, the measured drift ratios over ``heights`` beside."""
    out = []
    for name, meas, in_clone, why in events:
        if meas is None:
            out.append(OwnMotionCheck(name=name, in_clone=in_clone, p_collapse=None, heights_assumed=heights_assumed,
                                      why=why or "its record is not at hand"))
            continue
        motion = meas.ground_motion(name=name)
        out.append(own_motion_check(clone, name, motion, measured=measured_drift_ratios(meas, heights),
                                    ida_config=ida_config, n_ensemble=n_ensemble, seed=seed, in_clone=in_clone,
                                    heights_assumed=heights_assumed))
    return tuple(out)


HEIGHT_FACTORS = (0.8, 1.2)
"""Where story heights are assumed, the decisions resting on them are shown at these multiples too."""


def height_range(clone, name: str, meas, *, ida_config, heights, factors=HEIGHT_FACTORS, in_clone: bool = False
                 ) -> tuple[tuple[float, OwnMotionCheck], ...]:
    """The identified clone replaying ``meas``'s own motion with its assumed story ``heights``
    scaled by each of ``factors`` (drift ratios, P-Delta and the collapse law rest on them), the
    measured drift ratios over the same heights beside: ``((factor, OwnMotionCheck), ...)``."""
    h = np.asarray(heights, dtype=float)
    out = []
    for f in factors:
        cfg = ida_config.replace(heights_mm=[float(v) for v in f * h])
        out.append((float(f), own_motion_check(clone, name, meas.ground_motion(name=name),
                                               measured=measured_drift_ratios(meas, f * h), ida_config=cfg,
                                               in_clone=in_clone, heights_assumed=True)))
    return tuple(out)


__all__ = ["HEIGHT_FACTORS", "event_checks", "height_range", "own_motion_check", "recorded_events"]
