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
first records how the clone before it predicted it (``clone.events[k]["prequential"]``), and the
clone its rule's choice with the reason (``clone.diagnostics["start_rule"]``), which
:func:`hlaid.events.start.resolve_start` reads for ``start="auto"``. :func:`hlaid.identify_clone`
fits the prefixes of its records for the history (at most :data:`HISTORY`, warm-started from the
full fit); :func:`hlaid.update_clone` predicts the new event with the clone before updating it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

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

STARTS = {"carried": "carried", "rest": "undamaged"}
"""The rule's choices and the start each one is."""


def predicted(clone: Clone, meas: Measurement, hla_config: HLAConfig | None, clone_of: Sequence[str]) -> dict:
    """How ``clone`` (of the events ``clone_of``) predicts ``meas`` from its carried state and from
    rest: per start the mean floor R, the mean story-drift R and the peak-drift errors."""
    from .predict import predict_event

    out: dict = {"clone_of": [str(n) for n in clone_of]}
    for key, start in STARTS.items():
        if start == "carried" and clone.state is None:
            continue
        p = predict_event(clone, meas, start=start, hla_config=hla_config)
        out[key] = {"r": p.r_mean, "drift_r": float(np.mean(p.drift_r)),
                    "pde": [float(e) for e in p.peak_drift_error]}
    return out


def _scored(events: Sequence[Mapping]) -> list[dict]:
    out = []
    for e in events:
        h = e.get("prequential") if isinstance(e, Mapping) else None
        if not isinstance(h, Mapping):
            continue
        try:
            rc, rr = float(h["carried"]["r"]), float(h["rest"]["r"])
        except (KeyError, TypeError, ValueError):
            continue
        if np.isfinite(rc) and np.isfinite(rr):
            out.append({"carried": rc, "rest": rr})
    return out


def start_rule(events: Sequence[Mapping]) -> dict:
    """The prequential rule over a clone's ``events`` (their ``"prequential"`` records): the
    start of its next prediction (``"carried"`` or ``"rest"``) and why."""
    scored = _scored(events)
    n = len(scored)
    if not n:
        return {"rule": "prequential", "margin": MARGIN, "n": 0, "carried_minus_rest": None, "choice": "rest",
                "reason": "no event of this series has been predicted by an earlier clone yet: from rest (the "
                          "carried state is used once it has predicted the events better)"}
    diff = float(np.mean([s["carried"] for s in scored]) - np.mean([s["rest"] for s in scored]))
    what = f"over the {n} event(s) already predicted, the carried state's mean R {diff:+.3f} against from rest"
    if diff > MARGIN:
        choice, reason = "carried", f"{what}: better by more than {MARGIN:g}, the damage carries over"
    else:
        choice, reason = "rest", (f"{what}: not better by more than {MARGIN:g}, the building recovers between events "
                                  "(from rest)")
    return {"rule": "prequential", "margin": MARGIN, "n": n, "carried_minus_rest": diff, "choice": choice,
            "reason": reason}


def with_history(result: IdentificationResult, history: Mapping[int, dict], *, diagnostics: Mapping | None = None
                 ) -> IdentificationResult:
    """``result`` whose clone's events ``k`` carry ``history[k]`` (how the clone before event
    ``k`` predicted it) and whose diagnostics hold the start rule over them (and ``diagnostics``)."""
    clone = result.clone
    events = tuple({**e, "prequential": history[k]} if k in history else e for k, e in enumerate(clone.events))
    rule = start_rule(events)
    diag = {**(clone.diagnostics or {}), **dict(diagnostics or {}), "start_rule": rule}
    return dataclasses.replace(result, clone=dataclasses.replace(clone, events=events, diagnostics=diag))


__all__ = ["MARGIN", "HISTORY", "STARTS", "predicted", "start_rule", "with_history"]
