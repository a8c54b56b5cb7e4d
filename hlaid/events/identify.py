"""A clone learnt from one record, or from a building's records in time order.

:func:`identify_clone`, the entry point of every identification::

    events (time order) -> HLA of each                                   analyse
                        -> the paper's method on the most informative     hlaid.identify.identify_event
                           one (one yielding record and no system: the
                           clone), or the prior's median building where
                           none yielded
                        -> one set of parameters for all of them, the     hlaid.joint.fit.joint_fit
                           state carried from each event into the next,
                           the structural system's prior where the data say little
                        -> the clone, left in the state its last event left it

:func:`hlaid.events.update.update_clone` adds one event to a clone: the clone's posterior is the
prior, its state the start, the new event the data (sequential updating).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import time
from collections.abc import Sequence

import numpy as np

from .. import _progress
from ..clone import Clone
from ..config import config_to_dict
from ..errors import InputError, NotIdentifiableError
from ..hla import HLAResult
from ..identify.auto import Resolution, damping_ran_away, held_damping, resolve_settings
from ..identify.config import IdentifyConfig
from ..identify.pipeline import identify_event, open_cache
from ..identify.replaycheck import replay_check
from ..identify.result import IdentificationResult, file_digest, provenance
from ..identify.stages import Event, analyse
from ..identify.tb import TBLogger
from ..joint.fallback import run_stage
from ..joint.fit import WEIGHT_ROUNDS, JointFit, best_fit, flags, joint_fit, posterior_uncertainty
from ..joint.laws import NO_DEGRADATION, TIE_LOG_UNITS, candidates, choose_laws, default_laws, with_laws
from ..joint.priors import StructuralPrior, elf_profile, get_prior, weight_above
from ..joint.screen import SCREEN_MARGIN, Screened, prefix_point, screen_laws
from ..joint.series import state_after
from ..joint.vector import PriorVector, SystemPrior
from ..measurement import Measurement, building_name, check_series, ground_digest, ground_profile
from ..model import Building, Damping
from ..model.state import BuildingState
from ..record import EventRecord, LawChoice, Prequential, Settings
from ..units import G_MM_S2
from .coupled import choose_linear_part, in_band
from .evidence import measured_peak_drift
from .prequential import HISTORY, predicted, with_history
from .replay import with_replays


def identify_clone(measurements: Measurement | Sequence[Measurement], config: IdentifyConfig | None = None, *,
                   tensorboard: str | None = None, cache_dir: str | None = None) -> IdentificationResult:
    """Identify a digital clone from one measurement, or from several of one building in time
    order, with no expert input.

    One yielding record and no structural ``system``: the paper's method and the refinement on its
    data alone (:func:`hlaid.identify.identify_event`). Several records, a record that stays
    elastic, or a ``system`` named: the paper's method on the most informative record (where one
    yielded) gives the start, and one set of parameters is then fitted to every record, the state
    carried from each into the next and the system's prior holding what the data say little about
    (:mod:`hlaid.joint.fit`): the posterior (intervals, ensemble draws) is never wider than the
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
    events = [analyse(m, cfg) for m in _progress.progress(meas, desc="[identify] hysteresis loop analysis",
                                                          unit="record(s)")]
    timings["hla"] = time.perf_counter() - t_all
    best = most_informative(events)
    single = None if best is None else paper_clone(events[best], cfg, cache, tb, timings,
                                                   alone=len(meas) == 1 and cfg.system is None)
    if len(meas) == 1 and single is not None and cfg.system is None:  # no system named: the paper's method
        timings["total"] = time.perf_counter() - t_all
        tb.close()
        return with_modes(with_choices(with_history(dataclasses.replace(
            single, clone=dataclasses.replace(single.clone, system=cfg.system)), {}), settings))
    system = get_prior(cfg.system or "generic")
    starts = plausible_starts(single, events[0], meas[0], system, cfg)
    names = [m.name or f"event {k + 1}" for k, m in enumerate(meas)]
    k0_ref = events[0].hla.k0
    default = default_laws(system, len(k0_ref))
    notes: list[dict] = []
    t = time.perf_counter()
    with _progress.stage(f"[identify] joint fit of {len(meas)} record(s) from {len(starts)} start(s)"):
        fit, start, settings = _main_fit(starts, meas, system, settings, names=names, k0_ref=k0_ref, laws=default)
    cfg = settings.config
    timings["joint"] = time.perf_counter() - t
    t = time.perf_counter()
    with _progress.stage("[identify] fits under the candidate story laws"):
        fit, laws = select_laws(fit, meas, system, cfg, names=names, k0_ref=k0_ref,
                                isolation=isolation_start(events, meas[0], system, fit.building), notes=notes)
    timings["laws"] = time.perf_counter() - t
    fit, linear, lin, k0_ref = linear_stage(fit, meas, system, cfg, names=names, notes=notes, k0_ref=k0_ref,
                                            timings=timings)
    t = time.perf_counter()
    with _progress.stage("[identify] prefix fits of the start rule") if len(meas) > 1 else contextlib.nullcontext():
        history = prefix_history(fit, meas, system, cfg, names=names, k0_ref=k0_ref, notes=notes,
                                 mass_normalised=events[-1].hla.mass_normalised)
    timings["prequential"] = time.perf_counter() - t
    result = result_of_joint(events, meas, fit, cfg, system=system, start=start, single=single, timings=timings)
    timings["total"] = time.perf_counter() - t_all
    tb.close()
    result = with_choices(with_history(result, history, laws=laws, notes=notes), settings)
    return with_modes(result, () if lin is None else in_band(lin), linear)


