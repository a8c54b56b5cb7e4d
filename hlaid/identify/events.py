"""A clone learnt from a building's events in time order, and updated event by event.

The multi-event path of :func:`hlaid.identify.identify_clone`:

    events (time order) -> HLA of each                                  analyse
                        -> the paper's method on the most informative    (the single-event pipeline)
                           one, or the prior's median building where none yielded
                        -> one set of parameters for all of them, the    map_refine
                           state carried from each event into the next,
                           the structural system's prior where the data say little
                        -> the clone, left in the state its last event left it

:func:`hlaid.identify.update.update_clone` adds one event to a clone: the clone's posterior is
the prior, its state the start, the new event the data (sequential updating).
"""

from __future__ import annotations

import datetime
import functools
from collections.abc import Sequence

import numpy as np

from .._version import __version__
from ..clone import Clone
from ..config import config_to_dict
from ..hla import HLAResult
from ..measurement import Measurement
from ..model import Building, Damping
from ..model.state import BuildingState
from ..model.uncertainty import ParameterUncertainty
from .config import IdentifyConfig
from .joint import GaussianPrior, JointFit, PriorVector, SystemPrior, map_refine
from .priors import StructuralPrior, elf_profile, weight_above
from .refiners import fit_or_fall_back
from .replaycheck import replay_check
from .result import IdentificationResult, event_record
from .stages import Event

INFORMED = 0.5
"""A parameter whose posterior standard deviation is more than ``1 - INFORMED`` of its prior's
is flagged as coming from the prior: the data narrowed it by less than half."""


def most_informative(events) -> int | None:
    """Index of the event with the most yielding half cycles over its identifiable stories (the
    paper's method runs on it); None where no story of any event yielded."""
    counts = [sum(len(F) for F, ok in zip(e.features, e.identifiable) if ok) for e in events]
    return None if max(counts) == 0 else int(np.argmax(counts))


def prior_start(hla: HLAResult, meas: Measurement, prior: StructuralPrior, damping_ratio: float | None) -> Building:
    """The prior's median building with HLA's k0 (the start where no event yielded)."""
    n = hla.n_stories
    b = Building(mass=hla.mass, k0=hla.k0, alpha=np.full(n, prior.alpha.median), p=np.full(n, prior.p.median),
                 dy=np.ones(n), delta_eta=np.full(n, prior.delta_eta.median), height=meas.height,
                 damping=Damping(ratio=prior.damping.median if damping_ratio is None else damping_ratio),
                 pdelta=meas.pdelta_active if meas.height is not None else None, name=meas.name)
    dy = prior.cy.median * elf_profile(b) * weight_above(b) / np.asarray(hla.k0)
    return b.replace(dy=dy)


PLAUSIBLE_SD = 3.0
"""A start more than this many prior standard deviations from the system's medians (in any
entry) is implausible: the prior's median building is tried beside it."""


def plausible_starts(single: IdentificationResult | None, event: Event, meas: Measurement,
                     system: StructuralPrior, cfg: IdentifyConfig) -> list[Building]:
    """Where the joint fit starts: the single-event clone of the most informative event; also the
    prior's median building (HLA's k0 of the first event) where there is none or the prior finds
    it implausible (a record whose misfit is model error can drive a single-event fit to extreme
    values, from which the joint search would not leave)."""
    median = prior_start(event.hla, meas, system, None)
    if single is None:
        return [median]
    b = single.clone.building
    prior = SystemPrior(system, PriorVector(b, damping=cfg.refine.damping), event.hla.k0)
    if np.max(np.abs(prior.residuals(prior.vector.x0))) <= PLAUSIBLE_SD:
        return [b]
    return [median, b]


