"""A clone learnt from one record, or from a building's records in time order.

:func:`identify_clone`, the entry point of every identification::

    events (time order) -> HLA of each                                   analyse
                        -> the paper's method on the most informative     hlaid.identify.identify_event
                           one (one yielding record and no system: the
                           clone), or the prior's median building where
                           none yielded
                        -> one set of parameters for all of them, the     hlaid.events.fit.joint_fit
                           state carried from each event into the next,
                           the structural system's prior where the data say little
                        -> the clone, left in the state its last event left it

:func:`hlaid.events.update.update_clone` adds one event to a clone: the clone's posterior is the
prior, its state the start, the new event the data (sequential updating).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Sequence

import numpy as np

from .. import _progress
from ..clone import Clone
from ..errors import InputError, NotIdentifiableError
from ..hla import HLAResult
from ..hla.config import fixed
from ..identify.auto import Resolution, damping_ran_away, held_damping, resolve_settings
from ..identify.config import IdentifyConfig
from ..identify.pipeline import identify_event, open_cache
from ..identify.replaycheck import replay_check
from ..identify.result import IdentificationResult, file_digest, provenance
from ..identify.stages import Event, analyse
from ..identify.tb import TBLogger
from ..measurement import Measurement, building_name, check_series, ground_digest
from ..model import Building, Damping
from ..units import G_MM_S2
from .evidence import measured_peak_drift
from .fallback import run_stage
from .fit import JointFit, best_fit, flags, joint_fit, posterior_uncertainty
from .laws import NO_DEGRADATION, TIE_LOG_UNITS, candidates, choose_laws, default_laws, with_laws
from .prequential import HISTORY, predicted, with_history
from .priors import StructuralPrior, elf_profile, get_prior, weight_above
from .replay import with_replays
from .series import state_after
from .state import BuildingState
from .vector import PriorVector, SystemPrior


def identify_clone(measurements: Measurement | Sequence[Measurement], config: IdentifyConfig | None = None, *,
                   tensorboard: str | None = None, cache_dir: str | None = None) -> IdentificationResult:
    """Identify a digital clone from one measurement, or from several of one building in time
    order, with no expert input.

    One yielding record and no structural ``system``: the paper's method and the refinement on its
    data alone (:func:`hlaid.identify.identify_event`). Several records, a record that stays
    elastic, or a ``system`` named: the paper's method on the most informative record (where one
    yielded) gives the start, and one set of parameters is then fitted to every record, the state
    carried from each into the next and the system's prior holding what the data say little about
    (:mod:`hlaid.events.fit`): the posterior (intervals, ensemble draws) is never wider than the
    system's prior.
    The clone is left in the state its last record left the building in (``clone.state``).

    Parameters
    ----------
    measurements : ground and floor accelerations (masses optional: mass-normalised clone);
        several: records of one building, oldest first
    config : settings (defaults: :class:`~hlaid.identify.IdentifyConfig`)
    tensorboard : folder for TensorBoard logs (classifier accuracies, confusion matrices,
        example features, estimates per outer iteration)
    cache_dir : where trained classifiers are cached (default ``~/.cache/hlaid/svm``,
        ``HLAID_CACHE`` overrides; ``""`` disables the cache)

    Returns
    -------
    IdentificationResult
    """
    meas = [measurements] if isinstance(measurements, Measurement) else list(measurements)
    if not meas:
        raise InputError("identify_clone: no measurement given")
    check_series(meas)
    settings = resolve_settings(meas, config or IdentifyConfig())
    announce(settings)
    cfg = settings.config
    cache = open_cache(cfg, cache_dir)
    tb = TBLogger(tensorboard)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    events = [analyse(m, cfg) for m in meas]
    timings["hla"] = time.perf_counter() - t_all
    best = most_informative(events)
    single = None
    if best is not None:
        single = identify_event(events[best], cfg, cache, tb, timings)
        m = events[best].measurement
        state = state_after(single.clone.building, [m], cfg.refine.band_hz, [m.name or "event 1"])
        record = event_record(m, hla=events[best].hla)
        if len(meas) == 1 and cfg.system is None:  # this clone is the result: its full replay of its event
            record = with_replays((record,), single.clone.building, [m], [None],
                                  mass_normalised=single.clone.mass_normalised)[0]
        single = dataclasses.replace(single, clone=dataclasses.replace(single.clone, events=(record,), state=state))
    if len(meas) == 1 and single is not None and cfg.system is None:  # no system named: the paper's method
        timings["total"] = time.perf_counter() - t_all
        tb.close()
        return with_choices(with_history(dataclasses.replace(
            single, clone=dataclasses.replace(single.clone, system=cfg.system)), {}), settings)
    system = get_prior(cfg.system or "generic")
    starts = plausible_starts(single, events[0], meas[0], system, cfg)
    names = [m.name or f"event {k + 1}" for k, m in enumerate(meas)]
    k0_ref = events[0].hla.k0
    default = default_laws(system, len(k0_ref))
    notes: list[dict] = []
    t = time.perf_counter()
    fit, start, settings = _main_fit(starts, meas, system, settings, names=names, k0_ref=k0_ref, laws=default)
    cfg = settings.config
    timings["joint"] = time.perf_counter() - t
    t = time.perf_counter()
    fit, laws = select_laws(fit, meas, system, cfg, names=names, k0_ref=k0_ref,
                            isolation=isolation_start(events, meas[0], system, fit.building), notes=notes)
    timings["laws"] = time.perf_counter() - t
    t = time.perf_counter()
    history = prefix_history(fit, meas, system, cfg, names=names, k0_ref=k0_ref, notes=notes,
                             mass_normalised=events[-1].hla.mass_normalised)
    timings["prequential"] = time.perf_counter() - t
    result = result_of_joint(events, meas, fit, cfg, system=system, start=start, single=single, timings=timings)
    timings["total"] = time.perf_counter() - t_all
    tb.close()
    return with_choices(with_history(result, history, diagnostics={"laws": laws, "fallbacks": notes}), settings)


def _main_fit(starts: Sequence[Building], meas: Sequence[Measurement], system: StructuralPrior, settings: Resolution, *,
              names: Sequence[str], k0_ref: np.ndarray, laws) -> tuple[JointFit, Building, Resolution]:
    """The joint fit under the system's ``laws`` from each start, the best kept; where its damping
    ran to the model's bound (it took up model error) the damping is held and the fits run again.
    Returns the fit, its start and the settings (with the held damping where it was)."""
    cfg = settings.config
    fits = [joint_fit(b, meas, system, cfg, names=names, k0_ref=k0_ref, laws=laws) for b in starts]
    fit = best_fit(fits)
    if damping_ran_away(cfg, fit.building):
        settings = held_damping(settings, fit.building.damping.ratio, starts[fits.index(fit)].damping.ratio)
        _progress.warn(settings.choices[-1].line())
        fits = [joint_fit(b, meas, system, settings.config, names=names, k0_ref=k0_ref, laws=laws) for b in starts]
        fit = best_fit(fits)
    return fit, starts[fits.index(fit)], settings


CANDIDATE_ITERATIONS = 20
"""At most this many evaluations of the residuals per candidate law's fit (one weighting round,
warm-started): enough to rank their evidence; the chosen one, where it is not the main fit's,
is fitted again in full."""


def select_laws(fit: JointFit, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig, *,
                names: Sequence[str], k0_ref: np.ndarray, isolation: Building | None = None,
                notes: list[dict] | None = None, y0: np.ndarray | None = None) -> tuple[JointFit, dict]:
    """The laws the stories follow (:mod:`hlaid.events.laws`), chosen by the Laplace evidence of
    the joint fit of ``meas`` under each candidate (:func:`~hlaid.events.laws.candidates`,
    warm-started from ``fit``, the fit under the system's laws; the candidates whose first story
    differs from the others also from ``isolation``, an isolation-layer start, where there is
    one), ties to the system's law; the fit under the laws chosen and what was compared."""
    n = fit.building.n_stories
    default = fit.laws or default_laws(system, n)
    tried: dict[tuple[str, ...], JointFit] = {default: fit}
    seconds: dict[tuple[str, ...], float] = {default: fit.seconds}
    iterations = min(cfg.refine.max_iterations, CANDIDATE_ITERATIONS)
    for laws in candidates(n):
        if laws == default:
            continue
        starts = [fit.building] + ([isolation] if isolation is not None and len(set(laws)) > 1 else [])
        found = []
        for b in starts:
            f = run_stage(f"the fit under the laws {'/'.join(laws)}",
                          functools.partial(joint_fit, with_laws(b, laws, system), meas, system, cfg, names=names,
                                            k0_ref=k0_ref, laws=laws, rounds=1, max_iterations=iterations, y0=y0),
                          None, notes, used="the candidate is left out", extra=(NotIdentifiableError,))
            if f is not None:
                found.append(f)
        if found:
            tried[laws] = best_fit(found)
            seconds[laws] = float(sum(f.seconds for f in found))
    n_eff = np.mean([f.n_eff for f in tried.values()], axis=0)
    evidence = [(laws, f.log_evidence(n_eff)) for laws, f in tried.items()]
    chosen, reason = choose_laws(evidence, default)
    _progress.info(f"[identify] story laws: {reason}")
    best = tried[chosen]
    if chosen != default:  # the candidate's short fit, in full
        best = run_stage(f"the fit under the laws {'/'.join(chosen)}",
                         lambda: joint_fit(best.building, meas, system, cfg, names=names, k0_ref=k0_ref, laws=chosen,
                                           y0=y0), best, notes, used="the candidate's fit",
                         extra=(NotIdentifiableError,))
    info = {"chosen": list(chosen), "default": list(default), "reason": reason, "tie_log_units": TIE_LOG_UNITS,
            "candidates": [{"laws": list(laws), "log_evidence": z if np.isfinite(z) else None,
                            "seconds": seconds[laws]} for laws, z in evidence]}
    return best, info