def linear_stage(fit: JointFit, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig, *,
                 names: Sequence[str], notes: list, k0_ref, timings: dict):
    """The records' modes and the linear part chosen by them (:func:`choose_linear_part`):
    ``(fit, linear, lin, k0_ref)``, the prior's stiffness the records' springs where coupled."""
    t = time.perf_counter()
    with _progress.stage("[identify] the records' modes and the coupled linear part"):
        fit, linear, lin = choose_linear_part(fit, meas, system, cfg, names=names, notes=notes)
    if linear.form == "coupled" and lin is not None:
        k0_ref = np.asarray(lin.k)
    timings["linear"] = time.perf_counter() - t
    return fit, linear, lin, k0_ref


def paper_clone(event: Event, cfg: IdentifyConfig, cache, tb: TBLogger, timings: dict, *,
                alone: bool) -> IdentificationResult:
    """The paper's method on ``event`` (:func:`hlaid.identify.identify_event`): its clone left in
    the state the event left it, the event its record (``alone``: this clone is the result, with
    its full replay of its event)."""
    with _progress.stage(f"[identify] the paper's method on {event.measurement.name or 'the record'}"):
        single = identify_event(event, cfg, cache, tb, timings)
    m = event.measurement
    state = state_after(single.clone.building, [m], cfg.refine.band_hz, [m.name or "event 1"])
    record = event_record(m, hla=event.hla)
    if alone:
        record = with_replays((record,), single.clone.building, [m], [None],
                              mass_normalised=single.clone.mass_normalised)[0]
    return dataclasses.replace(single, clone=dataclasses.replace(single.clone, events=(record,), state=state))


def with_modes(result: IdentificationResult, records=(), linear=None) -> IdentificationResult:
    """``result`` whose clone holds its modes at small amplitude beside the ``records``' own
    (:class:`hlaid.model.modes.ModalCheck`) and its ``linear`` part's choice
    (:class:`hlaid.record.LinearPart`)."""
    from ..model.modes import modal_check

    clone = result.clone
    check = modal_check(clone.building, clone.system, records)
    return dataclasses.replace(result, clone=dataclasses.replace(clone, modes=check, linear=linear))


def _main_fit(starts: Sequence[Building], meas: Sequence[Measurement], system: StructuralPrior, settings: Resolution, *,
              names: Sequence[str], k0_ref: np.ndarray, laws) -> tuple[JointFit, Building, Resolution]:
    """The joint fit under the system's ``laws`` from each start, the best kept; where its damping
    ran to the model's bound (it took up model error) the damping is held and the fits run again.
    Returns the fit, its start and the settings (with the held damping where it was)."""
    cfg = settings.config
    fit, k = _from_starts(starts, meas, system, cfg, names=names, k0_ref=k0_ref, laws=laws)
    if damping_ran_away(cfg, fit.building):
        settings = held_damping(settings, fit.building.damping.ratio, starts[k].damping.ratio)
        _progress.warn(settings.choices[-1].line())
        fit, k = _from_starts(starts, meas, system, settings.config, names=names, k0_ref=k0_ref, laws=laws)
    return fit, starts[k], settings


