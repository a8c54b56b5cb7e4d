"""What a run's decision rests on, and what its reader must know.

A run's summary reports P(collapse) at the intensity of every event the clone was identified from
(the building survived each one: a high probability there says the clone or its collapse law is
wrong, not that the building is at risk), the clone's events as evidence
(:func:`hlaid.events.evidence.survivors`) and a list of *flags*: plain sentences for what would
change the reading of the numbers (:func:`run_flags`). The report shows them first and ``hlaid
run`` prints them as warnings.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..clone import Clone
from ..motions import GroundMotion

WIDE_INTERVAL_FLAG = 100.0
"""A 90 % interval whose upper end is more than this many times its lower end is flagged: the
data hardly bound the parameter (without a structural system nothing else does)."""

STIFFNESS_ERROR_FLAG = 0.20
"""A story whose stiffness-evolution error (the clone's elastic stiffness against HLA's along the
record) exceeds this is flagged: the clone does not follow the building's degradation there."""

EXTRAPOLATION_MARGIN = 1.10
"""Demands are flagged extrapolated where the clones' median peak drift ratio exceeds the largest
survived one by more than this factor: a clone's replay of the very record the building survived
misses its peak drifts by about 10 % (docs/events.md), which is not extrapolation."""


def event_risks(assessment: dict | None, ida, motions: Sequence[tuple[str, GroundMotion]]) -> list[dict]:
    """P(collapse) at each event's intensity: the ensemble assessment's (``assessment``: its
    :meth:`~hlaid.ida.Assessment.to_dict`) where there is one, else the identified clone's IDA
    fragility (``ida``: an :class:`~hlaid.ida.IDAResult`) at ``motions`` ``[(name, GroundMotion)]``."""
    if assessment is not None and assessment.get("events"):
        return [{**e, "source": f"ensemble of {assessment['n_ensemble']} clones"} for e in assessment["events"]]
    if ida is None or not motions:
        return []
    from ..ida.measures import intensity

    try:
        frag = ida.collapse_fragility("capacities", n_boot=0)
    except ValueError:
        frag = None
    out = []
    for name, m in motions:
        im = float(intensity(m, ida.im, building=ida.building, period=ida.period)[0])
        p = None if frag is None else float(frag.probability(im))
        out.append({"name": name, "im": im, "p_collapse": p, "source": "IDA of the identified clone"})
    return out


def parameter_flags(clone: Clone) -> list[str]:
    """Parameters at a limit of the model or taken from the prior (the joint fit's
    ``diagnostics["parameters"]``; for a clone of the paper's method alone, its values)."""
    rows = (clone.diagnostics or {}).get("parameters")
    if not isinstance(rows, list):
        b = clone.building
        rows = [{"name": n, "story": i + 1, "value": float(getattr(b, n)[i]), "source": "data",
                 "at_limit": bool((n == "alpha" and not 1e-3 < getattr(b, n)[i] < 0.949)
                                  or (n == "p" and getattr(b, n)[i] < 1.005)
                                  or (n == "delta_eta" and getattr(b, n)[i] < 1e-6))}
                for n in ("alpha", "p", "delta_eta") for i in range(b.n_stories)]

    def label(r: dict) -> str:
        return f"{r['name']}[{r['story']}]" if r.get("story") else str(r["name"])
    at = [label(r) for r in rows if isinstance(r, dict) and r.get("at_limit")]
    prior = [label(r) for r in rows if isinstance(r, dict) and r.get("source") not in (None, "data")]
    out = []
    u = clone.uncertainty
    if u is not None:
        slots = set(u.slots)
        held = [f"{n}[{i + 1}]" for n in ("alpha", "p", "dy", "delta_eta") for i in range(clone.building.n_stories)
                if (n, i) not in slots]
        if held:
            out.append("parameters held at their value without an interval (not identified, no structural system's "
                       "prior to give one; name one with --system): " + ", ".join(held))
    if u is not None:
        wide = [k for k, (lo, hi) in u.interval(0.9).items() if not hi <= WIDE_INTERVAL_FLAG * lo]
        if wide:
            out.append(f"90 % intervals wider than a factor {WIDE_INTERVAL_FLAG:g} (the data hardly bound them"
                       + ("; the structural system's prior is that wide" if clone.system else
                          "; name the structural system to bound them by its prior") + "): " + ", ".join(wide))
    if at:
        out.append(f"parameters at a limit of the model (the search could only approach them): {', '.join(at)}")
    if prior:
        out.append("parameters the data hardly informed (their value and interval are the prior's): "
                   + ", ".join(prior))
    return out


