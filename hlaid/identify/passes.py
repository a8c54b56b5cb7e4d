"""The classifier-pass stage: the class bins of every story (coarse, or fine around the
current values), path-driven training samples, the alpha and p machines of every story (or
taken from the cache), and their votes on the measured half cycles."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _progress
from .._workers import result, worker_pool
from ..config import config_to_dict
from ..model import Building
from .cache import MachineCache, array_digest, cache_key
from .classify import Bins, fit_ensemble, pass_result, vote
from .config import IdentifyConfig
from .pathtrain import noise_bank, path_training_set, story_paths
from .stages import Estimate, Event
from .tb import TBLogger
from .training import TrainingSet

PARAMS = ("alpha", "p")

COARSE_SAMPLES = 400
"""At most this many samples per story in the coarse pass: its machines only pick the coarse bin
the fine pass is centred on; 400 scored as 800 did on Table 1 (paper method alone 5.4 % mean
against 5.5 %) and saved about 1 s."""
PATH_SUBSTEPS = 1
"""RK4 sub-steps per sample of the story law driven along a path: one is 1e-5 of the force RMS
from the converged value on Table 1, far below the sensor noise."""
COARSE_FACTOR = 3.0
"""In the coarse pass (whose dy and delta_eta come from regressions on a guessed alpha and p),
dy and delta_eta are drawn log-uniformly within this factor of their estimates, not within
``training.spread``."""


@dataclass(frozen=True)
class TrainedPass:
    """Machines and statistics of a pass.

    Attributes
    ----------
    machines : ``{"story<i>_<param>": KernelSVC | None}`` (None: a single class, nothing to
        learn); path-driven passes hold ensembles as ``"story<i>_<param>#<k>"``, see
        :func:`machines_of`
    stats : per machine: accuracies, confusion, sample counts, seconds
    cached : taken from the cache
    seconds_simulate : time spent simulating training half cycles
    sets : the training sets, None for a story not trained (None when cached)
    """

    machines: dict
    stats: dict
    cached: bool
    seconds_simulate: float
    sets: Sequence[TrainingSet | None] | None



def _path_key(paths: list, estimate: Building, bins: list, identifiable: np.ndarray, *, cfg: IdentifyConfig,
              stage: str, seed: int) -> str:
    """The cache key of a path-driven pass: everything its training sets and machines depend on."""
    return cache_key(stage=stage, seed=seed, estimate=estimate.to_dict(), mode="path",
                     edges=[[bb[0].edges, bb[1].edges] for bb in bins], training=config_to_dict(cfg.training),
                     svm=config_to_dict(cfg.svm), identifiable=np.asarray(identifiable, bool),
                     paths=[None if sp is None else [array_digest(sp.drift[: sp.end]), array_digest(sp.force[: sp.end]),
                                                     np.asarray(sp.bounds).tolist(), sp.k0, sp.noise_std, sp.dt,
                                                     sp.cutoff_hz] for sp in paths])


def _cached_pass(hit: tuple, stage: str, chosen_C: dict) -> TrainedPass:
    """A pass loaded from the cache; its cross-validated C are kept for the later passes (as in a cold run)."""
    machines, meta = hit
    _progress.step(f"[identify] {stage} pass: classifiers from the cache")
    for name, st in meta["stats"].items():
        if "C" in st:
            chosen_C.setdefault(name, (st["C"], st.get("gamma_factor", 1.0)))
    return TrainedPass(machines, meta["stats"], True, 0.0, None)

def path_pass(paths: list, estimate: Building, bins: list[tuple[Bins, Bins]], identifiable: np.ndarray, *,
              cfg: IdentifyConfig, stage: str, seed: int, cache: MachineCache, tb: TBLogger | None = None,
              step: int = 0, chosen_C: dict | None = None,
              noise: np.ndarray | Callable[[], np.ndarray] | None = None) -> TrainedPass:
    """Train (or load) the alpha and p classifiers of every identifiable story on path-driven
    training sets (:mod:`hlaid.identify.pathtrain`): one feature vector per sample.

    Parameters
    ----------
    paths : per story a :class:`~hlaid.identify.pathtrain.StoryPath` (None where not identifiable)
    estimate : current building estimate (k0, dy, delta_eta the draws are centred on)
    bins : per story ``(alpha bins, p bins)``
    chosen_C : ``{machine name: (C, gamma factor)}`` cross-validated in an earlier pass of the
        same run: reused instead of a new cross-validation (updated with this pass's choices)
    noise : ``(time, histories)`` low-passed unit white noise shared by the stories
        (:func:`hlaid.identify.pathtrain.noise_bank`), or a function returning it (called only
        when the machines are not cached), or None (drawn per story)
    """
    tc = cfg.training
    chosen_C = {} if chosen_C is None else chosen_C
    key = _path_key(paths, estimate, bins, identifiable, cfg=cfg, stage=stage, seed=seed)
    hit = cache.load(key)
    if hit is not None:
        return _cached_pass(hit, stage, chosen_C)
    n_ident = int(np.sum(identifiable))
    coarse = stage == "coarse"
    noise = noise() if callable(noise) else noise
    n_samples = min(tc.samples, COARSE_SAMPLES) if coarse else tc.samples
    sets: list[TrainingSet | None]
    machines, stats, sets = {}, {}, []
    t_sim = 0.0
    # the story law runs here (compiled, both cores); the machines of a story train on the worker
    # processes while the next story's samples are drawn: the two kinds of work overlap
    jobs = []
    with worker_pool(cfg.n_jobs if n_ident > 0 else 1) as pool, \
            _progress.stage(f"[identify] {stage} pass: {n_ident} training set(s), {2 * n_ident} kernel machines",
                            3 * n_ident, unit="steps") as bar:
        for i, sp in enumerate(paths):
            if not identifiable[i] or sp is None:
                sets.append(None)
                continue
            bar.set_note(f"drawing story {i + 1}'s training set")
            t = time.perf_counter()
            S = path_training_set(sp, k0=float(estimate.k0[i]), dy=float(estimate.dy[i]),
                                  delta_eta=float(estimate.delta_eta[i]), alpha_range=bins[i][0].range,
                                  p_range=bins[i][1].range, n_samples=n_samples, spread=tc.spread,
                                  seed=seed + 7919 * i, substeps=PATH_SUBSTEPS,
                                  wide=COARSE_FACTOR if coarse else None, noise=noise)
            t_sim += time.perf_counter() - t
            sets.append(S)
            bar.update(1, note="training the kernel machines")
            for param, b in zip(PARAMS, bins[i]):
                name = f"story{i + 1}_{param}"
                svm = cfg.svm if name not in chosen_C else _chosen(cfg.svm, *chosen_C[name])
                kw: dict[str, Any]
                args, kw = (S, param, b, svm, tc.test_fraction), {"seed": seed + 31 * i + len(param)}
                job = pool.apply_async(fit_ensemble, args, kw) if pool else fit_ensemble(*args, **kw)
                jobs.append((i, param, b, S, job))
        accuracy = []
        for i, param, b, S, job in jobs:
            ms, st = result(job) if pool else job
            name = f"story{i + 1}_{param}"
            for k, m in enumerate(ms or []):
                machines[f"{name}#{k}"] = m
            if "C" in st:
                chosen_C[name] = (st["C"], st.get("gamma_factor", 1.0))
            stats[name] = _jsonable(st)
            _log_machine(tb, stage, i, param, st, S, b, step)
            _progress.debug(f"  story {i + 1} {param}: test accuracy {st['test_accuracy']:.3f} (C {st.get('C')})")
            accuracy.append(float(st["test_accuracy"]))
            bar.update(1, note=f"story {i + 1} {param}: test accuracy {st['test_accuracy']:.2f}")
        bar.done(f"test accuracy {min(accuracy):.2f}-{max(accuracy):.2f}" if accuracy else "no identifiable story")
    if tb is not None:
        tb.scalar(f"{stage}/simulate_seconds", t_sim, step)
    cache.store(key, machines, {"stats": stats})
    return TrainedPass(machines, stats, False, t_sim, sets)


def _chosen(svm, C: float, gamma_factor: float):
    """``svm`` with an earlier pass's choice: no cross-validation, the same C and the same
    factor of ``svm.gamma`` (resolved on this pass's features)."""
    return dataclasses.replace(svm, C=C, C_grid=None, gamma_grid=None if svm.gamma_grid is None else (gamma_factor,))


def _jsonable(st: dict) -> dict:
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in st.items()}


def _log_machine(tb, stage, i, param, st, S, b, step):
    if tb is None:
        return
    tag = f"{stage}/story{i + 1}/{param}"
    tb.scalar(f"{tag}/train_accuracy", st["train_accuracy"], step)
    tb.scalar(f"{tag}/test_accuracy", st["test_accuracy"], step)
    tb.scalar(f"{tag}/fit_seconds", st["seconds"], step)
    tb.confusion(f"{tag}/confusion", st["confusion"], b.edges, step)
    tb.features(f"{tag}/features", S.X, b.label(getattr(S, param)), b.edges, step)


def machines_of(tp: TrainedPass, name: str):
    """The machine (or the ensemble's list of machines, or None) named ``name`` in a pass."""
    if name in tp.machines:
        return tp.machines[name]
    bags = sorted((k for k in tp.machines if k.split("#")[0] == name), key=lambda k: int(k.split("#")[1]))
    return [tp.machines[k] for k in bags] or None


def story_bins(alpha_max: np.ndarray, cfg: IdentifyConfig, centre=None) -> list[tuple[Bins, Bins]]:
    """Per story ``(alpha Bins, p Bins)`` of a pass: the coarse bins (alpha over
    ``[0, alpha_max]``), or, given ``centre`` ``(alpha, p)``, fine bins over the coarse bin
    holding the current value and its two neighbours."""
    b = cfg.bins
    out = []
    for i in range(len(alpha_max)):
        a_bins = Bins.regular(0.0, alpha_max[i], b.alpha_coarse)
        p_bins = Bins.regular(b.p_range[0], b.p_range[1], b.p_coarse)
        if centre is not None:
            a_bins = a_bins.refine(int(a_bins.label(np.array([centre[0][i]]))[0]), b.alpha_fine, (0.0, alpha_max[i]))
            p_bins = p_bins.refine(int(p_bins.label(np.array([centre[1][i]]))[0]), b.p_fine, b.p_range)
        out.append((a_bins, p_bins))
    return out


class ClassifierPasses:
    """The classifier passes of one identification run, in the order they run.

    Holds what passes share: the classifier cache, the TensorBoard logger, the C and gamma
    cross-validated in the first pass (reused by later ones), the low-passed noise bank of each
    event (drawn once, when a pass first trains), the log of every pass (``log``, written into
    the clone's diagnostics) and the run's ``timings``.
    """

    def __init__(self, cfg: IdentifyConfig, cache: MachineCache, tb: TBLogger, timings: dict):
        self.cfg, self.cache, self.tb, self.timings = cfg, cache, tb, timings
        self.chosen_C: dict = {}
        self.log: list[dict] = []
        self._noise: dict = {}

    def run(self, event: Event, est: Estimate, stage: str, iteration: int, centre=None) -> list[dict]:
        """One pass over every story of ``event`` around ``est``: ``"coarse"``, or ``"fine"``
        around ``centre`` ``(alpha, p)``. Returns per story ``{"alpha": PassResult, "p":
        PassResult}`` (empty where not identifiable)."""
        cfg, res = self.cfg, event.hla
        bins = story_bins(event.alpha_max, cfg, centre if stage == "fine" else None)
        seed = cfg.training.seed + 1000 * iteration + (0 if stage == "coarse" else 500)
        paths = story_paths(est.stories, est.features, mass=res.mass, k0=est.k0,
                            floor_acc=event.measurement.floor_acc, noise_rms=event.noise, dt=res.dt,
                            cutoff_hz=res.band_hz[1], n_segments=cfg.training.n_segments,
                            identifiable=event.identifiable)
        tp = path_pass(paths, est.building(event, cfg.damping_ratio), bins, event.identifiable, cfg=cfg, stage=stage,
                       seed=seed, cache=self.cache, tb=self.tb, step=iteration + 1, chosen_C=self.chosen_C,
                       noise=lambda: self._noise_bank(event))
        if not tp.cached:
            self.timings[f"simulate_{stage}_{iteration + 1}"] = tp.seconds_simulate
        out = []
        for i, sp in enumerate(paths):
            entry = {}
            if event.identifiable[i] and sp is not None:
                for j, param in enumerate(PARAMS):
                    name = f"story{i + 1}_{param}"
                    st = tp.stats[name]
                    v = vote(machines_of(tp, name), sp.measured_features()[None, :], bins[i][j], st.get("single", -1),
                             st.get("scaler"))
                    entry[param] = pass_result(param, stage, bins[i][j], v, st, tp.cached, cfg.aggregate)
            out.append(entry)
        self.log.append({"iteration": iteration + 1, "stage": stage,
                         "stories": [{k: v.to_dict() for k, v in e.items()} for e in out]})
        return out

    def _noise_bank(self, event: Event) -> np.ndarray:
        """``(time, 256)`` low-passed unit white noise shared by every pass's training sets
        (:func:`hlaid.identify.pathtrain.noise_bank`)."""
        if event not in self._noise:
            res = event.hla
            self._noise[event] = noise_bank(event.measurement.n_samples, res.dt, res.band_hz[1],
                                            seed=9_000_000 + self.cfg.training.seed)
        return self._noise[event]


def voted(result: list[dict], alpha: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """alpha and p of every story from a pass's result (``alpha``, ``p`` where it has none)."""
    return (np.array([r["alpha"].value if r else a for r, a in zip(result, alpha)]),
            np.array([r["p"].value if r else q for r, q in zip(result, p)]))
