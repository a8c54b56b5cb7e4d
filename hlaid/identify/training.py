"""Simulated half-cycle training sets for the alpha/p classifiers.

Each simulation draws, for every story, ``alpha`` and ``p`` uniformly from that story's
current range (the classes), and ``k0``, ``dy``, ``delta_eta`` around their current
estimates; the batch simulator computes the response to the measured ground motion, noise
matched to the measurement is added, and the features come from the same HLA code path as
the measured data. One simulation therefore gives samples for every story at once.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .._workers import result, worker_pool
from ..hla import HLAConfig, run_hla
from ..hla.features import half_cycle_features
from ..measurement import Measurement
from ..model import Building
from ..motions import GroundMotion
from ..simulate import simulate_response
from ..synthetic import add_noise


@dataclass(frozen=True)
class TrainingSet:
    """Half-cycle samples of one story.

    Attributes
    ----------
    X : (sample, segment) features ``(ke - k_i) / k0``
    alpha, p : (sample,) the values the simulation used (the class targets)
    sim : (sample,) which simulation each sample came from (for a split by simulation)
    """

    X: np.ndarray
    alpha: np.ndarray
    p: np.ndarray
    sim: np.ndarray

    def __len__(self) -> int:
        return int(self.X.shape[0])


@dataclass(frozen=True)
class Ranges:
    """Per-story ``alpha`` and ``p`` ranges to draw from, each ``(story, 2)``."""

    alpha: np.ndarray
    p: np.ndarray


def draw_buildings(estimate: Building, ranges: Ranges, n: int, spread: float, rng: np.random.Generator):
    """``n`` buildings around ``estimate``: alpha, p uniform in their ranges; k0, dy, delta_eta
    uniform within ``+-spread`` (relative) of the estimate. Returns the buildings and the
    drawn ``(n, story)`` alpha and p."""
    ns = estimate.n_stories
    a = rng.uniform(ranges.alpha[:, 0], ranges.alpha[:, 1], size=(n, ns))
    p = rng.uniform(ranges.p[:, 0], ranges.p[:, 1], size=(n, ns))

    def jitter(v):
        return v * rng.uniform(1 - spread, 1 + spread, size=(n, ns))

    k0, dy, de = jitter(estimate.k0), jitter(estimate.dy), jitter(estimate.delta_eta)
    out = [estimate.replace(alpha=a[i], p=p[i], k0=k0[i], dy=dy[i], delta_eta=de[i]) for i in range(n)]
    return out, a, p


def _features_of(args):
    """Worker: noisy measurement of one simulation -> per-story features."""
    floor_acc, ground_acc, dt, mass, noise_rms, seed, hla_cfg, n_segments, yield_ratio, with_ke, disp = args
    rng = np.random.default_rng(seed)
    meas = Measurement(dt=dt, ground_acc=add_noise(ground_acc[:, None], noise_rms, rng)[:, 0],
                       floor_acc=add_noise(floor_acc, noise_rms, rng), mass=mass,
                       floor_disp=None if disp is None else add_noise(disp, noise_rms, rng))
    try:
        res = run_hla(meas, hla_cfg)
    except ValueError:  # a simulation too weak to analyse: no samples
        return [np.zeros((0, n_segments + with_ke)) for _ in range(floor_acc.shape[1])]
    return [half_cycle_features(s, n_segments, yield_ratio=yield_ratio, with_ke=with_ke).values for s in res.stories]


def simulate_training_sets(estimate: Building, motion: GroundMotion, ranges: Ranges, *, n_samples: int,
                           noise_rms: float, hla_config: HLAConfig, n_segments: int = 10, yield_ratio: float = 0.6,
                           spread: float = 0.2, batch: int = 32, max_simulations: int = 2000,
                           seed: int = 0, n_jobs: int | None = None, with_ke: bool = True,
                           progress=None) -> list[TrainingSet]:
    """Training sets for every story, at least ``n_samples`` samples each (or until
    ``max_simulations``).

    Parameters
    ----------
    estimate : current building estimate (masses, damping, k0, dy, delta_eta)
    motion : the measured ground motion (the excitation of every simulation)
    ranges : alpha and p ranges of every story
    noise_rms : noise added to every simulated channel (as the measurement's)
    hla_config : the HLA settings used on the measured data
    progress : callable ``(n_done_min, n_samples)`` for progress reports

    Returns
    -------
    list of TrainingSet, one per story
    """
    rng = np.random.default_rng(seed)
    ns = estimate.n_stories
    feats: list[list[np.ndarray]] = [[] for _ in range(ns)]
    alphas: list[list[np.ndarray]] = [[] for _ in range(ns)]
    ps: list[list[np.ndarray]] = [[] for _ in range(ns)]
    sims: list[list[np.ndarray]] = [[] for _ in range(ns)]
    counts = np.zeros(ns, dtype=int)
    n_sim = 0
    n_jobs = n_jobs or min(2, os.cpu_count() or 1)
    with worker_pool(n_jobs) as pool:  # workers ignore Ctrl-C (hlaid._workers)
        while counts.min() < n_samples and n_sim < max_simulations:
            nb = min(batch, max_simulations - n_sim)
            buildings, a, p = draw_buildings(estimate, ranges, nb, spread, rng)
            r = simulate_response(buildings, motion, substeps=4)
            ok = r.status == 0
            assert r.acc is not None and r.disp is not None  # simulate keeps the histories by default
            seeds = rng.integers(0, 2**63 - 1, size=nb)
            # HLA told to use measured floor displacements gets the simulated ones (same code path)
            with_disp = hla_config.preprocess.displacement == "measured"
            jobs = [(r.acc[b], motion.acc, motion.dt, estimate.mass, noise_rms, int(seeds[b]), hla_config, n_segments,
                     yield_ratio, with_ke, r.disp[b] if with_disp else None) for b in range(nb) if ok[b]]
            idx = np.flatnonzero(ok)
            results = result(pool.map_async(_features_of, jobs)) if pool else list(map(_features_of, jobs))
            for b, per_story in zip(idx, results):
                for s in range(ns):
                    v = per_story[s]
                    if v.shape[0]:
                        feats[s].append(v)
                        alphas[s].append(np.full(v.shape[0], a[b, s]))
                        ps[s].append(np.full(v.shape[0], p[b, s]))
                        sims[s].append(np.full(v.shape[0], n_sim + b))
                        counts[s] += v.shape[0]
            n_sim += nb
            if progress:
                progress(int(counts.min()), n_samples)
    out = []
    for s in range(ns):
        if feats[s]:
            out.append(TrainingSet(np.concatenate(feats[s]), np.concatenate(alphas[s]), np.concatenate(ps[s]),
                                   np.concatenate(sims[s])))
        else:
            out.append(TrainingSet(np.zeros((0, n_segments + with_ke)), np.zeros(0), np.zeros(0), np.zeros(0, int)))
    return out


def strong_motion_window(motion: GroundMotion, fraction: float = 0.95, tail_s: float = 5.0) -> GroundMotion:
    """The record up to where ``fraction`` of its Arias intensity has arrived, plus ``tail_s`` s."""
    e = np.cumsum(motion.acc**2)
    end = int(np.searchsorted(e, fraction * e[-1])) + int(round(tail_s / motion.dt))
    if end >= motion.npts - 1:
        return motion
    return GroundMotion(dt=motion.dt, acc=motion.acc[: end + 1], name=motion.name, source=motion.source)