def identification_flags(clone: Clone, stiffness_error: Sequence[float] | None = None) -> list[str]:
    """The flags of an identification: stories whose stiffness-evolution error exceeds
    :data:`STIFFNESS_ERROR_FLAG` (``stiffness_error`` per story; None: the clone's replay
    diagnostics), parameters at a limit or from the prior, unknown masses."""
    if stiffness_error is None:
        replay = (clone.diagnostics or {}).get("replay")
        stiffness_error = replay.get("stiffness_error") or () if isinstance(replay, dict) else ()
    err = np.asarray(stiffness_error, dtype=float)
    bad = [f"story {i + 1}: {v:.0%}" for i, v in enumerate(err) if np.isfinite(v) and v > STIFFNESS_ERROR_FLAG]
    out = []
    if bad:
        out.append(f"stiffness-evolution error above {STIFFNESS_ERROR_FLAG:.0%} ({', '.join(bad)}): the clone does not "
                   "follow the building's loss of stiffness there")
    out += parameter_flags(clone)
    fitted = any(f.get("name") == "mass" for f in (clone.diagnostics or {}).get("parameters") or ())
    if clone.mass_normalised and fitted:
        ratios = " / ".join(f"{v:.2f}" for v in np.asarray(clone.building.mass) / np.sum(clone.building.mass))
        out.append(f"floor masses unknown: their ratios fitted to the records' higher modes ({ratios} of the total, "
                   "equal the prior), the clone is mass-normalised (stiffness per unit mass; losses take floor areas "
                   "from the config)")
    elif clone.mass_normalised:
        out.append("floor masses unknown: equal (or the given ratios) assumed, the clone is mass-normalised "
                   "(stiffness per unit mass; losses take floor areas from the config)")
    return out


P_SURVIVED_FLAG = 0.5
"""P(collapse) at the intensity of an event the building survived from which on the run says the
fragility contradicts the record more likely than not."""


def run_flags(clone: Clone, *, stiffness_error: Sequence[float] | None = None, survival: dict | None = None,
              assessment: dict | None = None, heights_given: Sequence[float] | None = None,
              loss: dict | None = None, events: Sequence[dict] = (), drift_limit: float | None = None) -> list[str]:
    """The flags of a run (see the module doc): ``stiffness_error`` per story (None: the clone's
    replay diagnostics), the ``survival``
    block, the ``assessment`` (its members' own peak drift against what was observed), the story
    heights the config gave (None: the measurement's own), the ``loss`` block (its demands'
    flags) and P(collapse) at each recorded event (``events``, :func:`event_risks`; at or above
    :data:`P_SURVIVED_FLAG` the drifts survived and the IDA's ``drift_limit`` are named)."""
    out = identification_flags(clone, stiffness_error)
    seen = clone.survived_drift()
    h = clone.building.height if heights_given is None else np.asarray(heights_given, dtype=float)
    for e in events:
        if e.get("p_collapse") is not None and e["p_collapse"] >= P_SURVIVED_FLAG:
            what = ""
            if seen is not None and h is not None:
                ratio = np.asarray(seen) / np.asarray(h, dtype=float)
                what = (f": the building reached {float(ratio.max()):.1%} drift ("
                        + ", ".join(f"{d:.0f}" for d in seen) + " mm at heights "
                        + ", ".join(f"{v:g}" for v in np.asarray(h, dtype=float)) + " mm)"
                        + (f", the collapse criterion is {drift_limit:.0%}" if drift_limit else ""))
            out.append(f"P(collapse) {e['p_collapse']:.0%} at the intensity of {e['name']} ({e.get('im', 0):.3g} g), "
                       f"which the building survived{what}; check the story heights, the collapse law and the drift "
                       "limit before acting on the fragility")
    if survival and survival.get("nominal_survives") is False:
        out.append(f"the clone collapses under {survival.get('nominal_collapsed_in')}, an event it was identified "
                   "from and the building survived: its collapse risk is overstated (check the story heights and "
                   "the collapse law)")
    if survival and survival.get("n_rejected"):
        out.append(f"{survival['n_rejected']} of {survival['n_drawn']} ensemble draws collapsed under the clone's own "
                   "events and were rejected (the posterior conditioned on survival)")
    if survival and survival.get("unchecked"):
        out.append("survival not checked for: " + "; ".join(survival["unchecked"]))
    if assessment and seen is not None and h is not None and assessment.get("own_peak_drift") is not None:
        own = float(np.median(np.asarray(assessment["own_peak_drift"], dtype=float)))
        worst = float(np.max(np.asarray(seen) / np.asarray(h, dtype=float)))
        if own > EXTRAPOLATION_MARGIN * worst:
            out.append(f"demands extrapolated: the clones' median peak drift ratio under the record {own:.2%} lies "
                       f"beyond the largest the building survived (measured, or the clone's replay of its events), "
                       f"{worst:.2%}")
    for name, d in ((loss or {}).get("demands") or {}).items():
        out += [f"losses ({name}): {f}" for f in d.get("flags", ())]
    if heights_given is not None:
        out.append("story heights " + ", ".join(f"{v:g}" for v in heights_given) + " mm given in the config, not "
                   "measured: drift ratios, P-Delta and the collapse law rest on them")
    return out


__all__ = ["EXTRAPOLATION_MARGIN", "P_SURVIVED_FLAG", "STIFFNESS_ERROR_FLAG", "WIDE_INTERVAL_FLAG", "event_risks",
           "identification_flags", "parameter_flags", "run_flags"]
