"""Configuration of automated identification (``configs/identify.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ..errors import InputError
from ..hla import HLAConfig


@dataclass(frozen=True, kw_only=True)
class BinsConfig:
    """Class bins of the coarse and fine passes (the paper's Tables 2-3).

    Attributes
    ----------
    alpha_coarse, p_coarse : bin widths of the coarse pass (alpha over [0, alpha_max] with
        ``alpha_max = inf(ke/k0)`` from HLA; p over ``p_range``)
    alpha_fine, p_fine : bin widths of the fine pass, over the predicted coarse bin and its
        two neighbours (boundary crossing)
    p_range : the p range of the model [1, 3] (p > 3 is nearly bilinear)
    """

    alpha_coarse: float = 0.05
    p_coarse: float = 0.4
    alpha_fine: float = 0.01
    p_fine: float = 0.1
    p_range: tuple[float, float] = (1.0, 3.0)

    def __post_init__(self):
        for name in ("alpha_coarse", "p_coarse", "alpha_fine", "p_fine"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} = {getattr(self, name)}; expected a positive bin width")
        if not 1.0 <= self.p_range[0] < self.p_range[1]:
            raise InputError(f"p_range = {list(self.p_range)}; expected [low, high] with 1 <= low < high")


@dataclass(frozen=True, kw_only=True)
class TrainingConfig:
    """Simulated half-cycle training sets.

    Attributes
    ----------
    samples : half-cycle samples per story and pass (the paper: 1500)
    n_segments : segments per half cycle (eq 18)
    spread : k0, dy and delta_eta of the simulations are drawn within +-spread (relative) of
        the current estimates
    test_fraction : share of simulations held out to measure classifier accuracy
    noise_rms : noise added to the simulations; null: the measurement's own level when it is
        known (simulated data), else estimated from the record's high-frequency floor
    max_simulations : cap per pass
    arias_fraction, tail_s : the simulations run over the strong part of the record, up to
        where ``arias_fraction`` of its Arias intensity has arrived, plus ``tail_s`` seconds
    seed : seed of the simulations (identification is reproducible)
    """

    samples: int = 1200
    n_segments: int = 10
    spread: float = 0.2
    test_fraction: float = 0.2
    noise_rms: float | None = None
    max_simulations: int = 200
    arias_fraction: float = 0.95
    tail_s: float = 5.0
    seed: int = 0

    def __post_init__(self):
        if self.samples < 20 or self.n_segments < 3:
            raise InputError("training.samples must be >= 20 and training.n_segments >= 3")
        if not 0 <= self.spread < 1 or not 0 < self.test_fraction < 1:
            raise InputError("training.spread must be in [0, 1) and training.test_fraction in (0, 1)")


@dataclass(frozen=True, kw_only=True)
class SVMConfig:
    """The kernel machines (:class:`hlaid.svm.KernelSVC`)."""

    C: float = 10.0
    gamma: float | Literal["scale", "auto"] = "scale"
    kernel: str = "rbf"
    multiclass: Literal["ddag", "ovo"] = "ddag"


@dataclass(frozen=True, kw_only=True)
class OuterConfig:
    """The outer loop: classifiers, then regressions, until the parameters settle."""

    max_iterations: int = 3
    tol: float = 0.02


@dataclass(frozen=True, kw_only=True)
class RefineConfig:
    """Replay refinement after the paper's identification.

    Attributes
    ----------
    method : ``"replay"``: least squares of the replayed against the measured floor
        accelerations over the story parameters, started from the identified values;
        ``"none"``: keep the regression/SVM result.
    parameters : which story parameters are refined.
    damping : also refine the Rayleigh damping ratio.
    band_hz : band of the compared accelerations [Hz].
    max_iterations : Levenberg-Marquardt iterations.
    """

    method: Literal["replay", "none"] = "replay"
    parameters: tuple[str, ...] = ("k0", "alpha", "p", "dy", "delta_eta")
    damping: bool = False
    band_hz: tuple[float, float] = (0.1, 20.0)
    max_iterations: int = 40

    def __post_init__(self):
        bad = set(self.parameters) - {"k0", "alpha", "p", "dy", "delta_eta"}
        if bad:
            raise InputError(f"refine.parameters: unknown {sorted(bad)}; expected k0, alpha, p, dy, delta_eta")


@dataclass(frozen=True, kw_only=True)
class IdentifyConfig:
    """Automated identification settings.

    Attributes
    ----------
    hla, bins, training, svm, outer, refine : the sections above
    aggregate : how the votes of a story's half cycles are combined: ``"mean"`` (vote-weighted
        mean of the bin centres) or ``"majority"`` (the paper's most voted bin)
    damping_ratio : Rayleigh damping of the clone (modes 1 and 2), as assumed by HLA
    cache_dir : where trained classifiers are cached (null: ``~/.cache/hlaid/svm``)
    n_jobs : worker processes for the training simulations' HLA
    """

    hla: HLAConfig = field(default_factory=HLAConfig)
    bins: BinsConfig = field(default_factory=BinsConfig)
    training: TrainingConfig = field(default_factory=TrainingConfig)
    svm: SVMConfig = field(default_factory=SVMConfig)
    outer: OuterConfig = field(default_factory=OuterConfig)
    refine: RefineConfig = field(default_factory=RefineConfig)
    aggregate: Literal["mean", "majority"] = "mean"
    damping_ratio: float = 0.05
    cache_dir: str | None = None
    n_jobs: int = 2
