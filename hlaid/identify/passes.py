"""One classifier pass: training samples (path-driven, or dynamic simulations), the alpha and
p machines of every story (or taken from the cache). Used by :func:`hlaid.identify.identify` and by
``scripts/train_svm.py``."""

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
from ..motions import GroundMotion
from .cache import MachineCache, array_digest, cache_key
from .classify import Bins, fit_ensemble, fit_machine
from .config import IdentifyConfig
from .pathtrain import path_training_set
from .tb import TBLogger
from .training import Ranges, TrainingSet, simulate_training_sets

PARAMS = ("alpha", "p")


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


def train_pass(estimate: Building, motion: GroundMotion, bins: list[tuple[Bins, Bins]], identifiable: np.ndarray, *,
               noise: float, cfg: IdentifyConfig, stage: str, seed: int, cache: MachineCache,
               tb: TBLogger | None = None, step: int = 0) -> TrainedPass:
    """Train (or load) the alpha and p classifiers of every identifiable story.

    Parameters
    ----------
    estimate : current building estimate (the non-classified parameters of the simulations)
    motion : the excitation of the simulations (the measured ground motion)
    bins : per story ``(alpha bins, p bins)``
    identifiable : (story,) stories to train for; the others keep their estimate's alpha, p
    noise : noise level added to the simulated channels
    stage : a label (``"coarse"``, ``"fine"``) for logs and the cache key
    """
    a_rng = np.array([bb[0].range if identifiable[i] else (estimate.alpha[i],) * 2 for i, bb in enumerate(bins)])
    p_rng = np.array([bb[1].range if identifiable[i] else (estimate.p[i],) * 2 for i, bb in enumerate(bins)])
    key = cache_key(stage=stage, seed=seed, estimate=estimate.to_dict(), alpha=a_rng, p=p_rng,
                    edges=[[bb[0].edges, bb[1].edges] for bb in bins], motion=array_digest(motion.acc), dt=motion.dt,
                    noise=noise, training=config_to_dict(cfg.training), svm=config_to_dict(cfg.svm),
                    hla=config_to_dict(cfg.hla), identifiable=np.asarray(identifiable, bool))
    hit = cache.load(key)
    if hit is not None:
        machines, meta = hit
        _progress.info(f"[identify] {stage} pass: classifiers from the cache")
        return TrainedPass(machines, meta["stats"], True, 0.0, None)
    t = time.perf_counter()
    _progress.info(f"[identify] {stage} pass: simulating training half cycles")
    sets = simulate_training_sets(estimate, motion, Ranges(alpha=a_rng, p=p_rng), n_samples=cfg.training.samples,
                                  noise_rms=noise, hla_config=cfg.hla, n_segments=cfg.training.n_segments,
                                  yield_ratio=cfg.hla.stiffness.yield_ratio, spread=cfg.training.spread,
                                  max_simulations=cfg.training.max_simulations, seed=seed, n_jobs=cfg.n_jobs,
                                  progress=lambda k, tot: _progress.debug(f"  {k}/{tot} samples"))
    t_sim = time.perf_counter() - t
    machines, stats = {}, {}
    _progress.info(f"[identify] {stage} pass: training {2 * int(np.sum(identifiable))} kernel machines")
    for i, (bb, S) in enumerate(zip(bins, sets)):
        if not identifiable[i]:
            continue
        for param, b in zip(PARAMS, bb):
            name = f"story{i + 1}_{param}"
            machines[name], st = fit_machine(S, param, b, cfg.svm, cfg.training.test_fraction)
            stats[name] = _jsonable(st)
            _log_machine(tb, stage, i, param, st, S, b, step)
    if tb is not None:
        tb.scalar(f"{stage}/simulate_seconds", t_sim, step)
    cache.store(key, machines, {"stats": stats})
    return TrainedPass(machines, stats, False, t_sim, sets)


def path_pass(paths: list, estimate: Building, bins: list[tuple[Bins, Bins]], identifiable: np.ndarray, *,
              cfg: IdentifyConfig, stage: str, seed: int, cache: MachineCache, tb: TBLogger | None = None,
              step: int = 0, chosen_C: dict | None = None, path_errors: np.ndarray | None = None,
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
    path_errors : ``(history, time, story)`` simulated errors of the paths
        (:func:`hlaid.identify.patherrors.path_error_bank`), or None
    noise : ``(time, histories)`` low-passed unit white noise shared by the stories
        (:func:`hlaid.identify.pathtrain.noise_bank`), or a function returning it (called only
        when the machines are not cached), or None (drawn per story)
    """
    tc = cfg.training
    chosen_C = {} if chosen_C is None else chosen_C
    key = cache_key(stage=stage, seed=seed, estimate=estimate.to_dict(), mode="path",
                    edges=[[bb[0].edges, bb[1].edges] for bb in bins], training=config_to_dict(tc),
                    svm=config_to_dict(cfg.svm), identifiable=np.asarray(identifiable, bool),
                    paths=[None if sp is None else [array_digest(sp.drift[: sp.end]), array_digest(sp.force[: sp.end]),
                                                    np.asarray(sp.bounds).tolist(), sp.k0, sp.noise_std, sp.dt,
                                                    sp.cutoff_hz] for sp in paths])
    hit = cache.load(key)
    if hit is not None:
        machines, meta = hit
        _progress.info(f"[identify] {stage} pass: classifiers from the cache")
        for name, st in meta["stats"].items():  # later passes reuse the same C as in a cold run
            if "C" in st:
                chosen_C.setdefault(name, (st["C"], st.get("gamma_factor", 1.0)))
        return TrainedPass(machines, meta["stats"], True, 0.0, None)
    _progress.info(f"[identify] {stage} pass: path-driven training sets and {2 * int(np.sum(identifiable))} "
                   "kernel machines")
    coarse = stage == "coarse"
    noise = noise() if callable(noise) else noise
    n_samples = min(tc.samples, tc.coarse_samples) if coarse and tc.coarse_samples is not None else tc.samples
    sets: list[TrainingSet | None]
    machines, stats, sets = {}, {}, []
    t_sim = 0.0
    # the story law runs here (compiled, both cores); the machines of a story train on the worker
    # processes while the next story's samples are drawn: the two kinds of work overlap
    jobs = []
    with worker_pool(cfg.n_jobs if int(np.sum(identifiable)) > 0 else 1) as pool:
        for i, sp in _progress.progress(list(enumerate(paths)), desc=f"[identify] {stage} pass, stories"):
            if not identifiable[i] or sp is None:
                sets.append(None)
                continue
            t = time.perf_counter()
            S = path_training_set(sp, k0=float(estimate.k0[i]), dy=float(estimate.dy[i]),
                                  delta_eta=float(estimate.delta_eta[i]), alpha_range=bins[i][0].range,
                                  p_range=bins[i][1].range, n_samples=n_samples, spread=tc.spread,
                                  seed=seed + 7919 * i, substeps=tc.substeps,
                                  wide=tc.coarse_factor if coarse else None,
                                  path_errors=None if path_errors is None else path_errors[:, :, i], noise=noise)
            t_sim += time.perf_counter() - t
            sets.append(S)
            for param, b in zip(PARAMS, bins[i]):
                name = f"story{i + 1}_{param}"
                svm = cfg.svm if name not in chosen_C else _chosen(cfg.svm, *chosen_C[name])
                kw: dict[str, Any]
                args, kw = (S, param, b, svm, tc.test_fraction), {"seed": seed + 31 * i + len(param)}
                job = pool.apply_async(fit_ensemble, args, kw) if pool else fit_ensemble(*args, **kw)
                jobs.append((i, param, b, S, job))
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
