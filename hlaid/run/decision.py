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
from ..ida.basis import EXTRAPOLATION_MARGIN, P_SURVIVED_FLAG, DecisionBasis, decision_basis
from ..motions import GroundMotion

WIDE_INTERVAL_FLAG = 100.0
"""A 90 % interval whose upper end is more than this many times its lower end is flagged: the
data hardly bound the parameter (without a structural system nothing else does)."""

STIFFNESS_ERROR_FLAG = 0.20
"""A story whose stiffness-evolution error (the clone's elastic stiffness against HLA's along the
record) exceeds this is flagged: the clone does not follow the building's degradation there."""

def event_risks(assessment: dict | None, ida, motions: Sequence[tuple[str, GroundMotion]]) -> list[dict]:
    """P(collapse | another record of each event's intensity): the identified clone's IDA fragility
    (``ida``: an :class:`~hlaid.ida.IDAResult`) at ``motions`` ``[(name, GroundMotion)]``, the one
    figure every command reports (:func:`hlaid.ida.basis.ida_events`), with the ensemble
    assessment's band beside it where there is one (``assessment``: its
    :meth:`~hlaid.ida.Assessment.to_dict`; its events only, where the IDA is not at hand)."""
    ens = {e["name"]: e for e in (assessment or {}).get("events") or () if isinstance(e, dict) and "name" in e}
    if ida is None or not motions:
        return [{**e, "source": f"ensemble of {assessment['n_ensemble']} clones"} for e in ens.values()] \
            if assessment else []
    from ..ida.basis import ida_events

    out = []
    for e in ida_events(None, ida, motions):
        d = e.to_dict()
        band = ens.get(e.name, {}).get("p_collapse_band")
        if band is not None and assessment is not None:
            d.update(p_collapse_band=list(band), source=f"{d['source']}; 90 % band: ensemble of "
                                                           f"{assessment['n_ensemble']} clones")
        out.append(d)
    return out


def parameter_flags(clone: Clone) -> list[str]:
    """Parameters at a limit of the search or taken from the prior (the joint fit's
    ``clone.parameters``; for a clone of the paper's method alone, its values against the same
    bounds, :func:`hlaid.joint.vector.at_limit`)."""
    from ..joint.vector import at_limit
    from ..record import ParameterFlag

    rows = clone.parameters
    if rows is None:
        b = clone.building
        rows = tuple(ParameterFlag(name=n, story=i + 1, value=float(getattr(b, n)[i]),
                                   at_limit=at_limit(n, float(getattr(b, n)[i])))
                     for n in ("alpha", "p", "delta_eta") for i in range(b.n_stories))
    at = [r.label() for r in rows if r.at_limit]
    prior = [r.label() for r in rows if r.source not in ("data", "earlier events")]
    carried = [r.label() for r in rows if r.source == "earlier events"]
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
        out.append(f"parameters at a limit of the model (the search could only approach them; the records hardly "
                   f"bound them: add events or name the structural system): {', '.join(at)}")
    if prior:
        out.append("parameters the data hardly informed (their value and interval are the prior's; more events or a "
                   "record that drives the stories further would inform them): " + ", ".join(prior))
    if carried:
        out.append("parameters the last event hardly informed (their interval is carried from the earlier events; "
                   "their value may still have moved): " + ", ".join(carried))
    return out


YIELD_DRIFT_MIN = 0.001
"""A story whose yield drift ``dy`` is below this fraction of its height is flagged implausible: frames
yield at drift ratios of about 0.5-1 % (a building that stays linear gets a "yield" in its noise)."""

PRIOR_SIGMAS = 2.0
"""A story's ``alpha`` or ``p`` more than this many of the structural system's prior standard
deviations (in prior units, :mod:`hlaid.joint.priors`) from its median is flagged implausible."""


def plausibility_flags(clone: Clone) -> list[str]:
    """Story parameters outside what the clone's structural system (the ``generic`` one when none
    is named) makes plausible, each with its evidence and what to do: a yield drift under
    :data:`YIELD_DRIFT_MIN` of the story height, ``alpha`` or ``p`` beyond :data:`PRIOR_SIGMAS` of the
    system's prior."""
    from ..joint.priors import ALPHA_MAX, PRIORS

    b = clone.building
    from ..systems import get_system

    named = clone.system in PRIORS and clone.system != "generic"
    system = clone.system if named and clone.system is not None else "generic"
    prior = PRIORS[system]
    title = (f"a {get_system(system).title} (its prior" if named else
             "any structure under the generic prior (no structural system named; the prior")
    out = []
    if b.height is not None:
        h = np.asarray(b.height, dtype=float)
        low = [i for i in range(b.n_stories) if b.dy[i] < YIELD_DRIFT_MIN * h[i]]
        if low:
            out.append("implausible yield drift: " + ", ".join(
                f"story {i + 1} dy {b.dy[i]:.3g} mm = {100 * b.dy[i] / h[i]:.3g} % of its {h[i]:g} mm height"
                for i in low) + f" (frames yield at about 0.5-1 %; under {100 * YIELD_DRIFT_MIN:g} % the record "
                "hardly left the linear range there): read that story as linear; its hysteresis parameters are "
                "noise, not the building's")

    def logit(a: float) -> float:
        x = min(max(a / ALPHA_MAX, 1e-9), 1 - 1e-9)
        return float(np.log(x / (1 - x)))
    far = []
    for i in range(b.n_stories):
        za = (logit(float(b.alpha[i])) - logit(prior.alpha.median)) / prior.alpha.beta
        zp = (np.log(max(float(b.p[i]) - 1.0, 1e-9)) - np.log(prior.p.median - 1.0)) / prior.p.beta
        if abs(za) > PRIOR_SIGMAS:
            far.append(f"story {i + 1} alpha {b.alpha[i]:.3g} ({za:+.1f} sd)")
        if abs(zp) > PRIOR_SIGMAS:
            far.append(f"story {i + 1} p {b.p[i]:.3g} ({zp:+.1f} sd)")
    if far:
        out.append(f"implausible for {title}: alpha median {prior.alpha.median:g}, p median "
                   f"{prior.p.median:g}; flagged beyond {PRIOR_SIGMAS:g} standard deviations): " + ", ".join(far)
                   + ("; name the structural system (--system) so its prior bounds them" if not named else
                      "; check the records' band and the story heights, or identify from more events"))
    return out


