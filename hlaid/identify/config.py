"""Configuration of automated identification (``configs/identify.yaml``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from ..errors import InputError
from ..hla import HLAConfig
from ..limits import check_count


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
    mode : ``"path"`` (default): the story law is driven along the story's own drift path
        (:mod:`hlaid.identify.pathtrain`), one feature vector per story and sample (every
        yielding half cycle's segment slopes); ``"simulate"``: dynamic simulations of the
        whole building, HLA of each, one sample per simulated half cycle (the first
        version, kept for comparison)
    path : drift path of ``mode: path``: ``"replay"`` (HLA's drift above ``crossover_hz``,
        the current estimate's replayed drift below, :mod:`hlaid.identify.drift`) or ``"hla"``
    crossover_hz : the corner of the complementary filters of ``path: replay`` [Hz], at most 10
    substeps : RK4 sub-steps per sample of the path-driven story law (one: 1e-5 of the force RMS
        from the converged value on Table 1, far below the sensor noise; docs/identification.md)
    coarse_factor : in the coarse pass (whose dy and delta_eta come from regressions with a
        guessed alpha and p) dy and delta_eta are drawn log-uniformly within this factor (1..100)
        of their estimates, not within ``spread``
    reanalyse : along a reconstructed path, HLA's half cycles, ke and k0 are analysed again
        (against the low-passed force) before the regressions and the features
    samples : samples per story and pass (the paper: 1500; with ``mode: simulate`` half cycles).
        800 with the cross-validated gamma is as close on Table 1 as 1200 with gamma "scale"
        was (paper method alone 5.5 % mean against 5.9 %) and a fifth faster
    coarse_samples : at most this many samples per story in the coarse pass of ``mode: path``
        (null: ``samples``). Its machines only pick the coarse bin the fine pass is centred on;
        400 scored as 800 did on Table 1 (paper method alone 5.4 % mean against 5.5 %) and
        saves ~1 s
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
    path_errors : with ``mode: path``, this many simulated error histories of the drift path
        per pass (0..64; 0: none, the training samples follow the path itself). The measurement
        process (noise, HLA, the path reconstruction) is repeated on the current estimate and
        each sample is driven along ``path - error`` (the true drift such a path stands for),
        its features taken with the path's own operator like the measured ones
        (:mod:`hlaid.identify.patherrors`). Measured on Table 1 (15 runs): 4 histories no
        better than 0; 16 the paper method's mean 6.0 -> 5.6 %, the refined clone the same
        (docs/identification.md); off by default
    """

    mode: Literal["path", "simulate"] = "path"
    path: Literal["replay", "hla"] = "replay"
    crossover_hz: float = 1.0
    reanalyse: bool = True
    substeps: int = 1
    coarse_factor: float = 3.0
    samples: int = 800
    coarse_samples: int | None = 400
    n_segments: int = 10
    spread: float = 0.2
    test_fraction: float = 0.2
    noise_rms: float | None = None
    max_simulations: int = 200
    arias_fraction: float = 0.95
    tail_s: float = 5.0
    seed: int = 0
    path_errors: int = 0

    def __post_init__(self):
        check_count(self.samples, "TRAINING", "training.samples")
        if self.coarse_samples is not None:
            check_count(self.coarse_samples, "TRAINING", "training.coarse_samples")
            if self.coarse_samples < 20:
                raise InputError(f"training.coarse_samples = {self.coarse_samples}; expected >= 20, or null")
        check_count(self.max_simulations, "TRAINING", "training.max_simulations")
        if self.samples < 20 or self.n_segments < 3:
            raise InputError("training.samples must be >= 20 and training.n_segments >= 3")
        if not 0 <= self.spread < 1 or not 0 < self.test_fraction < 1:
            raise InputError("training.spread must be in [0, 1) and training.test_fraction in (0, 1)")
        if self.max_simulations < 1:
            raise InputError(f"max_simulations = {self.max_simulations}; expected an integer >= 1")
        if not 0 < self.arias_fraction <= 1:
            raise InputError(f"arias_fraction = {self.arias_fraction}; expected a fraction in (0, 1]")
        if not 0 <= self.tail_s < math.inf:
            raise InputError(f"tail_s = {self.tail_s}; expected a duration >= 0 [s]")
        if self.noise_rms is not None and not 0 <= self.noise_rms < 10:
            raise InputError(f"noise_rms = {self.noise_rms}; expected a fraction such as 0.10, or null")
        if self.seed < 0:
            raise InputError(f"seed = {self.seed}; expected an integer >= 0")
        if not 1 <= self.coarse_factor <= 100:
            raise InputError(f"training.coarse_factor = {self.coarse_factor}; expected a factor in 1..100")
        if not 1 <= self.substeps <= 64:
            raise InputError(f"training.substeps = {self.substeps}; expected 1..64")
        if not 0 <= self.path_errors <= 64:
            raise InputError(f"training.path_errors = {self.path_errors}; expected a number of error histories "
                             "in 0..64")
        if not 0 < self.crossover_hz <= 10:
            raise InputError(f"training.crossover_hz = {self.crossover_hz}; expected a frequency in (0, 10] Hz "
                             "(below the band that carries the loops' shape)")


