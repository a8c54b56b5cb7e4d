"""What a decision rests on: one definition of each figure every decision command reports.

``hlaid ida``, ``hlaid demands``, ``hlaid run`` (and ``hlaid demo``), ``hlaid loss`` and ``hlaid
fleet`` turn a clone into a decision. Each prints and stores (``basis`` in its JSON output) a
:class:`DecisionBasis`, built here and nowhere else:

* **The fragility at each recorded event's intensity** (:func:`p_collapse`, the lognormal
  collapse fragility at the event's Sa(T1)): how likely collapse is in ANOTHER record of that
  intensity (:data:`hlaid.ida.ownevent.AT_INTENSITY`). Whether the clone survives the event's own
  motion is the other question, :func:`hlaid.loss.ownmotion.own_motion_check`.
* **Survival contradicted**: that fragility at or above :data:`P_SURVIVED_FLAG` at an event the
  building survived. Not a contradiction by itself (other records of the intensity may be worse),
  but a sign that the clone, its collapse law or the story heights may be wrong there.
* **The drift the building survived** (:meth:`hlaid.clone.Clone.survived_drift`, measured only): per
  story the largest drift MEASURED in the events the clone was identified from, never the clone's
  replay of them. The collapse law is conditioned on the same drifts
  (:mod:`hlaid.model.capacity`).
* **Extrapolation**: the decision's demand (median peak drift ratio) beyond
  :data:`EXTRAPOLATION_MARGIN` times the largest drift ratio the building survived. A clone's
  replay of the very record the building survived misses its peak drifts by about 10 %
  (docs/events.md), which is not extrapolation. A collapse fragility always extrapolates to its
  drift limit, and says from which drift.
* **Assumed heights**: story heights given on the command line or in a config instead of measured.
  Drift ratios, P-Delta and the collapse law rest on them.
* **The clone's own replay error** (:meth:`hlaid.clone.Clone.own_replay_miss`): flagged when its
  worst peak-drift error is larger than :data:`REPLAY_MISS_FLAG`; "not assessed" where the clone
  keeps no record of its replay.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .ownevent import OwnMotionCheck, p_collapse

P_SURVIVED_FLAG = 0.5
"""P(collapse) at the intensity of an event the building survived from which on the figure
contradicts the record more likely than not."""

EXTRAPOLATION_MARGIN = 1.10
"""A decision's median peak drift ratio more than this factor above the largest drift ratio the
building survived is flagged as extrapolated."""

REPLAY_MISS_FLAG = 0.15
"""The clone's replay of its own events missing a story's peak drift by more than this fraction
is flagged."""


@dataclass(frozen=True)
class AtEvent:
    """P(collapse) at the intensity of one event the building survived.

    Attributes
    ----------
    name : the event
    im : its intensity [g] (None: its ground motion was not at hand)
    p_collapse : P(collapse) there (None: not assessed)
    p_collapse_band : the interval of an ensemble (5th to 95th percentile over its members and
        record resamples), or None
    source : whose fragility (the identified clone's IDA, an ensemble of N clones)
    """

    name: str
    im: float | None
    p_collapse: float | None
    p_collapse_band: tuple[float, float] | None = None
    source: str = ""

    @property
    def contradicted(self) -> bool:
        return self.p_collapse is not None and self.p_collapse >= P_SURVIVED_FLAG

    def text(self) -> str:
        p = "not assessed" if self.p_collapse is None else f"{self.p_collapse:.1%}"
        band = "" if self.p_collapse_band is None else \
            f" (90% band {self.p_collapse_band[0]:.1%}-{self.p_collapse_band[1]:.1%})"
        im = "" if self.im is None else f" at {self.im:.3g} g"
        return f"{self.name}{im}: {p}{band}"

    def to_dict(self) -> dict:
        return {"name": self.name, "im": self.im, "p_collapse": self.p_collapse,
                "p_collapse_fragility_at_im": self.p_collapse,
                "question": "P(collapse | another record of the event's intensity), the IDA fragility at its IM",
                "p_collapse_band": None if self.p_collapse_band is None else list(self.p_collapse_band),
                "source": self.source, "contradicts_survival": self.contradicted}


@dataclass(frozen=True)
class DecisionBasis:
    """What a decision figure rests on (see the module doc).

    Attributes
    ----------
    events : P(collapse) at each event the clone recorded
    heights_mm : the story heights the figures use [mm] (None: none known)
    heights_assumed : True where they were given (command line, config), not measured
    survived_mm : the drift each story survived [mm] (:meth:`~hlaid.clone.Clone.survived_drift`,
        measured only; None: not recorded)
    fitted_mm : the drift each story went through in the records or in the clone's replay of them,
        whichever is larger [mm] (the range the clone was fitted on; None: as ``survived_mm``)
    demand_ratio : the decision's median peak drift ratio (None: the command has none)
    drift_limit : the collapse criterion, peak drift ratio (None: the command has none)
    replay_miss : :meth:`~hlaid.clone.Clone.own_replay_miss` (None: not assessed)
    events_note : why P(collapse) at the events is not assessed, where ``events`` is empty
    own_motion : per recorded event, the clone replaying its own motion
        (:class:`~hlaid.ida.ownevent.OwnMotionCheck`: P(collapse | this motion), the residual drift
        beside the measured); empty: not asked
    capacity : the collapse law's capping drift conditioned on what the building survived
        (:meth:`hlaid.model.capacity.CapacityPosterior.to_dict`; None: no law or no heights)
    height_range : where the heights are assumed, ``(factor, OwnMotionCheck)`` of the replay with
        the heights scaled by each factor (:func:`hlaid.loss.ownmotion.height_range`)
    """

    events: tuple[AtEvent, ...] = ()
    heights_mm: tuple[float, ...] | None = None
    heights_assumed: bool = False
    survived_mm: tuple[float, ...] | None = None
    fitted_mm: tuple[float, ...] | None = None
    demand_ratio: float | None = None
    drift_limit: float | None = None
    replay_miss: tuple[float, int, str, tuple[float, float]] | None = None
    events_note: str = "the clone's events' ground motions are not at hand"
    own_motion: tuple = ()
    capacity: dict | None = None
    height_range: tuple = ()

    # ---------------------------------------------------------------- the figures
    @property
    def survived_ratio(self) -> float | None:
        """The largest drift ratio the building survived (over stories); None where unknown."""
        if self.survived_mm is None or self.heights_mm is None or len(self.survived_mm) != len(self.heights_mm):
            return None
        return float(np.max(np.asarray(self.survived_mm) / np.asarray(self.heights_mm)))

    @property
    def fitted_ratio(self) -> float | None:
        """The largest drift ratio of the range the clone was fitted on: the records' or its replay
        of them, whichever is larger (the replay of a survived record is no extrapolation)."""
        f = self.fitted_mm
        if f is None or self.heights_mm is None or len(f) != len(self.heights_mm):
            return self.survived_ratio
        r = float(np.max(np.asarray(f) / np.asarray(self.heights_mm)))
        s = self.survived_ratio
        return r if s is None else max(r, s)

    @property
    def extrapolated(self) -> bool | None:
        """Whether the demand lies beyond :data:`EXTRAPOLATION_MARGIN` times the largest drift ratio
        the clone was fitted on (:attr:`fitted_ratio`; None: not assessed)."""
        s = self.fitted_ratio
        if s is None or self.demand_ratio is None:
            return None
        return bool(self.demand_ratio > EXTRAPOLATION_MARGIN * s)

    @property
    def contradicted(self) -> tuple[AtEvent, ...]:
        """The events the building survived at which P(collapse) >= :data:`P_SURVIVED_FLAG`."""
        return tuple(e for e in self.events if e.contradicted)

    @property
    def replay_flagged(self) -> bool | None:
        """Whether the clone's replay of its own events misses a peak drift by more than
        :data:`REPLAY_MISS_FLAG` (None: not assessed)."""
        return None if self.replay_miss is None else abs(self.replay_miss[0]) > REPLAY_MISS_FLAG

    # ---------------------------------------------------------------- in words
    def flags(self) -> list[str]:
        """One warning per thing that changes the reading of the figures, each saying what to do."""
        out = []
        for e in self.contradicted:
            out.append(f"the fragility gives P(collapse) {e.p_collapse:.0%} for another record of {e.name}'s intensity"
                       + (f" ({e.im:.3g} g)" if e.im is not None else "")
                       + ", an event the building survived: check the story heights (--heights), the collapse law "
                       "(--collapse) and the drift limit before acting on it")
        if self.extrapolated:
            out.append(f"demands extrapolated: median peak drift ratio {self.demand_ratio:.2%}, beyond "
                       f"{EXTRAPOLATION_MARGIN:g} x the largest the clone was fitted on ({self.fitted_ratio:.2%}, "
                       "the records' or its replay of them); "
                       "the clone there follows its law, not the data: treat the figure as an estimate")
        if self.heights_assumed and self.heights_mm is not None:
            out.append("story heights " + ", ".join(f"{v:g}" for v in self.heights_mm) + " mm assumed, not "
                       "measured: drift ratios, P-Delta and the collapse law rest on them; give the building's "
                       "own heights")
        for c in self.own_motion:
            if c.p_collapse is not None and c.p_collapse >= 0.05:
                out.append(f"the clone collapses in {c.p_collapse:.0%} of its replays of {c.name}'s own motion, an "
                           "event the building survived: its collapse law or the story heights contradict the record")
            if c.residual_met is False:
                err = max(c.residual_error or (0.0,), key=abs)
                out.append(f"the clone's replay of {c.name} leaves a residual drift ratio {err:+.2%} off the measured "
                           "(beyond 0.3 %): residual-drift decisions inherit that error")
        cap = self.capacity
        if cap is not None and cap.get("informative") and not cap.get("consistent"):
            out.append(f"collapse law {cap['law']!r}: the drifts the building survived are beyond what such a law "
                       f"allows (prior probability {cap['p_consistent']:.2g}): collapse figures not assessed")
        elif cap is not None and cap.get("informative") and cap.get("p_consistent", 1.0) < 0.05:
            out.append(f"collapse law {cap['law']!r}: the building survived drifts in the law's "
                       f"{cap['p_consistent']:.1%} tail; its capping drift is set by the records "
                       f"(theta_p {cap['theta_p_median']:.3g}), not the literature")
        if self.replay_flagged:
            err, story, event, band = self.replay_miss  # type: ignore[misc]
            out.append(f"the clone's replay of its own event {event} misses story {story + 1}'s peak drift by "
                       f"{err:+.0%} ({_band(band)}): decisions inherit that error; identify again with more "
                       "events or a structural system (--system)")
        return out

    def lines(self) -> list[str]:
        """The short block a command prints (its warnings come from :meth:`flags`)."""
        out = ["what the decision rests on:"]
        if self.events:
            out.append("  P(collapse | another record of the intensity of each event the building survived), the "
                       "fragility at its IM: " + "; ".join(e.text() for e in self.events)
                       + (f" ({self.events[0].source})" if self.events[0].source else ""))
        else:
            out.append("  P(collapse | another record of the intensity of each event the building survived): "
                       f"not assessed ({self.events_note})")
        for c in self.own_motion:
            out.append("  " + c.text())
        for f, c in self.height_range:
            out.append(f"  with the assumed heights x {f:g}: " + c.text())
        cap = self.capacity
        if cap is not None and cap.get("informative"):
            lo, hi = cap["theta_p_90"]
            out.append(f"  collapse law {cap['law']!r} conditioned on the drifts survived: theta_p median "
                       f"{cap['theta_p_median']:.3g} (90 % {lo:.3g}-{hi:.3g}; literature {cap['theta_p_prior']:g}, "
                       f"beta {cap['beta_p']:g})")
        if self.survived_mm is not None:
            s = ", ".join(f"{v:.1f}" for v in self.survived_mm)
            r = self.survived_ratio
            out.append(f"  largest drift survived (measured): {s} mm"
                       + ("" if r is None else f" (up to {r:.2%} of the story height"
                              + (", assumed)" if self.heights_assumed else ")"))
                       + (f"; demand: median peak drift ratio {self.demand_ratio:.2%}, "
                          + ("extrapolated" if self.extrapolated else f"within {EXTRAPOLATION_MARGIN:g} x")
                          if self.demand_ratio is not None and r is not None else "")
                       + (f"; the collapse criterion {self.drift_limit:.0%} is {self.drift_limit / r:.2g} x the "
                          "drift survived (the fragility there rests on the model, not the data)"
                          if self.drift_limit is not None and r else ""))
        else:
            out.append("  largest drift survived: not recorded with the clone (extrapolation not assessed)")
        if self.heights_mm is not None:
            out.append("  story heights: " + ", ".join(f"{v:g}" for v in self.heights_mm) + " mm, "
                       + ("assumed (given, not measured)" if self.heights_assumed else "the clone's own"))
        if self.replay_miss is None:
            out.append("  the clone's replay of its own events: not assessed (no replay record kept with its events)")
        else:
            err, story, event, band = self.replay_miss
            out.append(f"  the clone's replay of its own events: worst peak-drift error {err:+.1%} (story {story + 1}, "
                       f"{event}, {_band(band)})")
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> DecisionBasis:
        """The basis :meth:`to_dict` wrote (a run's ``summary.json``, ``loss.json``)."""
        miss = d.get("replay_miss")
        h, seen, fitted = d.get("heights_mm"), d.get("survived_drift_mm"), d.get("fitted_drift_mm")
        return cls(events=tuple(_at_event(e) for e in d.get("events") or ()),
                   heights_mm=None if h is None else tuple(float(v) for v in h),
                   heights_assumed=bool(d.get("heights_assumed")),
                   survived_mm=None if seen is None else tuple(float(v) for v in seen),
                   fitted_mm=None if fitted is None else tuple(float(v) for v in fitted),
                   demand_ratio=d.get("demand_drift_ratio"), drift_limit=d.get("drift_limit"),
                   replay_miss=None if not miss else (float(miss["error"]), int(miss["story"]) - 1, str(miss["event"]),
                                                      _band_pair(miss.get("band_hz"))),
                   events_note=d.get("events_note") or cls.events_note,
                   own_motion=tuple(_own(c) for c in d.get("own_motion") or ()), capacity=d.get("capacity"),
                   height_range=tuple((float(c["factor"]), _own(c)) for c in d.get("height_range") or ()))

    def to_dict(self) -> dict:
        miss = self.replay_miss
        return {"events": [e.to_dict() for e in self.events],
                "heights_mm": None if self.heights_mm is None else list(self.heights_mm),
                "heights_assumed": self.heights_assumed,
                "survived_drift_mm": None if self.survived_mm is None else list(self.survived_mm),
                "survived_drift_ratio": self.survived_ratio,
                "fitted_drift_mm": None if self.fitted_mm is None else list(self.fitted_mm),
                "fitted_drift_ratio": self.fitted_ratio, "demand_drift_ratio": self.demand_ratio,
                "extrapolation_margin": EXTRAPOLATION_MARGIN, "extrapolated": self.extrapolated,
                "drift_limit": self.drift_limit,
                "survival_contradicted": [e.name for e in self.contradicted],
                "replay_miss": None if miss is None else {"error": miss[0], "story": miss[1] + 1, "event": miss[2],
                                                          "band_hz": list(miss[3])},
                "replay_miss_flagged": self.replay_flagged,
                "events_note": None if self.events else self.events_note,
                "own_motion": [c.to_dict() for c in self.own_motion], "capacity": self.capacity,
                "height_range": [{"factor": f, **c.to_dict()} for f, c in self.height_range],
                "flags": self.flags()}


def _band(band) -> str:
    lo, hi = band
    return "band not recorded" if not (math.isfinite(lo) and math.isfinite(hi)) else f"{lo:.2g}-{hi:.3g} Hz"


def decision_basis(clone, *, events: Iterable[AtEvent | Mapping] = (), heights=None, heights_assumed: bool = False,
                   demand_ratio: float | None = None, drift_limit: float | None = None,
                   events_note: str | None = None, own_motion: Iterable = (), capacity: dict | None = None,
                   height_range: Iterable = ()) -> DecisionBasis:
    """The :class:`DecisionBasis` of a decision taken from ``clone`` (None: no clone at hand, e.g. a
    demand CSV): ``events`` (:class:`AtEvent` or mappings of its fields), the story ``heights``
    used [mm] (None: the clone's), whether they were ``heights_assumed``, the decision's
    ``demand_ratio`` and ``drift_limit``; ``events_note`` why there are no ``events``."""
    evs = tuple(e if isinstance(e, AtEvent) else _at_event(e) for e in events)
    if events_note is None and clone is not None and not clone.events:
        events_note = "the clone records no events it was identified from (an older clone file)"
    h = heights if heights is not None else (None if clone is None else clone.building.height)
    seen = None if clone is None else clone.survived_drift(measured_only=True)
    fitted = None if clone is None else clone.survived_drift()  # the records' or the clone's replay of them
    return DecisionBasis(events=evs, heights_mm=None if h is None else tuple(float(v) for v in h),
                         heights_assumed=bool(heights_assumed and h is not None),
                         survived_mm=None if seen is None else tuple(float(v) for v in seen),
                         fitted_mm=None if fitted is None else tuple(float(v) for v in fitted),
                         demand_ratio=None if demand_ratio is None else float(demand_ratio),
                         drift_limit=drift_limit, replay_miss=None if clone is None else clone.own_replay_miss(),
                         own_motion=tuple(own_motion), capacity=capacity, height_range=tuple(height_range),
                         **({"events_note": events_note} if events_note else {}))


def _at_event(d: Mapping) -> AtEvent:
    band = d.get("p_collapse_band")
    p = d.get("p_collapse_fragility_at_im", d.get("p_collapse"))
    return AtEvent(name=str(d.get("name")), im=None if d.get("im") is None else float(d["im"]),
                   p_collapse=None if p is None else float(p),
                   p_collapse_band=None if band is None else (float(band[0]), float(band[1])),
                   source=str(d.get("source") or ""))


def events_at(motions: Sequence[tuple[str, object]], im_of, median: float | None, beta: float | None,
              source: str) -> tuple[AtEvent, ...]:
    """P(collapse) of the fragility (``median`` [g], ``beta``) at each ``(name, GroundMotion)``, its
    intensity given by ``im_of(motion)`` [g] (a motion None: not assessed)."""
    out = []
    for name, m in motions:
        im = None if m is None else float(im_of(m))
        out.append(AtEvent(name=str(name), im=im, p_collapse=None if im is None else p_collapse(im, median, beta),
                           source=source))
    return tuple(out)


def ida_events(clone, ida, motions: Sequence[tuple[str, object]] | None = None) -> tuple[AtEvent, ...]:
    """P(collapse) of an IDA's collapse fragility (``ida``: an :class:`~hlaid.ida.IDAResult`) at the
    intensity of each of ``clone``'s events (``motions``: ``(name, GroundMotion)``; None: read
    from the events' files where unchanged, :func:`hlaid.events.evidence.event_motions`)."""
    from .measures import intensity

    if motions is None:
        from ..events.evidence import event_motions
        em = event_motions(clone)
        motions = list(zip(em.names, em.motions))
    source = "the identified clone's IDA fragility"
    median: float | None
    beta: float | None
    try:
        frag = ida.collapse_fragility("capacities", n_boot=0)
        median, beta = float(frag.median), float(frag.beta)
    except ValueError as err:
        median = beta = None
        source = f"no collapse fragility: {err}; raise the IDA levels"
    return events_at(motions, lambda m: intensity(m, ida.im, building=ida.building, period=ida.period)[0],
                     median, beta, source)


__all__ = ["AtEvent", "DecisionBasis", "EXTRAPOLATION_MARGIN", "P_SURVIVED_FLAG", "REPLAY_MISS_FLAG", "decision_basis",
           "events_at", "ida_events", "p_collapse"]


def _own(d: Mapping):
    """An :class:`~hlaid.ida.ownevent.OwnMotionCheck` from its :meth:`to_dict`."""
    def t(k):
        v = d.get(k)
        return None if v is None else tuple(float(x) for x in v)
    return OwnMotionCheck(name=str(d.get("name")), in_clone=bool(d.get("in_clone")),
                          p_collapse=d.get("p_collapse_own_motion"), n_runs=int(d.get("n_runs") or 0),
                          peak=t("peak_drift_ratio"), residual=t("residual_drift_ratio"),
                          residual_median=t("residual_drift_ratio_median"),
                          measured_peak=t("measured_peak_drift_ratio"),
                          measured_residual=t("measured_residual_drift_ratio"),
                          heights_assumed=bool(d.get("heights_assumed")), why=str(d.get("why_not_assessed") or ""))


def _band_pair(v) -> tuple[float, float]:
    """A stored ``band_hz`` as ``(lo, hi)`` [Hz]; NaNs where none was stored."""
    lo, hi = (float(x) for x in (v or (math.nan, math.nan)))
    return lo, hi