ISOLATION_RATIO = 3.0
"""Story 1 is an isolation-layer candidate where its peak drift (HLA of the records) is at least
this many times every other story's."""

ISOLATION = {"cy": 0.06, "alpha": 0.05, "p": 1.5, "damping": 0.02}
"""The isolation-layer start's first story: the medians of lead-rubber and friction-pendulum
design ranges (characteristic strength Qd/W 0.03-0.10, post-yield stiffness ratio 0.01-0.15,
Bouc-Wen exponent 1-2, no degradation, damping 2-5 %)."""


def isolation_start(events: Sequence[Event], meas: Measurement, system: StructuralPrior,
                    building: Building) -> Building | None:
    """``building`` with its first story as an isolation layer (:data:`ISOLATION`; k0 so that it
    yields at a tenth of its peak drift) where the records show one: story 1's peak drift at
    least :data:`ISOLATION_RATIO` times every other story's in each record; None otherwise."""
    if building.n_stories < 2:
        return None
    peaks = []
    for ev in events:
        d = np.array([float(np.max(np.abs(s.drift))) for s in ev.hla.stories])
        if not np.all(np.isfinite(d)) or d[0] < ISOLATION_RATIO * float(np.max(d[1:])):
            return None
        peaks.append(d[0])
    w = weight_above(building)[0]
    dy = 0.1 * float(np.median(peaks))
    k0 = np.array(building.k0, dtype=float)
    k0[0] = ISOLATION["cy"] * w / ((1.0 - ISOLATION["alpha"]) * dy)
    b = building.replace(k0=k0)
    alpha, p, dys, de = (np.array(getattr(b, k), dtype=float) for k in ("alpha", "p", "dy", "delta_eta"))
    alpha[0], p[0], dys[0], de[0] = ISOLATION["alpha"], ISOLATION["p"], dy, NO_DEGRADATION
    return b.replace(alpha=alpha, p=p, dy=dys, delta_eta=de,
                     damping=dataclasses.replace(b.damping, ratio=ISOLATION["damping"]))