def _from_starts(starts: Sequence[Building], meas: Sequence[Measurement], system: StructuralPrior,
                 cfg: IdentifyConfig, *, names: Sequence[str], k0_ref: np.ndarray, laws) -> tuple[JointFit, int]:
    """The joint fit from the best of ``starts`` and its index: with several, each searched for
    one weighting round, the others pruned there and the best one's search continued (its
    remaining rounds, from its optimum)."""
    if len(starts) == 1:
        return joint_fit(starts[0], meas, system, cfg, names=names, k0_ref=k0_ref, laws=laws), 0
    firsts = [joint_fit(b, meas, system, cfg, names=names, k0_ref=k0_ref, laws=laws, rounds=1) for b in starts]
    lead = best_fit(firsts)
    k = firsts.index(lead)
    _progress.step(f"[identify] joint fit: start {k + 1} of {len(starts)} kept after one weighting round")
    if lead.series is not None and lead.jac_weights is not None:
        lead.series.reweigh(lead.building)
        if bool(np.all(np.abs(np.log(lead.series.weights / lead.jac_weights)) < np.log(1.2))):
            return lead, k  # its weights settled: nothing to continue
    more = joint_fit(lead.building, meas, system, cfg, names=names, k0_ref=k0_ref, laws=laws,
                     rounds=WEIGHT_ROUNDS - 1, warm=True)
    return (more if more.score(lead.n_eff) <= lead.score(lead.n_eff) else lead), k


CANDIDATE_ITERATIONS = 20
"""At most this many evaluations of the residuals per candidate law's short fit (one weighting
round, warm-started; a candidate the screen cannot judge: not nested in the system's laws, or
from an isolation-layer start)."""

MAX_CONTENDERS = 2
"""At most this many candidate laws the screen finds close to beating the system's law get a
short fit (the best first)."""


def _short_fits(fit: JointFit, laws: tuple[str, ...], starts: Sequence[Building], fit_short, tried: dict,
                seconds: dict, how: dict, notes: list[dict] | None) -> None:
    """The short fits of the candidate ``laws`` from ``starts`` (``fit_short``: :func:`joint_fit`
    of one weighting round, its ``start`` and ``laws`` to give): the best kept in ``tried`` where it
    beats what is there, its time added to ``seconds``."""
    found = []
    for b in starts:
        f = run_stage(f"the fit under the laws {'/'.join(laws)}", functools.partial(fit_short, b, laws=laws), None,
                      notes, used="the candidate is left out", extra=(NotIdentifiableError,))
        if f is not None:
            found.append(f)
    if found:
        best_found = best_fit(found)
        n_eff = np.mean([fit.n_eff, best_found.n_eff], axis=0)
        if laws not in tried or best_found.log_evidence(n_eff) > tried[laws].log_evidence(n_eff):
            tried[laws], how[laws] = best_found, "short fit"
        seconds[laws] = seconds.get(laws, 0.0) + float(sum(f.seconds for f in found))