@dataclass(frozen=True, kw_only=True)
class SVMConfig:
    """The kernel machines (:class:`hlaid.svm.KernelSVC`).

    Attributes
    ----------
    C, gamma, kernel, multiclass : of every machine (``multiclass: ddag`` is the paper's)
    standardize : features centred and scaled by their training mean and std (stored with
        the machine, applied to the measured features)
    C_grid : when set, C is chosen from these values by ``cv_folds``-fold cross-validation
        on the training samples (per machine; cached with it); ``C`` is then unused
    gamma_grid : when set, gamma is chosen in the same cross-validation (every pair with
        ``C_grid``) from these factors of ``gamma`` resolved on the standardised training
        features (``"scale"``: ``1 / n_features``). Measured on Fig. 2 (Table 1, 1500 samples):
        94-99 % noise-free where ``scale`` with C from {10, 100, 1000} scores 91-95 %, and 75-87 %
        at 10 % noise where it scores 73-83 % (docs/identification.md); null: ``gamma`` as it is
    cv_folds, cv_samples : folds of that cross-validation, and at most this many training
        samples in it (evenly spaced)
    n_bags, bag_fraction : with ``training.mode: path``, every classifier is an ensemble of
        ``n_bags`` machines, each trained on a random ``bag_fraction`` of the samples; each
        votes, and ``aggregate`` combines the votes (1: one machine on all samples). 5 voted as
        well as 7 on Table 1's 15 runs (paper method alone 5.3 % mean against 5.2 %) and train in
        five sevenths of the time
    """

    C: float = 10.0
    gamma: float | Literal["scale", "auto"] = "scale"
    kernel: str = "rbf"
    multiclass: Literal["ddag", "ovo"] = "ddag"
    standardize: bool = True
    C_grid: tuple[float, ...] | None = (1000.0, 10000.0)
    gamma_grid: tuple[float, ...] | None = (0.03, 0.1)
    cv_folds: int = 2
    cv_samples: int = 400
    n_bags: int = 5
    bag_fraction: float = 0.5

    def __post_init__(self):
        from ..svm import KERNELS
        if not 0 < self.C < math.inf:
            raise InputError(f"C = {self.C}; expected a positive number")
        if not isinstance(self.gamma, str) and not 0 < self.gamma < math.inf:
            raise InputError(f"gamma = {self.gamma}; expected a positive number, 'scale' or 'auto'")
        if self.kernel not in KERNELS:
            raise InputError(f"kernel = {self.kernel!r} is unknown; expected one of {', '.join(sorted(KERNELS))}")
        if self.C_grid is not None and (len(self.C_grid) == 0 or not all(c > 0 for c in self.C_grid)):
            raise InputError(f"svm.C_grid = {list(self.C_grid)}; expected positive values (or null)")
        if self.gamma_grid is not None and (len(self.gamma_grid) == 0 or not all(0 < g < math.inf
                                                                                 for g in self.gamma_grid)):
            raise InputError(f"svm.gamma_grid = {list(self.gamma_grid)}; expected positive factors of gamma "
                             "(or null)")
        if not 2 <= self.cv_folds <= 10:
            raise InputError(f"svm.cv_folds = {self.cv_folds}; expected 2..10")
        if self.cv_samples < 20 or not 1 <= self.n_bags <= 100 or not 0 < self.bag_fraction <= 1:
            raise InputError("svm.cv_samples must be >= 20, svm.n_bags in 1..100 and svm.bag_fraction in (0, 1]")