def posterior_uncertainty(fit: JointFit, level: float = 0.9) -> ParameterUncertainty:
    """The Laplace posterior of a joint fit as a Gaussian over the clone's parameters: per story
    ``log k0, logit(alpha / 0.95), log(p - 1), log dy, log delta_eta`` (and ``log zeta``), an exact
    linear map of the prior units (``log dy = log Cy + log W - log k0``)."""
    vec, b = fit.vector, fit.building
    n, P = b.n_stories, len(fit.vector.slots)
    A = np.eye(P)
    for i in range(n):
        A[5 * i + 3, 5 * i] = -1.0  # log dy = log Cy - log k0 (+ log W)
    x = np.asarray(fit.result.x)
    c = A @ x
    c[3:5 * n:5] += np.log(weight_above(b))
    names = {"k0": "log", "alpha": "logit", "p": "log1", "cy": "log", "delta_eta": "log", "damping": "log"}
    slots = tuple(("dy" if name == "cy" else name, i) for name, i in vec.slots)
    transforms = tuple(names[name] for name, _ in vec.slots)
    info = {"prior": "joint MAP", "informed": fit.informed().tolist(), "level": level}
    return ParameterUncertainty(slots=slots, transform=transforms, centre=c, covariance=A @ fit.covariance @ A.T,
                                method="laplace-posterior", info=info)


def prior_of_clone(unc: ParameterUncertainty | None, building: Building, vector: PriorVector,
                   fallback: StructuralPrior, widen: float = 1.0) -> GaussianPrior | SystemPrior:
    """A clone's posterior as the prior of its update, in ``vector``'s prior units: exact where
    the clone stores the joint fit's posterior (:func:`posterior_uncertainty`), else from 4000
    draws of its uncertainty; the structural system's prior around the clone where it has none
    (or it does not cover every parameter). ``widen``: its standard deviations multiplied (to let
    a building that changed move)."""
    if unc is None or len(unc.slots) < len(vector.slots):
        return SystemPrior(fallback, vector, building.k0)
    n = building.n_stories
    if unc.method == "laplace-posterior" and len(unc.slots) == len(vector.slots):
        A = np.eye(len(vector.slots))
        for i in range(n):
            A[5 * i + 3, 5 * i] = -1.0
        c = np.asarray(unc.centre, dtype=float).copy()
        c[3:5 * n:5] -= np.log(weight_above(building))
        Ai = np.linalg.inv(A)
        return GaussianPrior(Ai @ c, widen**2 * Ai @ unc.covariance @ Ai.T)
    rng = np.random.default_rng(0)
    draws = unc.sample(4000, rng)
    xs = np.array([vector.of(unc.apply(building, d)) for d in draws])
    return GaussianPrior(xs.mean(axis=0), widen**2 * np.cov(xs.T))


def flags(fit: JointFit, prior: str = "prior") -> list[dict]:
    """Per fitted parameter: value, where it comes from (``"data"``, or ``prior`` where the data
    narrowed it by less than :data:`INFORMED`: ``"prior"`` for the structural system's,
    ``"earlier events"`` for an update's), and whether it sits at a limit of the model
    (alpha at 0 or 0.95, p at 1, delta_eta below 1e-6: a value the search could only approach)."""
    b, informed = fit.building, fit.informed()
    out = []
    for (name, i), inf in zip(fit.vector.slots, informed):
        if name == "damping":
            value = b.damping.ratio
        elif name == "cy":
            value, name = float(b.dy[i]), "dy"
        else:
            value = float(getattr(b, name)[i])
        at = ((name == "alpha" and not 1e-3 < value < 0.949) or (name == "p" and value < 1.005)
              or (name == "delta_eta" and value < 1e-6))
        out.append({"name": name, "story": i + 1 if i >= 0 else None, "value": value,
                    "source": "data" if inf >= INFORMED else prior, "informed": float(inf), "at_limit": bool(at)})
    return out