def select_laws(fit: JointFit, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig, *,
                names: Sequence[str], k0_ref: np.ndarray, isolation: Building | None = None,
                notes: list[dict] | None = None, y0: np.ndarray | None = None) -> tuple[JointFit, LawChoice]:
    """The laws the stories follow (:mod:`hlaid.joint.laws`), chosen by the Laplace evidence of
    the joint fit of ``meas`` under each candidate (:func:`~hlaid.joint.laws.candidates`), ties to
    the system's law. Every candidate nested in ``fit``'s laws (the fit under the system's laws)
    is judged from ``fit`` itself (:func:`hlaid.joint.screen.screen_laws`: no fit of its own);
    one the screen finds better than the system's law by more than the tie and
    :data:`~hlaid.joint.screen.SCREEN_MARGIN` wins on the screen (the screen errs against a
    candidate); else those within the margin of beating it get a short fit (one weighting round
    from the screen's point) before they are compared (at most :data:`MAX_CONTENDERS`). The law
    chosen, where it is not the system's, is fitted in full from its point.
    A candidate the screen cannot judge, and the candidates whose first story differs from the
    others from ``isolation`` (an isolation-layer start, where there is one), get a short fit.
    Returns the fit under the laws chosen and what was compared."""
    n = fit.building.n_stories
    default = fit.laws or default_laws(system, n)
    tried: dict[tuple[str, ...], JointFit | Screened] = {default: fit}
    seconds: dict[tuple[str, ...], float] = {default: fit.seconds}
    how: dict[tuple[str, ...], str] = {default: "the joint fit"}
    others = [laws for laws in candidates(n) if laws != default]
    t = time.perf_counter()
    screened = run_stage("the screen of the candidate laws",
                         functools.partial(screen_laws, fit, others, system, k0_ref), {}, notes,
                         used="each candidate gets a short fit")
    if screened:
        dt = (time.perf_counter() - t) / len(screened)
        for laws, sc in screened.items():
            tried[laws], seconds[laws], how[laws] = sc, dt, "screened from the joint fit"
    iterations = min(cfg.refine.max_iterations, CANDIDATE_ITERATIONS)
    fit_short = functools.partial(joint_fit, measurements=meas, prior=system, cfg=cfg, names=names, k0_ref=k0_ref,
                                  rounds=1, max_iterations=iterations, y0=y0)
    for laws in others:
        starts = ([] if laws in screened else [fit.building]) + (
            [isolation] if isolation is not None and len(set(laws)) > 1 else [])
        _short_fits(fit, laws, [with_laws(b, laws, system) for b in starts], fit_short, tried, seconds, how, notes)

    def evidence_of() -> list[tuple[tuple[str, ...], float]]:
        n_eff = np.mean([f.n_eff for f in tried.values()], axis=0)
        return [(laws, f.log_evidence(n_eff)) for laws, f in tried.items()]

    z = dict(evidence_of())
    screened_z = {laws: z[laws] for laws, f in tried.items() if isinstance(f, Screened) and np.isfinite(z[laws])}
    clear = [laws for laws, v in screened_z.items() if v > z[default] + TIE_LOG_UNITS + SCREEN_MARGIN]
    contenders = [] if clear else sorted((laws for laws, v in screened_z.items()
                                          if v > z[default] + TIE_LOG_UNITS - SCREEN_MARGIN), key=lambda k: -z[k])
    for laws in contenders[:MAX_CONTENDERS]:  # close enough to matter: a search of its own before it is compared
        sc = tried[laws]
        short = run_stage(f"the fit under the laws {'/'.join(laws)}",
                          functools.partial(joint_fit, sc.building, meas, system, cfg, names=names, k0_ref=k0_ref,
                                            laws=laws, rounds=1, max_iterations=iterations, warm=True, y0=y0),
                          None, notes, used="the candidate is left out", extra=(NotIdentifiableError,))
        if short is None:
            del tried[laws]
        else:
            tried[laws], how[laws] = short, "screened, then a short fit"
            seconds[laws] += short.seconds
    for laws in contenders[MAX_CONTENDERS:]:
        del tried[laws]  # close, but behind two that were fitted: not chosen on the screen alone
    evidence = evidence_of()
    eligible = [(k, v) for k, v in evidence if k == default or not isinstance(tried[k], Screened) or k in clear]
    chosen, reason = choose_laws(eligible, default)
    _progress.step(f"[identify] story laws: {reason}")
    best: JointFit = fit
    if chosen != default:  # the candidate's point (a short fit, or the screen's where it won clearly), in full
        near = tried[chosen].building
        full = run_stage(f"the fit under the laws {'/'.join(chosen)}",
                         lambda: joint_fit(near, meas, system, cfg, names=names, k0_ref=k0_ref, laws=chosen, y0=y0,
                                           warm=True), None, notes, used="the system's law is kept",
                         extra=(NotIdentifiableError,))
        if full is None:
            chosen, reason = default, reason + "; its fit failed: the system's law is kept"
        else:
            best = full
    info = LawChoice(chosen=tuple(chosen), default=tuple(default), reason=reason, tie_log_units=TIE_LOG_UNITS,
                     screen_margin=SCREEN_MARGIN,
                     candidates=tuple({"laws": list(laws), "log_evidence": z if np.isfinite(z) else None,
                                       "seconds": seconds[laws], "judged_by": how[laws]} for laws, z in evidence))
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


PREFIX_ROUNDS = 1
"""Weighting rounds of a prefix's fit (from the full fit's building, the weights at its start):
the prefix's clone only predicts the record after it. On the steel frame the prefix clones of
one round predict as those of three did (docs/events.md)."""