def prefix_history(fit: JointFit, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig, *,
                   names: Sequence[str], k0_ref: np.ndarray, notes: list[dict] | None = None,
                   mass_normalised: bool = False) -> dict[int, dict]:
    """How the clones of the prefixes of ``meas`` (the last :data:`~hlaid.events.prequential.HISTORY`,
    each fitted from ``fit``'s building under its laws) predict the record after them, from their
    carried state and from rest: per record index its prequential record."""
    out: dict[int, dict] = {}
    k = len(meas)
    for j in range(max(1, k - HISTORY), k):
        f = run_stage(f"the prefix fit of {', '.join(names[:j])}",
                      functools.partial(joint_fit, fit.building, meas[:j], system, cfg, names=names[:j],
                                        k0_ref=k0_ref, laws=fit.laws),
                      None, notes, used=f"{names[j]} is not in the start rule's history",
                      extra=(NotIdentifiableError,))
        if f is None:
            continue
        clone = Clone(building=f.building, state=f.states[-1], mass_normalised=mass_normalised)
        out[j] = run_stage(f"the prediction of {names[j]} by the clone of {', '.join(names[:j])}",
                           functools.partial(predicted, clone, meas[j], cfg.hla, names[:j]), None, notes,
                           used=f"{names[j]} is not in the start rule's history")
        if out[j] is None:
            del out[j]
        else:
            c, r = out[j].get("carried", {}).get("r"), out[j].get("rest", {}).get("r")
            _progress.info(f"[identify] the clone of {', '.join(names[:j])} predicts {names[j]}: R {c:.3f} carried, "
                           f"{r:.3f} from rest" if c is not None and r is not None else
                           f"[identify] the clone of {', '.join(names[:j])} predicts {names[j]}")
    return out


