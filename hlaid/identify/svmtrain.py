"""Training the alpha/p classifiers outside an identification: ``scripts/train_svm.py``.

The same code as inside :func:`hlaid.identify.identify` (:func:`~hlaid.identify.passes.train_pass`),
around a building given in the config instead of one estimated from a measurement.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from .._fileio import write_json
from ..config import config_to_dict, load_config
from ..errors import InputError
from ..motions import GroundMotion
from ..signal import lowpass
from ..specs import BuildingSpec, MotionSpec
from .cache import MachineCache
from .classify import Bins
from .config import IdentifyConfig
from .passes import PARAMS, TrainedPass, train_pass
from .tb import TBLogger
from .training import strong_motion_window


@dataclass(frozen=True, kw_only=True)
class TrainSVMConfig:
    """``configs/svm.yaml``: the building the half cycles are simulated around, the record,
    the noise, which pass, and the identification settings that govern training.

    Attributes
    ----------
    alpha_max : upper end of the coarse alpha bins (in an identification: inf(ke/k0) from HLA)
    stage : ``"coarse"`` (the Table 2-3 bins) or ``"fine"`` (0.01 / 0.1 bins over the coarse
        bin holding the building's own alpha and p, and its neighbours)
    """

    building: BuildingSpec
    motion: MotionSpec
    noise_rms: float = 0.10
    alpha_max: float = 0.6
    stage: Literal["coarse", "fine"] = "coarse"
    identify: IdentifyConfig = field(default_factory=IdentifyConfig)

    def __post_init__(self):
        if not 0 <= self.noise_rms < 10:
            raise InputError(f"noise_rms = {self.noise_rms}; expected a fraction such as 0.10")
        if not 0 < self.alpha_max <= 1:
            raise InputError(f"alpha_max = {self.alpha_max}; expected (0, 1]")


def pass_bins(building, alpha_max: float, cfg: IdentifyConfig, stage: str) -> list[tuple[Bins, Bins]]:
    b = cfg.bins
    out = []
    for i in range(building.n_stories):
        a = Bins.regular(0.0, alpha_max, b.alpha_coarse)
        p = Bins.regular(b.p_range[0], b.p_range[1], b.p_coarse)
        if stage == "fine":
            a = a.refine(int(a.label(np.array([building.alpha[i]]))[0]), b.alpha_fine, (0.0, alpha_max))
            p = p.refine(int(p.label(np.array([building.p[i]]))[0]), b.p_fine, b.p_range)
        out.append((a, p))
    return out


def train_from_config(config_path: str | Path, out: str | Path) -> tuple[TrainedPass, list]:
    """Train the classifiers a :class:`TrainSVMConfig` describes; write machines, TensorBoard
    logs and ``summary.json`` under ``out``."""
    cfg = load_config(config_path, TrainSVMConfig)
    building = cfg.building.build(source=str(config_path))
    gm = cfg.motion.load(Path(config_path).parent).resampled(200.0)
    ground = GroundMotion(dt=gm.dt, acc=lowpass(gm.acc, gm.dt, 20.0), name=gm.name)
    bins = pass_bins(building, cfg.alpha_max, cfg.identify, cfg.stage)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tb = TBLogger(str(out / "tensorboard"))
    tp = train_pass(building, strong_motion_window(ground, cfg.identify.training.arias_fraction,
                                                    cfg.identify.training.tail_s),
                    bins, np.ones(building.n_stories, bool), noise=cfg.noise_rms, cfg=cfg.identify, stage=cfg.stage,
                    seed=cfg.identify.training.seed, cache=MachineCache(out / "machines"), tb=tb)
    tb.close()
    summary = {"config": config_to_dict(cfg), "cached": tp.cached, "seconds_simulate": tp.seconds_simulate,
               "machines": {k: {s: v for s, v in st.items() if s != "confusion"} for k, st in tp.stats.items()},
               "bins": [{p: b.edges.tolist() for p, b in zip(PARAMS, bb)} for bb in bins]}
    write_json(out / "summary.json", summary)
    return tp, bins
