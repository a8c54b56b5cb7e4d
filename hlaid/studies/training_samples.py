"""The paper's Fig. 2: the classifiers' training sets around a known building
(``configs/svm.yaml``, ``scripts/study_training_samples.py``).

The measurement is simulated (the building under the config's record, with noise), its HLA
drift is reconstructed with the building (:mod:`hlaid.identify.drift`), and the training samples
are the story law driven along each story's path, exactly as an identification draws them
(:mod:`hlaid.identify.pathtrain`), over the coarse bins of the paper's Tables 2-3.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..hla import run_hla
from ..hla.features import half_cycle_features
from ..identify.classify import Bins
from ..identify.config import IdentifyConfig
from ..identify.drift import reconstruct_drift
from ..identify.passes import story_bins
from ..identify.pathtrain import path_training_set, story_paths
from ..identify.training import TrainingSet
from ..measurement import measured_ground
from ..specs import BuildingSpec, MotionSpec
from ..synthetic import simulate_measurement


@dataclass(frozen=True, kw_only=True)
class TrainingSamplesConfig:
    """``configs/svm.yaml``: the building the samples are drawn around, the record, the noise,
    and the identification settings that govern training (bins, training, svm).

    Attributes
    ----------
    alpha_max : upper end of the coarse alpha bins (in an identification: inf(ke/k0) from HLA)
    """

    building: BuildingSpec
    motion: MotionSpec
    noise_rms: float = 0.10
    alpha_max: float = 0.6
    identify: IdentifyConfig = field(default_factory=IdentifyConfig)

    def __post_init__(self):
        if not 0 <= self.noise_rms < 10:
            raise InputError(f"noise_rms = {self.noise_rms}; expected a fraction such as 0.10")
        if not 0 < self.alpha_max <= 1:
            raise InputError(f"alpha_max = {self.alpha_max}; expected (0, 1]")


def path_training_sets(cfg: TrainingSamplesConfig, *, noise: float, spread: float, n: int,
                       seed: int) -> tuple[list[TrainingSet], list[tuple[Bins, Bins]]]:
    """``n`` path-driven samples of every story around the config's building, along the drift
    path reconstructed from a simulated measurement of it (noise ``noise``, seed ``seed``), alpha
    and p drawn over the coarse bins, k0, dy, delta_eta within ``+-spread``; ``(sets, bins)``."""
    b = cfg.building.build()
    meas = simulate_measurement(b, cfg.motion.load(None), noise_rms=noise, seed=seed)
    res = run_hla(meas, cfg.identify.hla)
    ground = measured_ground(meas, res.band_hz[1], name="")
    paths = reconstruct_drift(res, ground, b, crossover_hz=cfg.identify.training.crossover_hz)
    bins = story_bins(np.full(b.n_stories, cfg.alpha_max), cfg.identify)
    tc = cfg.identify.training
    stories = [dataclasses.replace(s, drift=paths[:, i], force_fit=s.force) for i, s in enumerate(res.stories)]
    sps = story_paths(stories, [half_cycle_features(s, tc.n_segments) for s in stories], mass=b.mass, k0=b.k0,
                      floor_acc=meas.floor_acc, noise_rms=noise, dt=meas.dt, cutoff_hz=res.band_hz[1],
                      n_segments=tc.n_segments)
    sets = [path_training_set(sp, k0=float(b.k0[i]), dy=float(b.dy[i]), delta_eta=float(b.delta_eta[i]),
                              alpha_range=bins[i][0].range, p_range=bins[i][1].range, n_samples=n, spread=spread,
                              seed=tc.seed + i) for i, sp in enumerate(sps)]
    return sets, bins