def prefix_history(fit: JointFit, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig, *,
                   names: Sequence[str], k0_ref: np.ndarray, notes: list[dict] | None = None,
                   mass_normalised: bool = False, refit: bool = False) -> dict[int, Prequential]:
    """How the clones of the prefixes of ``meas`` (the last :data:`~hlaid.events.prequential.HISTORY`)
    predict the record after them, from their carried state and from rest: per record index its
    prequential record. Each prefix's clone is ``fit``'s optimum moved by one Newton step of the
    prefix's posterior (:func:`hlaid.joint.screen.prefix_point`: no fit of its own); where the
    replay does not bear the step out, or it goes beyond the Gaussian's reach (or ``refit``), the
    prefix is fitted (:data:`PREFIX_ROUNDS` weighting rounds from ``fit``'s building under its laws)."""
    out: dict[int, Prequential] = {}
    k = len(meas)
    for j in range(max(1, k - HISTORY), k):
        point = None if refit else run_stage(f"the Newton step to the clone of {', '.join(names[:j])}",
                                             functools.partial(prefix_point, fit, j, names), None, notes,
                                             used="the prefix is fitted")
        if point is not None and point.building is not None:
            building, state, how = point.building, point.state, "newton"
        else:
            f = run_stage(f"the prefix fit of {', '.join(names[:j])}",
                          functools.partial(joint_fit, fit.building, meas[:j], system, cfg, names=names[:j],
                                            k0_ref=k0_ref, laws=fit.laws, rounds=PREFIX_ROUNDS),
                          None, notes, used=f"{names[j]} is not in the start rule's history",
                          extra=(NotIdentifiableError,))
            if f is None:
                continue
            building, state, how = f.building, f.states[-1], "fit"
        clone = Clone(building=building, state=state, mass_normalised=mass_normalised)
        told = run_stage(f"the prediction of {names[j]} by the clone of {', '.join(names[:j])}",
                         functools.partial(predicted, clone, meas[j], cfg.hla, names[:j]), None, notes,
                         used=f"{names[j]} is not in the start rule's history")
        if told is not None:
            out[j] = dataclasses.replace(told, prefix={"by": how, **({} if point is None else
                                                                    {"newton": point.to_dict()})})
            c = None if told.carried is None else told.carried.r
            r = None if told.undamaged is None else told.undamaged.r
            _progress.step(f"[identify] the clone of {', '.join(names[:j])} predicts {names[j]}: R {c:.3f} carried, "
                           f"{r:.3f} from rest" if c is not None and r is not None else
                           f"[identify] the clone of {', '.join(names[:j])} predicts {names[j]}")
    return out


CHOICE_WIDTH = 100
"""A chosen setting's line is cut to this many characters (its whole evidence with ``--verbose``
and in the clone's ``settings``)."""


def announce(settings: Resolution) -> None:
    """Say which settings were chosen from the data: a short block (:func:`choice_block`, each line
    its own message, so no line break is escaped), every choice with its evidence at ``--verbose``."""
    if not settings.choices:
        return
    full = _progress.verbosity() >= 2
    _progress.info("[identify] settings chosen from the data (a config value overrides any"
                   + ("" if full else "; --verbose gives the evidence") + "):")
    for line in ([f"  {c.line()}" for c in settings.choices] if full else choice_block(settings.choices)):
        _progress.info(line)


def choice_block(choices) -> list[str]:
    """The chosen settings grouped by the config's sections (``hla``, ``refine``, the rest), each
    group ``setting = value`` items wrapped at :data:`CHOICE_WIDTH` characters; a setting left
    unchosen with advice (``system = null``) keeps it."""
    from ..hla.auto import show_value

    groups: dict[str, list[str]] = {}
    for c in choices:
        top, _, rest = c.setting.partition(".")
        group, leaf = (top, rest.rpartition(".")[2]) if rest else ("", top)
        item = f"{leaf} = {show_value(c.value)}"
        if c.value is None:  # not chosen: its reason, shortly, says what to do
            item = choice_line(c).replace(f"{c.setting} = {show_value(c.value)}: ", f"{item} (", 1) + ")"
        groups.setdefault(group, []).append(item)
    out = []
    for group, items in groups.items():  # wrapped between items, never inside one
        line = f"  {group}: " if group else "  "
        fresh = True
        for k, item in enumerate(items):
            piece = item + ("," if k < len(items) - 1 else "")
            if not fresh and len(line) + 1 + len(piece) > CHOICE_WIDTH:
                out.append(line)
                line, fresh = "    ", True
            line += ("" if fresh else " ") + piece
            fresh = False
        out.append(line)
    return out