def announce(settings: Resolution) -> None:
    """Say which settings were chosen from the data, one line each."""
    if settings.choices:
        _progress.info("[identify] settings chosen from the data (a config value overrides any):\n"
                       + "\n".join(f"  {line}" for line in settings.lines()))


def with_choices(result: IdentificationResult, settings: Resolution) -> IdentificationResult:
    """``result`` whose clone keeps the settings chosen from the data (``provenance["choices"]``)."""
    clone = result.clone
    prov = {**(clone.provenance or {}), "choices": settings.to_list()}
    return dataclasses.replace(result, clone=dataclasses.replace(clone, provenance=prov))


def event_record(meas: Measurement, start: str | None = None, hla: HLAResult | None = None) -> dict:
    """What a clone keeps of an event it learnt from (``start``: where its replay started,
    ``"carried"`` or ``"undamaged"``, when an update chose it; ``peak_drift``: the largest story
    drifts measured, with ``hla`` HLA's, :func:`~hlaid.events.evidence.measured_peak_drift`)."""
    peak = measured_peak_drift(meas, hla)
    return {"name": meas.name, "source": meas.source or None,
            "sha256": file_digest(meas.source) if meas.source else None, "ground_sha256": ground_digest(meas),
            "pga_g": float(np.max(np.abs(meas.ground_acc)) / G_MM_S2), "duration_s": float(meas.n_samples * meas.dt),
            "dt": float(meas.dt), "n_floors": int(meas.n_floors),
            **({"recorded": meas.recorded} if meas.recorded else {}), **({"start": start} if start else {}),
            **({"peak_drift": peak} if peak is not None else {})}


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
                 pdelta=meas.pdelta_active if meas.height is not None else None, name=building_name(meas))
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
    prior = SystemPrior(system, PriorVector(b, damping=fixed(cfg.refine.damping, "refine.damping")), event.hla.k0)
    if np.max(np.abs(prior.residuals(prior.vector.x0))) <= PLAUSIBLE_SD:
        return [b]
    return [median, b]


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
    per_event = [{"name": m.name, **info, **c.to_dict()} for m, info, c in zip(meas, fit.events, checks)]
    prior = fit_prior_summary(fit, system)
    diagnostics = {"joint": {"events": per_event, "rounds": fit.rounds, "prior": prior, "start": start.to_dict(),
                             "cost_final": fit.result.cost_final, "nfev": fit.result.nfev,
                             "seconds": fit.seconds},
                   "parameters": flags(fit, "earlier events" if history else "prior"), "replay": checks[-1].to_dict(),
                   "single_event": None if single is None else single.clone.diagnostics}
    prov = provenance(cfg, timings, sources=[m.source or None for m in meas])
    records = (tuple(history) + tuple(event_record(m, hla=ev.hla) for m, ev in zip(meas[:-1], events))
               + (event_record(meas[-1], start=last_start, hla=events[-1].hla),))
    befores = [None if y0 is None else BuildingState.from_vector(y0)] + list(fit.states[:-1])
    records = with_replays(records, fit.building, meas, befores, mass_normalised=events[-1].hla.mass_normalised)
    clone = Clone(building=fit.building, mass_normalised=events[-1].hla.mass_normalised, diagnostics=diagnostics,
                  provenance=prov, uncertainty=posterior_uncertainty(fit), system=system.name,
                  events=records, state=fit.states[-1])
    return IdentificationResult(clone=clone, hla=events[-1].hla,
                                paper_estimate=start if single is None else single.paper_estimate,
                                passes=[] if single is None else single.passes,
                                iterations=0 if single is None else single.iterations, replay=checks[-1],
                                timings=timings, refinement=fit.result, joint=fit)


def fit_prior_summary(fit: JointFit, system: StructuralPrior) -> dict:
    """What the joint fit's prior was (the system's, or an earlier clone's posterior)."""
    return {"system": system.name, "sources": list(system.sources)}
