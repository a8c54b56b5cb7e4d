"""Automated identification of a digital clone (paper section 2.2, docs/DESIGN.md section 6).

The paper's flow chart, stage by stage (:mod:`hlaid.identify.stages`, :mod:`.passes`,
:mod:`.refiners`)::

    measurement -> HLA                                    analyse
                -> first estimate (regressions)           first_estimate
                -> outer loop:                            outer_loop
                     drift paths (from the 2nd iteration)   follow_paths
                     classifier passes, coarse to fine      ClassifierPasses.run
                     regressions                            regress
                -> refinement (REFINERS[refine.method])   refiners
                -> replay check, clone

The per-event stages pass an explicit :class:`~hlaid.identify.stages.Estimate` on; the
refinement works on the paper's estimate and the measurement alone.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .. import _progress
from ..clone import Clone
from ..config import config_to_dict
from ..model import Building
from ..record import PaperMethod, PaperStory, Settings
from ..uncertainty.laplace import uncertainty_of_refinement
from .cache import MachineCache, default_cache_dir
from .config import IdentifyConfig
from .passes import ClassifierPasses, voted
from .refiners import Refinement, RefineProblem, get_refiner
from .replaycheck import ReplayCheck, replay_check
from .result import IdentificationResult, file_digest, provenance
from .stages import Estimate, Event, first_estimate, follow_paths, regress
from .tb import TBLogger


def outer_loop(event: Event, passes: ClassifierPasses, cfg: IdentifyConfig) -> tuple[Estimate, list[dict]]:
    """The paper's estimate: classifier passes and regressions until the parameters settle.

    The first iteration runs along HLA's drift: the coarse pass, the regressions with its
    alpha and p, the fine pass around them. Each later one first follows the drift paths
    reconstructed with the last estimate (:func:`~hlaid.identify.stages.follow_paths`), then
    runs the fine pass around the last alpha and p. Every iteration ends with the regressions on
    the fine pass's alpha and p. Returns the estimate and one summary per iteration.
    """
    est = first_estimate(event, cfg)
    history: list[dict] = []
    for it in range(cfg.outer.max_iterations):
        t = time.perf_counter()
        prev = est
        if it == 0:
            est = regress(event, est, *voted(passes.run(event, est, "coarse", it), est.alpha, est.p))
        else:
            est = follow_paths(event, est, cfg)
        fine = passes.run(event, est, "fine", it, centre=(est.alpha, est.p))
        passes.timings[f"classifiers_{it + 1}"] = time.perf_counter() - t
        new = regress(event, est, *voted(fine, prev.alpha, prev.p))
        change = max(_rel_change(new.alpha, prev.alpha), _rel_change(new.p, prev.p),
                     _rel_change(new.delta_eta, est.delta_eta), _rel_change(new.dy, est.dy))
        history.append({"iteration": it + 1, "alpha": new.alpha.tolist(), "p": new.p.tolist(),
                        "delta_eta": new.delta_eta.tolist(), "dy": new.dy.tolist(), "change": change})
        est = new
        _progress.step(f"[identify] outer iteration {it + 1}: alpha {np.round(est.alpha, 3)}, "
                       f"p {np.round(est.p, 2)}, delta_eta {np.round(est.delta_eta, 3)}, dy {np.round(est.dy, 3)} "
                       f"(change {change:.3f})")
        for i in range(event.n_stories):
            for name in ("alpha", "p", "delta_eta", "dy"):
                passes.tb.scalar(f"estimate/story{i + 1}/{name}", getattr(est, name)[i], it + 1)
        if change < cfg.outer.tol:
            break
    return est, history


def refine(event: Event, est: Estimate, cfg: IdentifyConfig) -> Refinement:
    """The refinement ``refine.method`` names, of the paper's estimate ``est`` against the
    measured floor accelerations (after a k0 stage, the regressions again along ``est``'s
    paths)."""
    rc = cfg.refine
    settings = {f.name: getattr(rc, f.name) for f in dataclasses.fields(rc) if f.name not in ("method", "compare")}
    refiner = get_refiner(rc.method, **settings)

    def with_k0(k0: np.ndarray) -> Building:
        return regress(event, est.replace(k0=k0), est.alpha, est.p).building(event, cfg.damping_ratio)

    problem = RefineProblem(measurement=event.measurement, start=est.building(event, cfg.damping_ratio),
                            stories=tuple(int(i) for i in np.flatnonzero(event.identifiable)), noise=event.noise,
                            peak_drift=event.peak_drift, regress=with_k0)
    return refiner.refine(problem)


def open_cache(cfg: IdentifyConfig, cache_dir: str | None = None) -> MachineCache:
    """The classifier cache of an identification: ``cache_dir`` (None: the config's, else the
    default ``~/.cache/hlaid/svm``, ``HLAID_CACHE`` overrides; ``""``: no cache)."""
    cache_dir = cache_dir if cache_dir is not None else cfg.cache_dir
    return MachineCache(default_cache_dir() if cache_dir is None else (cache_dir or None))


def identify_event(event: Event, cfg: IdentifyConfig, cache: MachineCache, tb: TBLogger,
                   timings: dict) -> IdentificationResult:
    """The paper's method and the refinement on one analysed record (:func:`hlaid.identify_clone`
    runs it on a building's most informative record). ``timings`` gains the seconds of each
    stage; the clone has no history yet (its ``events`` and ``state`` are the caller's)."""
    passes = ClassifierPasses(cfg, cache, tb, timings)
    est, history = outer_loop(event, passes, cfg)
    paper = est.building(event, cfg.damping_ratio)
    t = time.perf_counter()
    refined = refine(event, est, cfg)
    if refined.result is not None:
        timings["refine"] = time.perf_counter() - t
    t = time.perf_counter()
    measurement = event.measurement
    check = replay_check(refined.building, measurement, event.hla)
    timings["replay"] = time.perf_counter() - t
    for i, r in enumerate(check.r_measured):
        tb.scalar(f"replay/story{i + 1}/R_measured", r)
    clone = _clone(event, est, paper, refined, history, passes.log, check, timings, cfg)
    return IdentificationResult(clone=clone, hla=event.hla, paper_estimate=paper, passes=passes.log,
                                iterations=len(history), replay=check, timings=timings, refinement=refined.result)


def _clone(event: Event, est: Estimate, paper: Building, refined: Refinement, history: list, passes: list,
           check: ReplayCheck, timings: dict, cfg: IdentifyConfig) -> Clone:
    """The clone file's content: the building, its uncertainty, what the paper's method found
    (``paper``), the replay of the record (``fit_replays``), the settings, provenance and the
    write-only diagnostics."""
    meas = event.measurement
    prov = {**provenance(timings, source=meas.source, sha256=file_digest(meas.source) if meas.source else None),
            "noise_rms_used": event.noise}
    rr = refined.result
    unc = None if rr is None else uncertainty_of_refinement(rr, rr.channels or meas.n_floors, noise_rms=event.noise,
                                                            band_hz=cfg.refine.band_hz, dt=meas.dt)
    stories = _stories(event, est, paper, check)
    diagnostics = _diagnostics(event, stories, history, passes, check, refined.info)
    return Clone(building=refined.building, mass_normalised=event.hla.mass_normalised, diagnostics=diagnostics,
                 provenance=prov, uncertainty=unc, fit_replays=(check.record(meas.name),),
                 paper=PaperMethod(paper_stories(stories, passes), refine=refined.info),
                 settings=Settings(config=config_to_dict(cfg)))


def paper_stories(stories: list[dict], passes: list) -> tuple[PaperStory, ...]:
    """What the paper's method found of each story (the clone's ``paper.stories``), with each
    story's SVM test accuracies in the last pass that trained them."""
    last: dict[int, dict] = {}
    for pas in passes:
        for i, st in enumerate(pas.get("stories", []) if isinstance(pas, dict) else []):
            if st:
                last[i] = {k: v.get("test_accuracy") for k, v in st.items()}
    return tuple(PaperStory(story=s["story"], identifiable=s["identifiable"], k0_hla=s["k0_hla"],
                            reason=s.get("reason", ""), svm_test_accuracy=last.get(i)) for i, s in enumerate(stories))


def _stories(event: Event, est: Estimate, paper: Building, check: ReplayCheck) -> list[dict]:
    """Per story what the paper's method found (the diagnostics' ``stories``)."""
    res = event.hla
    stories = []
    for i, s in enumerate(res.stories):
        d = {"story": i + 1, "identifiable": bool(event.identifiable[i]), "k0_hla": float(s.k0),
             "yielded": bool(s.yielded), "n_half_cycles": len(s.half_cycles),
             "n_yielding_half_cycles": len(event.features[i]), "alpha_max": float(event.alpha_max[i]),
             "peak_drift": float(np.max(np.abs(s.drift))),
             "paper_method": {k: float(getattr(paper, k)[i]) for k in ("k0", "alpha", "p", "dy", "delta_eta")},
             "regressions": est.regressions[i], "r_measured": float(check.r_measured[i]),
             "r_true": None if check.r_true is None else float(check.r_true[i]),
             "stiffness_error": float(check.stiffness_error[i])}
        if not event.identifiable[i]:
            d["reason"] = (f"story stayed elastic (peak drift {d['peak_drift']:.3g} mm, "
                           f"{len(event.features[i])} yielding half cycles): alpha, p and delta_eta are borrowed "
                           "from the identified stories and dy is set above the largest drift reached; they "
                           "are assumptions, not identified")
        stories.append(d)
    return stories


def _diagnostics(event: Event, stories: list[dict], history: list, passes: list, check: ReplayCheck,
                 refine_info: dict | None) -> dict:
    """What the paper's method did, for the reader (the clone's ``diagnostics``)."""
    res = event.hla
    return {"stories": stories, "outer_iterations": history, "passes": passes, "refine": refine_info,
            "hla": {"band_hz": list(res.band_hz), "damping": res.damping, "mass_normalised": res.mass_normalised},
            "replay": check.to_dict()}


def _rel_change(new, old) -> float:
    new, old = np.asarray(new, float), np.asarray(old, float)
    return float(np.max(np.abs(new - old) / np.maximum(np.abs(old), 1e-9)))