def choice_line(c) -> str:
    """``setting = value: the reason's first clause``, at most :data:`CHOICE_WIDTH` characters."""
    from ..hla.auto import show_value

    head = f"{c.setting} = {show_value(c.value)}"
    text = str(c.reason)
    reason = text.split(":")[0].split(";")[0].split(" (")[0].strip()
    advice = text.rsplit("; ", 1)[1].strip() if "; " in text else ""
    if advice and len(advice) <= 40 and "(" not in advice and ":" not in advice:  # what to do, kept
        reason += f"; {advice}"
    line = f"{head}: {reason}" if reason else head
    return line if len(line) <= CHOICE_WIDTH else line[: CHOICE_WIDTH - 3].rstrip() + "..."


def with_choices(result: IdentificationResult, settings: Resolution) -> IdentificationResult:
    """``result`` whose clone keeps the settings it used and those chosen from the data
    (``clone.settings``: :class:`~hlaid.record.Settings`)."""
    return dataclasses.replace(result, clone=dataclasses.replace(result.clone, settings=settings.record()))


def event_record(meas: Measurement, start: str | None = None, hla: HLAResult | None = None) -> EventRecord:
    """What a clone keeps of an event it learnt from (``start``: where its replay started,
    ``"carried"`` or ``"undamaged"``, when an update chose it; ``peak_drift``: the largest story
    drifts measured, with ``hla`` HLA's, :func:`~hlaid.events.evidence.measured_peak_drift`)."""
    peak = measured_peak_drift(meas, hla)
    return EventRecord(name=meas.name, source=meas.source or None,
                       sha256=file_digest(meas.source) if meas.source else None, ground_sha256=ground_digest(meas),
                       pga_g=float(np.max(np.abs(meas.ground_acc)) / G_MM_S2),
                       duration_s=float(meas.n_samples * meas.dt), dt=float(meas.dt), n_floors=int(meas.n_floors),
                       ground_profile=tuple(ground_profile(meas)), recorded=meas.recorded or None, start=start or None,
                       peak_drift=None if peak is None else tuple(peak))


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
    prior = SystemPrior(system, PriorVector(b, damping=cfg.resolved().damping), event.hla.k0)
    if np.max(np.abs(prior.residuals(prior.vector.x0))) <= PLAUSIBLE_SD:
        return [b]
    return [median, b]


def result_of_joint(events: Sequence[Event], meas: Sequence[Measurement], fit: JointFit, cfg: IdentifyConfig, *,
                    system: StructuralPrior, start: Building, single: IdentificationResult | None = None,
                    history: Sequence[EventRecord] = (), y0: np.ndarray | None = None,
                    timings: dict | None = None, last_start: str | None = None,
                    settings: Resolution | None = None) -> IdentificationResult:
    """The identification result of a joint fit over ``events``: the clone left in the last
    event's state, its posterior, per event the replay from the state carried into it
    (``last_start``: the start of the last event, recorded with it, where one was chosen), the
    settings used (``settings``: with the choices made from the data; None: ``cfg`` alone)."""
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
                   "replay": checks[-1].to_dict(),
                   "single_event": None if single is None else single.clone.diagnostics}
    prov = provenance(timings, sources=[m.source or None for m in meas])
    replays = tuple(c.record(m.name) for m, c in zip(meas, checks))
    records = (tuple(history) + tuple(event_record(m, hla=ev.hla) for m, ev in zip(meas[:-1], events))
               + (event_record(meas[-1], start=last_start, hla=events[-1].hla),))
    befores = [None if y0 is None else BuildingState.from_vector(y0)] + list(fit.states[:-1])
    records = with_replays(records, fit.building, meas, befores, mass_normalised=events[-1].hla.mass_normalised)
    clone = Clone(building=fit.building, mass_normalised=events[-1].hla.mass_normalised, diagnostics=diagnostics,
                  provenance=prov, uncertainty=posterior_uncertainty(fit), system=system.name,
                  events=records, state=fit.states[-1], parameters=flags(fit, "earlier events" if history else "prior"),
                  fit_replays=replays,
                  settings=Settings(config=config_to_dict(cfg)) if settings is None else settings.record())
    return IdentificationResult(clone=clone, hla=events[-1].hla,
                                paper_estimate=start if single is None else single.paper_estimate,
                                passes=[] if single is None else single.passes,
                                iterations=0 if single is None else single.iterations, replay=checks[-1],
                                timings=timings, refinement=fit.result, joint=fit)


def fit_prior_summary(fit: JointFit, system: StructuralPrior) -> dict:
    """What the joint fit's prior was (the system's, or an earlier clone's posterior)."""
    return {"system": system.name, "sources": list(system.sources)}
