"""What carries between events: the start of the next prediction, chosen by the events already seen.

A clone carries the state its last event left the building in (its degradation, residual drift
and hysteretic displacement). Whether the next event starts from it or from rest is a question
the building answers event by event: damage that is real carries over; softening that recovers
between events (most buildings in small events) does not. No fixed answer is safe (carried
loses up to 0.13 of R where the building recovered, from rest up to 0.24 where the damage was
real), so the clone keeps score (prequential: each event predicted by the clone of the events
before it, from both starts) and the rule is

- carried where, over the events already predicted, the carried start's mean R beat the
  from-rest start's by more than :data:`MARGIN`;
- from rest otherwise, and where no event has been predicted yet.

Measured on every series at hand (docs/events.md), this was never worse than from rest by more
than the margin, and kept the carried start where the damage was real. Each event after the
first records how the clone before it predicted it (``clone.events[k].prequential``), and the
clone its rule's choice with the reason (``clone.start_rule``), which
:func:`hlaid.events.start.resolve_start` reads for ``start="auto"``. :func:`hlaid.identify_clone`
fits the prefixes of its records for the history (at most :data:`HISTORY`, warm-started from the
full fit); :func:`hlaid.update_clone` predicts the new event with the clone before updating it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..record import STARTS, EventRecord, Fallback, LawChoice, Prequential, StartRule, StartScore, UpdateCheck

if TYPE_CHECKING:
    from ..clone import Clone
    from ..hla import HLAConfig
    from ..identify.result import IdentificationResult
    from ..measurement import Measurement

MARGIN = 0.01
"""The carried start must have predicted the events already seen better than from rest by more
than this (mean R) to be chosen."""

HISTORY = 3
"""At most this many prefixes of its records are fitted by :func:`hlaid.identify_clone` for the
history (the last ones)."""


def predicted(clone: Clone, meas: Measurement, hla_config: HLAConfig | None, clone_of: Sequence[str]) -> Prequential:
    """How ``clone`` (of the events ``clone_of``) predicts ``meas`` from its carried state and from
    rest: per start the mean floor R, the mean story-drift R and the peak-drift errors."""
    from .predict import predict_event

    scores: dict[str, StartScore] = {}
    for start in STARTS:
        if start == "carried" and clone.state is None:
            continue
        p = predict_event(clone, meas, start=start, hla_config=hla_config)
        scores[start] = StartScore(r=p.r_mean, drift_r=float(np.mean(p.drift_r)),
                                   pde=tuple(float(e) for e in p.peak_drift_error))
    return Prequential(clone_of=tuple(str(n) for n in clone_of), carried=scores.get("carried"),
                       undamaged=scores.get("undamaged"))


def start_rule(events: Sequence[EventRecord]) -> StartRule:
    """The prequential rule over a clone's ``events`` (their :attr:`~hlaid.record.EventRecord.prequential`
    records): the start of its next prediction (``"carried"`` or ``"undamaged"``) and why."""
    scored = [s for s in (e.prequential.scored() for e in events if e.prequential is not None) if s is not None]
    n = len(scored)
    if not n:
        return StartRule("undamaged", "no event of this series has been predicted by an earlier clone yet: from rest "
                         "(the carried state is used once it has predicted the events better)", margin=MARGIN)
    diff = float(np.mean([c for c, _ in scored]) - np.mean([r for _, r in scored]))
    what = f"over the {n} event(s) already predicted, the carried state's mean R {diff:+.3f} against from rest"
    if diff > MARGIN:
        choice, reason = "carried", f"{what}: better by more than {MARGIN:g}, the damage carries over"
    else:
        choice, reason = "undamaged", (f"{what}: not better by more than {MARGIN:g}, the building recovers between "
                                       "events (from rest)")
    return StartRule(choice, reason, n=n, margin=MARGIN, carried_minus_undamaged=diff)


def with_history(result: IdentificationResult, history: Mapping[int, Prequential], *, laws: LawChoice | None = None,
                 notes: Sequence[dict] | None = None, update_check: UpdateCheck | None = None
                 ) -> IdentificationResult:
    """``result`` whose clone's events ``k`` carry ``history[k]`` (how the clone before event
    ``k`` predicted it), whose start rule is the rule over them, and which keeps ``laws``, the
    ``update_check`` and the ``notes`` of stages that fell back (its ``fallbacks``)."""
    clone = result.clone
    events = tuple(dataclasses.replace(e, prequential=history[k]) if k in history else e
                   for k, e in enumerate(clone.events))
    fields: dict = {"laws": laws} if laws is not None else {}
    if update_check is not None:
        fields["update_check"] = update_check
    if notes is not None:
        fields["fallbacks"] = tuple(Fallback.from_dict(n) for n in notes)
    return dataclasses.replace(result, clone=dataclasses.replace(clone, events=events, start_rule=start_rule(events),
                                                                 **fields))


__all__ = ["MARGIN", "HISTORY", "STARTS", "predicted", "start_rule", "with_history"]