def identification_flags(clone: Clone, stiffness_error: Sequence[float] | None = None) -> list[str]:
    """The flags of an identification: stories whose stiffness-evolution error exceeds
    :data:`STIFFNESS_ERROR_FLAG` (``stiffness_error`` per story; None: the replay
    of its last fit), parameters at a limit or from the prior, unknown masses."""
    if stiffness_error is None:
        stiffness_error = clone.fit_replays[-1].stiffness_error if clone.fit_replays else ()
    err = np.asarray(stiffness_error, dtype=float)
    bad = [f"story {i + 1}: {v:.0%}" for i, v in enumerate(err) if np.isfinite(v) and v > STIFFNESS_ERROR_FLAG]
    out = []
    if bad:
        out.append(f"stiffness-evolution error above {STIFFNESS_ERROR_FLAG:.0%} ({', '.join(bad)}): the clone does not "
                   "follow the building's loss of stiffness there; read that story's degradation from HLA's figure, "
                   "and identify from more events or with the structural system (--system)")
    out += parameter_flags(clone)
    out += plausibility_flags(clone)
    fitted = any(f.name == "mass" for f in clone.parameters or ())
    if clone.mass_normalised and fitted:
        ratios = " / ".join(f"{v:.2f}" for v in np.asarray(clone.building.mass) / np.sum(clone.building.mass))
        out.append(f"floor masses unknown: their ratios fitted to the records' higher modes ({ratios} of the total, "
                   "equal the prior), the clone is mass-normalised (stiffness per unit mass; losses take floor areas "
                   "from the config)")
    elif clone.mass_normalised:
        out.append("floor masses unknown: equal (or the given ratios) assumed, the clone is mass-normalised "
                   "(stiffness per unit mass; losses take floor areas from the config); give the floor masses where "
                   "known (measurement.mass_t in a run config)")
    return out


def run_basis(clone: Clone, *, assessment: dict | None = None, heights_given: Sequence[float] | None = None,
              events: Sequence[dict] = (), drift_limit: float | None = None) -> DecisionBasis:
    """What a run's decision rests on (:func:`hlaid.ida.basis.decision_basis`): P(collapse) at each
    recorded event (``events``, :func:`event_risks`), the story heights the config gave (None: the
    measurement's own), the ensemble's median peak drift ratio under the record (``assessment``)
    against the drift survived, and the drift limit."""
    own = None
    if assessment and assessment.get("own_peak_drift") is not None:
        own = float(np.median(np.asarray(assessment["own_peak_drift"], dtype=float)))
    return decision_basis(clone, events=events, heights=heights_given, heights_assumed=heights_given is not None,
                          demand_ratio=own, drift_limit=drift_limit)


def run_flags(clone: Clone, *, stiffness_error: Sequence[float] | None = None, survival: dict | None = None,
              assessment: dict | None = None, heights_given: Sequence[float] | None = None,
              loss: dict | None = None, events: Sequence[dict] = (), drift_limit: float | None = None,
              basis: DecisionBasis | None = None) -> list[str]:
    """The flags of a run (see the module doc): ``stiffness_error`` per story (None: the replay
    of the clone's last fit), the flags of what the decision rests on (``basis``; None: :func:`run_basis`
    of ``assessment``, ``heights_given``, ``events`` and ``drift_limit``), the ``survival`` block and
    the ``loss`` block (its demands' flags)."""
    out = identification_flags(clone, stiffness_error)
    if basis is None:
        basis = run_basis(clone, assessment=assessment, heights_given=heights_given, events=events,
                          drift_limit=drift_limit)
    out += basis.flags()
    if survival and survival.get("nominal_survives") is False:
        out.append(f"the clone collapses under {survival.get('nominal_collapsed_in')}, an event it was identified "
                   "from and the building survived: its collapse risk is overstated (check the story heights and "
                   "the collapse law)")
    if survival and survival.get("n_rejected"):
        out.append(f"{survival['n_rejected']} of {survival['n_drawn']} ensemble draws collapsed under the clone's own "
                   "events and were rejected (the posterior conditioned on survival); many rejected means the clone "
                   "and its collapse law sit near what the building survived: check the story heights and the law")
    if survival and survival.get("unchecked"):
        out.append("survival not checked for: " + "; ".join(survival["unchecked"])
                   + " (keep the events' files where the clone names them, unchanged)")
    for name, d in ((loss or {}).get("demands") or {}).items():
        out += [f"losses ({name}): {f}" for f in d.get("flags", ())
                if not (name == "recorded" and f.startswith("demands extrapolated"))]  # the basis says it
    return out


__all__ = ["EXTRAPOLATION_MARGIN", "P_SURVIVED_FLAG", "STIFFNESS_ERROR_FLAG", "WIDE_INTERVAL_FLAG", "event_risks",
           "identification_flags", "parameter_flags", "plausibility_flags", "run_basis", "run_flags",
           "YIELD_DRIFT_MIN", "PRIOR_SIGMAS"]