@dataclass(frozen=True, kw_only=True)
class OuterConfig:
    """The outer loop: classifiers, then regressions, until the parameters settle.

    Attributes
    ----------
    max_iterations, tol : at most this many iterations; stop when the largest relative
        change of a parameter is below ``tol``
    k0 : along a reconstructed drift path, k0 from HLA again (``"hla"``) or, then, by least
        squares of the story law's force along the path against the measured force with the
        other parameters held (``"loop"``, :mod:`hlaid.identify.loopfit`)
    first_fine : the first iteration runs the fine pass too (along HLA's drift); False: only
        the coarse pass, so every fine pass runs along a reconstructed path (measured on Table 1:
        2.2 s faster, paper method alone 5.7 % mean / 30.4 % worst against 5.5 / 27.1 %)
    """

    max_iterations: int = 3
    tol: float = 0.02
    k0: Literal["hla", "loop"] = "loop"
    first_fine: bool = True

    def __post_init__(self):
        if self.max_iterations < 1:
            raise InputError(f"max_iterations = {self.max_iterations}; expected an integer >= 1")
        if not 0 < self.tol < math.inf:
            raise InputError(f"tol = {self.tol}; expected a positive relative change such as 0.02")


@dataclass(frozen=True, kw_only=True)
class RefineConfig:
    """Replay refinement after the paper's identification.

    Attributes
    ----------
    method : ``"replay"``: least squares of the replayed against the measured floor
        accelerations over the story parameters, started from the identified values;
        ``"none"``: keep the regression/SVM result.
    upper_factor : upper bound of k0, dy and delta_eta in the replay search, as a factor of
        their start (null: open above)
    parameters : which story parameters are refined.
    damping : also refine the Rayleigh damping ratio.
    band_hz : band of the compared accelerations [Hz].
    max_iterations : Levenberg-Marquardt iterations.
    ftol : the search stops when a step lowers the cost by less than this fraction of it
    substeps : RK4 sub-steps per sample of the replays. Fewer, or a looser ``ftol``, is faster
        but was measured to move the optimum on ill-conditioned random buildings (2 sub-steps
        at 200 Hz: one run's worst parameter from 63 % to 3000 %; ftol 1e-6: another's from
        36 % to 2500 %, docs/identification.md), so the defaults stay tight
    jac_substeps : RK4 sub-steps of the replays that build the finite-difference Jacobian.
        The Jacobian only steers the search; the residuals (``substeps``) define the optimum,
        so 2 sub-steps here cut the refinement of a 20-story building by a third and left the
        Table 1 and random-building studies as they were. One sub-step was faster still but
        moved two random buildings to worse optima (docs/identification.md, "Speed")
    ground_noise : ``"tangent"`` (default since session 9): maximum likelihood with the true ground
        as a nuisance: the residuals whitened against the ground noise carried to the floors by
        the time-varying tangent of the replay (:class:`hlaid.identify.eiv.TangentWhitener`; every
        channel's noise a common fraction of its RMS), fitted from the regressions' building with
        the tangent of its replay. Where that fit misses the data by more than ``restart_ratio``
        times its noise, stops on ``max_iterations``, or the tangent is unstable or larger than
        ``tangent_max_mb``, least
        squares runs instead (with its restart), then the errors-in-variables fit once more from
        its optimum if that one is consistent with the noise; the clone says which
        (``diagnostics.refine.tangent``). On Table 1 at 10 % noise: 0.92 % mean, 4.26 % worst
        against 1.39 / 8.96 % by least squares; 30 random buildings: median and 90th percentile
        in docs/identification.md. ``"ignore"``: plain least squares of the normalised residuals
        (``configs/identify_leastsquares.yaml``); ``"whiten"``: the residuals whitened per frequency
        by their covariance with the measured ground's noise carried to the floors by the linear
        (initial-stiffness) building being evaluated, ``Sigma(w) = diag(s_f^2) + s_g^2 |L h|^2``
        (:mod:`hlaid.identify.eiv`), both refinement stages, no restart
    ground_memory_s : with ``ground_noise: tangent``, seconds of the floors' response to each
        ground sample kept in the tangent; null: four first-mode decay times of the building the
        tangent is taken at, ``4 T1 / (2 pi zeta)``, within 2-10 s (4.9 s for Table 1;
        :func:`hlaid.identify.refine.ground_memory`)
    tangent_max_mb : the errors-in-variables weighting is used only where the tangent (and its
        step Jacobians) takes at most this many MiB; above it, least squares (said in the clone's
        diagnostics). Its time grows alike: a 20-story building under El Centro (54 s) would need
        1.3 GiB and minutes of whitening; Table 1 (3 stories) 0.1 GiB
    eiv_start : with ``ground_noise: tangent``, where the errors-in-variables fit starts and its
        tangent is taken: ``"regressions"`` (default: the regressions' building, least squares
        only as the fall-back) or ``"least_squares"`` (session 8's order: least squares and its
        restart first, the errors-in-variables fit as a last stage from that optimum). The second
        weights with a tangent taken nearer the truth: 30 random buildings median 1.40 % against
        1.56 %, 90th percentile 10.0 against 9.7 %, Table 1 0.90 / 4.07 % against 0.92 / 4.26 %
        (docs/identification.md), at about 3 s more per identification
    eiv_ftol : ``ftol`` of the errors-in-variables fits (``ground_noise: tangent``). Their cost is a
        negative log-likelihood whose minimum is ``N/2`` noise variances, so a step that lowers it
        by less than this fraction moves it by ``eiv_ftol N / 2`` units of log-likelihood: 1e-6 is
        about 0.01 for a 50 s record at 200 Hz (a step of about a tenth of a standard error). At
        ``ftol``'s 1e-10 the fit found the same optimum in 19 evaluations instead of 6 (the rest
        rejected steps shrinking the trust region), 1.2 s more on Table 1. (``ftol``'s warning
        concerns least squares stopping far from the data; such an errors-in-variables fit
        falls back, and the random-building study is measured with 1e-6)
    restart_ratio : when the refined cost exceeds this multiple of ``0.5 N sigma^2`` (N residuals,
        sigma the measurement's noise level), the fit misses the data by more than its noise:
        the refinement runs again, every story's parameters, from a neutral start (alpha 0.2,
        p 2, delta_eta 0.5, dy a tenth of the story's peak drift, k0 1.5x the estimate) and the
        result with the lower cost is kept (the restart only if at least 20 % lower). At the
        true building the ratio was 0.25-0.64 on Table 1 and 30 random buildings (band-passing
        keeps part of the noise); the five random runs that stopped at local optima had 2.3-23,
        three of them the restart brings to their true optimum (docs/identification.md). Not
        with ``ground_noise: whiten`` (its cost has another scale). null: never restart. On real
        records the misfit is mostly model error, so the restart runs there too and is kept when
        it fits clearly better: on the steel frame's s3 record its clone predicted the other
        records better (mean R 0.891 -> 0.955) with ke about 40 % off HLA's (8.8 % before;
        docs/validation.md)
    """

    method: Literal["replay", "none"] = "replay"
    parameters: tuple[str, ...] = ("k0", "alpha", "p", "dy", "delta_eta")
    damping: bool = False
    band_hz: tuple[float, float] = (0.1, 20.0)
    max_iterations: int = 40
    upper_factor: float | None = 10.0
    ftol: float = 1e-10
    substeps: int = 4
    jac_substeps: int = 2
    ground_noise: Literal["ignore", "whiten", "tangent"] = "tangent"
    ground_memory_s: float | None = None
    eiv_start: Literal["regressions", "least_squares"] = "regressions"
    eiv_ftol: float = 1e-6
    tangent_max_mb: float = 1024.0
    restart_ratio: float | None = 1.0

    def __post_init__(self):
        if self.restart_ratio is not None and not 0 < self.restart_ratio < math.inf:
            raise InputError(f"refine.restart_ratio = {self.restart_ratio}; expected a positive number (or null)")
        if self.ground_noise not in ("ignore", "whiten", "tangent"):
            raise InputError(f"refine.ground_noise = {self.ground_noise!r}; expected 'ignore', 'whiten' or 'tangent'")
        if self.ground_memory_s is not None and not 0 < self.ground_memory_s <= 60:
            raise InputError(f"refine.ground_memory_s = {self.ground_memory_s}; expected seconds in (0, 60], e.g. 7.5")
        if not 0 < self.ftol < 1:
            raise InputError(f"refine.ftol = {self.ftol}; expected a fraction in (0, 1), e.g. 1e-10")
        if not 0 < self.tangent_max_mb < math.inf:
            raise InputError(f"refine.tangent_max_mb = {self.tangent_max_mb}; expected MiB > 0, e.g. 1024")
        if self.eiv_start not in ("regressions", "least_squares"):
            raise InputError(f"refine.eiv_start = {self.eiv_start!r}; expected 'regressions' or 'least_squares'")
        if not 0 < self.eiv_ftol < 1:
            raise InputError(f"refine.eiv_ftol = {self.eiv_ftol}; expected a fraction in (0, 1), e.g. 1e-6")
        if not 1 <= self.substeps <= 64:
            raise InputError(f"refine.substeps = {self.substeps}; expected 1..64")
        if not 1 <= self.jac_substeps <= 64:
            raise InputError(f"refine.jac_substeps = {self.jac_substeps}; expected 1..64")
        if self.upper_factor is not None and not self.upper_factor > 1:
            raise InputError(f"refine.upper_factor = {self.upper_factor}; expected a factor > 1 (or null)")
        bad = set(self.parameters) - {"k0", "alpha", "p", "dy", "delta_eta"}
        if bad:
            raise InputError(f"refine.parameters: unknown {sorted(bad)}; expected k0, alpha, p, dy, delta_eta")
        lo, hi = self.band_hz
        if not (0 <= lo < hi < math.inf):
            raise InputError(f"band_hz = {list(self.band_hz)}; expected [low, high] with 0 <= low < high")
        if self.max_iterations < 1:
            raise InputError(f"max_iterations = {self.max_iterations}; expected an integer >= 1")


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
    n_jobs : worker processes: the kernel machines of the path-driven passes train on them while
        the next story's samples are drawn (mode path); the training simulations' HLA (mode simulate)
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

    def __post_init__(self):
        if not 0 <= self.damping_ratio < 1:
            raise InputError(f"damping_ratio = {self.damping_ratio}; expected a ratio in [0, 1) such as 0.05")
        if self.n_jobs < 1:
            raise InputError(f"n_jobs = {self.n_jobs}; expected an integer >= 1")