def joint_fit(start: Building, measurements: Sequence[Measurement], prior, cfg: IdentifyConfig, *, y0=None,
              names: Sequence[str] = (), k0_ref: np.ndarray | None = None) -> JointFit:
    """:func:`~hlaid.identify.joint.map_refine` with the settings of ``cfg.refine`` (errors in
    variables per event for ``method: eiv``, least squares otherwise)."""
    rc = cfg.refine
    if isinstance(prior, StructuralPrior):
        prior = SystemPrior(prior, PriorVector(start, damping=rc.damping), start.k0 if k0_ref is None else k0_ref)
    fit = functools.partial(map_refine, start, measurements, prior, band_hz=rc.band_hz, damping=rc.damping, y0=y0,
                            names=names, max_iterations=rc.max_iterations, tangent_max_mb=rc.tangent_max_mb)
    return fit_or_fall_back(fit, "tangent" if rc.method == "eiv" else "ignore")


def best_fit(fits: Sequence[JointFit]) -> JointFit:
    """The fit of highest posterior among searches from different starts (the posterior of a
    first-mode-dominated record can have more than one mode): the lowest
    :meth:`~hlaid.identify.joint.JointFit.score`, each event's ``n_eff`` the mean of the fits'."""
    n_eff = np.mean([[e["n_eff"] for e in f.events] for f in fits], axis=0)
    return min(fits, key=lambda f: f.score(n_eff))


def state_after(building: Building, measurements: Sequence[Measurement], band_hz, names: Sequence[str] = (),
                y0: np.ndarray | None = None) -> BuildingState:
    """The state ``building`` is left in by ``measurements`` replayed in order (from ``y0``)."""
    from .joint import _series

    series = _series(building, measurements, band_hz, "ignore", 4, 2, y0, None)
    return series.states(building, names)[-1]


def result_of_joint(events: Sequence[Event], meas: Sequence[Measurement], fit: JointFit, cfg: IdentifyConfig, *,
                    system: StructuralPrior, start: Building, single: IdentificationResult | None = None,
                    history: Sequence[dict] = (), y0: np.ndarray | None = None,
                    timings: dict | None = None, last_start: str | None = None) -> IdentificationResult:
    """The identification result of a joint fit over ``events``: the clone left in the last
    event's state, its posterior, per event the replay from the state carried into it
    (``last_start``: the start of the last event, recorded with it, where one was chosen)."""
    timings = {} if timings is None else timings
    checks = []
    y = y0
    for ev, st in zip(events, fit.states):
        checks.append(replay_check(fit.building, ev.measurement, ev.hla, y0=y))
        y = st.vector()
    per_event = [{"name": m.name, **info, "R_measured": c.r_measured.tolist(),
                  "R_true": None if c.r_true is None else c.r_true.tolist(),
                  "stiffness_error": c.stiffness_error.tolist()} for m, info, c in zip(meas, fit.events, checks)]
    prior = fit_prior_summary(fit, system)
    diagnostics = {"joint": {"events": per_event, "rounds": fit.rounds, "prior": prior, "start": start.to_dict(),
                             "cost_final": fit.result.cost_final, "nfev": fit.result.nfev,
                             "seconds": fit.seconds},
                   "parameters": flags(fit, "earlier events" if history else "prior"), "replay": checks[-1].to_dict(),
                   "single_event": None if single is None else single.clone.diagnostics}
    provenance = {"sources": [m.source or None for m in meas], "hlaid_version": __version__,
                  "config": config_to_dict(cfg), "timings": timings,
                  "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    clone = Clone(building=fit.building, mass_normalised=events[-1].hla.mass_normalised, diagnostics=diagnostics,
                  provenance=provenance, uncertainty=posterior_uncertainty(fit), system=system.name,
                  events=tuple(history) + tuple(event_record(m) for m in meas[:-1])
                  + (event_record(meas[-1], start=last_start),), state=fit.states[-1])
    return IdentificationResult(clone=clone, hla=events[-1].hla,
                                paper_estimate=start if single is None else single.paper_estimate,
                                passes=[] if single is None else single.passes,
                                iterations=0 if single is None else single.iterations, replay=checks[-1],
                                timings=timings, refinement=fit.result, joint=fit)


def fit_prior_summary(fit: JointFit, system: StructuralPrior) -> dict:
    """What the joint fit's prior was (the system's, or an earlier clone's posterior)."""
    return {"system": system.name, "sources": list(system.sources)}
