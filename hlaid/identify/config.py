"""Configuration of automated identification (``configs/identify.yaml``).

Import-light: this module and what it imports load neither torch, numba nor scipy, so a bad
config is refused before they load. Every numeric field declares its range (:mod:`hlaid.bounds`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import ClassVar, Literal, cast

from ..bounds import SEED, bounded, check_bounds, with_bounds
from ..errors import InputError
from ..hla.config import AUTO, HLAConfig, auto_hla_config
from ..systems import get_system
from .refiners import REFINERS

COMPARES = ("acc", "acc+drift", "disp+drift")
"""What a joint fit may compare (``refine.compare``; :mod:`hlaid.joint.compare`)."""

KERNEL_NAMES = ("linear", "poly", "rbf", "sigmoid")
"""The kernels of :data:`hlaid.svm.KERNELS`, kept here so that loading a config imports no torch
(a test checks the two agree)."""

PARAMETERS = ("k0", "alpha", "p", "dy", "delta_eta")
"""The story parameters a refinement may fit."""

MAX_CLASSES = 100
"""Most classes one classifier of a pass may have (bins of alpha or of p): a pairwise multiclass
machine trains ``n (n - 1) / 2`` binary machines, and every class needs training samples."""


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

    alpha_coarse: float = bounded(0.05, lo=0.01, hi=0.5)
    p_coarse: float = bounded(0.4, lo=0.05, hi=1.0)
    alpha_fine: float = bounded(0.01, lo=0.002, hi=0.1)
    p_fine: float = bounded(0.1, lo=0.01, hi=0.5)
    p_range: tuple[float, float] = bounded((1.0, 3.0), lo=1.0, hi=50.0)

    def __post_init__(self):
        check_bounds(self, prefix="bins.")
        if not self.p_range[0] < self.p_range[1]:
            raise InputError(f"bins.p_range = {list(self.p_range)}; expected [low, high] with 1 <= low < high")
        classes = {"alpha_coarse": (1.0, self.alpha_coarse),  # alpha over [0, inf(ke/k0)], at most [0, 1]
                   "p_coarse": (self.p_range[1] - self.p_range[0], self.p_coarse),
                   "alpha_fine": (3 * self.alpha_coarse, self.alpha_fine),  # a coarse bin and its neighbours
                   "p_fine": (3 * self.p_coarse, self.p_fine)}
        for name, (width, step) in classes.items():
            n = math.ceil(width / step - 1e-9)
            if n > MAX_CLASSES:
                raise InputError(f"bins.{name} = {step:g} makes {n} classes over a width of {width:g}; expected at "
                                 f"most {MAX_CLASSES} (a wider bin)")


@dataclass(frozen=True, kw_only=True)
class TrainingConfig:
    """The classifiers' training sets: the story law driven along each story's drift path
    (:mod:`hlaid.identify.pathtrain`), one feature vector per story and sample (every yielding
    half cycle's segment slopes), alpha and p drawn from the class bins and k0, dy, delta_eta
    around the current estimate. After the first outer iteration the path is reconstructed
    (HLA's drift above ``crossover_hz``, the current estimate's replayed drift below,
    :mod:`hlaid.identify.drift`) and HLA's half cycles, ke and k0 are analysed again along it.

    Attributes
    ----------
    crossover_hz : the corner of the path reconstruction's complementary filters [Hz], at most 10
    samples : samples per story and pass (the paper: 1500). 800 with the cross-validated gamma
        is as close on Table 1 as 1200 with gamma "scale" was (paper method alone 5.5 % mean
        against 5.9 %) and a fifth faster; the coarse pass, which only picks the bin the fine
        pass is centred on, draws at most 400
    n_segments : segments per half cycle (eq 18)
    spread : k0, dy and delta_eta of the samples are drawn within +-spread (relative) of the
        current estimates (in the coarse pass, whose dy and delta_eta come from regressions on a
        guessed alpha and p, within a factor 3)
    test_fraction : share of samples held out to measure classifier accuracy
    noise_rms : noise of the training samples; null: the measurement's own level when it is
        known (simulated data), else estimated from the record's high-frequency floor
    seed : seed of the samples (identification is reproducible)
    """

    crossover_hz: float = bounded(1.0, lo=1e-3, hi=10.0, unit="Hz")
    samples: int = bounded(800, lo=20, hi="TRAINING")
    n_segments: int = bounded(10, lo=3, hi=100)
    spread: float = bounded(0.2, lo=0.0, hi=1.0, hi_open=True)
    test_fraction: float = bounded(0.2, lo=0.01, hi=0.9)
    noise_rms: float | None = bounded(None, lo=0.0, hi=10.0, hi_open=True)
    seed: int = with_bounds(SEED, 0)

    def __post_init__(self):
        check_bounds(self, prefix="training.")


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
    n_bags, bag_fraction : every classifier is an ensemble of
        ``n_bags`` machines, each trained on a random ``bag_fraction`` of the samples; each
        votes, and ``aggregate`` combines the votes (1: one machine on all samples). 5 voted as
        well as 7 on Table 1's 15 runs (paper method alone 5.3 % mean against 5.2 %) and train in
        five sevenths of the time
    """

    C: float = bounded(10.0, lo=1e-6, hi=1e9)
    gamma: float | Literal["scale", "auto"] = bounded("scale", lo=1e-9, hi=1e9)
    kernel: str = "rbf"
    multiclass: Literal["ddag", "ovo"] = "ddag"
    standardize: bool = True
    C_grid: tuple[float, ...] | None = bounded((1000.0, 10000.0), lo=1e-6, hi=1e9)
    gamma_grid: tuple[float, ...] | None = bounded((0.03, 0.1), lo=1e-6, hi=1e6)
    cv_folds: int = bounded(2, lo=2, hi=10)
    cv_samples: int = bounded(400, lo=20, hi="TRAINING")
    n_bags: int = bounded(5, lo=1, hi=100)
    bag_fraction: float = bounded(0.5, lo=0.01, hi=1.0)

    def __post_init__(self):
        check_bounds(self, prefix="svm.")
        if self.kernel not in KERNEL_NAMES:
            raise InputError(f"svm.kernel = {self.kernel!r} is unknown; expected one of {', '.join(KERNEL_NAMES)}")
        if self.C_grid is not None and len(self.C_grid) == 0:
            raise InputError("svm.C_grid = []; expected positive values (or null)")
        if self.gamma_grid is not None and len(self.gamma_grid) == 0:
            raise InputError("svm.gamma_grid = []; expected positive factors of gamma (or null)")


@dataclass(frozen=True, kw_only=True)
class OuterConfig:
    """The outer loop: classifiers, then regressions, until the parameters settle. From the
    second iteration on, each runs along the drift paths reconstructed with the last estimate,
    with k0 fitted along them (least squares of the story law's force against the measured
    force, the other parameters held; :mod:`hlaid.identify.loopfit`).

    Attributes
    ----------
    max_iterations, tol : at most this many iterations; stop when the largest relative
        change of a parameter is below ``tol``
    """

    max_iterations: int = bounded(3, lo=1, hi=100)
    tol: float = bounded(0.02, lo=1e-9, hi=10.0)

    def __post_init__(self):
        check_bounds(self, prefix="outer.")


@dataclass(frozen=True, kw_only=True)
class RefineConfig:
    """The refinement of the paper's estimate against the measured floor accelerations
    (:data:`hlaid.identify.refiners.REFINERS`). Every refinement first fits k0 alone (HLA's
    k0 is its least certain output and the regressions amplify its error) and runs the
    regressions again with it, then every parameter of the identifiable stories.

    Attributes
    ----------
    Each of ``method``, ``parameters``, ``damping`` and ``band_hz`` may be ``"auto"`` (the
    default): chosen from the record(s) by :func:`hlaid.identify.auto.resolve_settings`, which says
    why (docs/identification.md, "Settings chosen from the data").

    method : ``"eiv"``: errors in variables, maximum likelihood with the true ground as
        a nuisance: the residuals whitened against the ground noise carried to the floors by the
        time-varying tangent of the replay (every channel's noise a common fraction of its RMS),
        fitted from the regressions' building. Where that fit misses the data by more than
        ``restart_ratio`` times its noise, stops on ``max_iterations``, or the tangent is
        unstable or larger than ``tangent_max_mb``, least squares runs instead (with its
        restart), then the errors-in-variables fit once more from its optimum if that one is
        consistent with the noise; the clone says which (``clone.paper.refine["tangent"]``). On
        Table 1 at 10 % noise: 0.92 % mean, 4.26 % worst against 1.39 / 8.96 % by least squares.
        ``"least_squares"``: plain least squares of the normalised residuals (the fall-back and
        the comparison baseline, ``configs/identify_leastsquares.yaml``; the steel frame's
        clones, whose misfit is model error, not sensor noise). ``"none"``: keep the
        regressions' and classifiers' estimate. ``"auto"``: ``least_squares`` where HLA chose a
        first-mode band (the records are not a shear building's above it: the misfit is model
        error), else ``eiv``
    parameters : which story parameters are refined (without ``k0``: no k0 stage). ``"auto"``:
        all five, without ``k0`` where the floor masses are unknown and no mass ratios are given
        (the replay fit of k0 is then ill-conditioned: docs/validation.md)
    damping : also refine the Rayleigh damping ratio. ``"auto"``: where HLA found the assumed
        damping over-corrects (``force.damping`` chosen ``regression``)
    band_hz : band of the compared accelerations [Hz]. ``"auto"``: the band the records hold
        (:func:`hlaid.identify.auto.records_band`) where HLA chose a first-mode band, HLA's band
        where one is given, else 0.1-20 Hz
    max_iterations : evaluations of the residuals per fit
    tangent_max_mb : the errors-in-variables weighting is used only where the tangent (and its
        step Jacobians) takes at most this many MiB; above it, least squares (said in the clone's
        diagnostics). Its time grows alike: a 20-story building under El Centro (54 s) would need
        1.3 GiB and minutes of whitening; Table 1 (3 stories) 0.1 GiB
    compare : what a joint fit of several records (or of one that stays elastic) compares
        (:data:`hlaid.joint.compare.COMPARES`): ``"acc"`` the floor accelerations, ``"acc+drift"``
        also the story drifts of the measured floor displacements, ``"disp+drift"`` floor
        displacements and story drifts (least squares: the errors-in-variables weighting models
        accelerations only). ``"auto"``: ``acc+drift`` where the records' floor displacements
        resolve every story's drift (HLA's ``preprocess.displacement`` chosen ``measured``;
        ``disp+drift`` there where the band is the records' band of a first-mode-band building),
        else ``acc``. On the steel frame the drifts put the next event's peak drift in the right
        story (worst story error 23 -> 16 %)
    restart_ratio : when the least-squares cost exceeds this multiple of ``0.5 N sigma^2`` (N
        residuals, sigma the measurement's noise level), the fit misses the data by more than its
        noise: it runs again, every story's parameters, from a neutral start (alpha 0.2, p 2,
        delta_eta 0.5, dy a tenth of the story's peak drift, k0 1.5x the estimate) and the result
        with the lower cost is kept (the restart only if at least 20 % lower). At the true
        building the ratio was 0.25-0.64 on Table 1 and 30 random buildings (band-passing keeps
        part of the noise); the five random runs that stopped at local optima had 2.3-23, three
        of them the restart brings to their true optimum. null: never restart. On real records
        the misfit is mostly model error, so the restart runs there too and is kept when it fits
        clearly better: on the steel frame's s3 record its clone predicted the other records
        better (mean R 0.891 -> 0.955)
    """

    method: str = AUTO
    parameters: tuple[str, ...] | Literal["auto"] = AUTO
    damping: bool | Literal["auto"] = AUTO
    band_hz: tuple[float, float] | Literal["auto"] = bounded(AUTO, lo=0.0, hi=50_000.0, unit="Hz")
    max_iterations: int = bounded(40, lo=1, hi=10_000)
    tangent_max_mb: float = bounded(1024.0, lo=1.0, hi="TANGENT_MB", unit="MiB")
    restart_ratio: float | None = bounded(1.0, lo=1e-6, hi=1e6)
    compare: str = AUTO

    def __post_init__(self):
        check_bounds(self, prefix="refine.")
        if self.compare not in COMPARES and self.compare != AUTO:
            raise InputError(f"refine.compare = {self.compare!r} is unknown; expected one of "
                             f"{', '.join(repr(k) for k in (*COMPARES, AUTO))}")
        if self.method not in REFINERS and self.method != AUTO:
            raise InputError(f"refine.method = {self.method!r} is unknown; expected one of "
                             f"{', '.join(repr(k) for k in (*REFINERS, AUTO))}")
        bad = set() if self.parameters == AUTO else set(self.parameters) - set(PARAMETERS)
        if bad:
            raise InputError(f"refine.parameters: unknown {sorted(bad)}; expected k0, alpha, p, dy, delta_eta or auto")
        if self.band_hz != AUTO:
            lo, hi = self.band_hz
            if not lo < hi:
                raise InputError(f"refine.band_hz = {list(self.band_hz)}; expected [low, high] with 0 <= low < high")

    def unresolved(self) -> list[str]:
        """The settings still ``"auto"``."""
        return [f.name for f in dataclasses.fields(self) if isinstance(getattr(self, f.name), str)
                and getattr(self, f.name) == AUTO]


@dataclass(frozen=True, kw_only=True)
class IdentifyConfig:
    """Automated identification settings.

    Attributes
    ----------
    hla, bins, training, svm, outer, refine : the sections above. The record-dependent settings are
        ``"auto"`` by default (``hla``: the band, the damping handling and the yield ratio,
        :func:`hlaid.hla.auto.resolve_hla`; ``refine``: method, parameters, damping and band):
        :func:`hlaid.identify.auto.resolve_settings` chooses them from the record(s), and the
        clone keeps the choices (``clone.settings``). A value given overrides.
    aggregate : how the votes of a story's half cycles are combined: ``"mean"`` (vote-weighted
        mean of the bin centres) or ``"majority"`` (the paper's most voted bin)
    damping_ratio : Rayleigh damping of the clone (modes 1 and 2), as assumed by HLA
    cache_dir : where trained classifiers are cached (null: ``~/.cache/hlaid/svm``)
    n_jobs : worker processes on which the kernel machines train while the next story's
        samples are drawn
    system : the structural system (:data:`hlaid.systems.SYSTEMS`: ``steel-moment-frame``,
        ``rc-frame``, ``generic``). Its prior holds the parameters the data say little about
        (maximum a posteriori over all of a clone's events, :mod:`hlaid.joint.fit`), and its
        collapse law is the assessment's. null: ``generic`` where a prior is needed (several
        events, a record that stays elastic) and a single yielding record identified by its data
        alone
    """

    hla: HLAConfig = field(default_factory=auto_hla_config)
    bins: BinsConfig = field(default_factory=BinsConfig)
    training: TrainingConfig = field(default_factory=TrainingConfig)
    svm: SVMConfig = field(default_factory=SVMConfig)
    outer: OuterConfig = field(default_factory=OuterConfig)
    refine: RefineConfig = field(default_factory=RefineConfig)
    aggregate: Literal["mean", "majority"] = "mean"
    damping_ratio: float = bounded(0.05, lo=0.0, hi=1.0, hi_open=True)
    cache_dir: str | None = None
    n_jobs: int = bounded(2, lo=1, hi=1024)

    system: str | None = None

    def __post_init__(self):
        check_bounds(self)
        if self.system is not None:
            get_system(self.system, "system")

    def unresolved(self) -> list[str]:
        """The settings still ``"auto"`` (keys as in the config file)."""
        return [f"hla.{k}" for k in self.hla.unresolved()] + [f"refine.{k}" for k in self.refine.unresolved()]

    def resolved(self) -> ResolvedSettings:
        """The settings the stages use, with no ``"auto"`` left (:class:`ResolvedSettings`); one
        still ``"auto"`` is an InputError (the settings are chosen from the records first:
        :func:`hlaid.identify.auto.resolve_settings`)."""
        todo = [k for k in self.unresolved() if k in ResolvedSettings.KEYS]
        if todo:
            raise InputError(f"{todo[0]} is 'auto': it is chosen from the record(s) first (hlaid.identify.auto."
                             "resolve_settings, hlaid.hla.resolve_hla)")
        rc = self.refine
        return ResolvedSettings(method=rc.method, parameters=tuple(cast("tuple[str, ...]", rc.parameters)),
                                damping=bool(rc.damping), band_hz=cast("tuple[float, float]", tuple(rc.band_hz)),
                                compare=rc.compare, yield_ratio=float(self.hla.stiffness.yield_ratio))


@dataclass(frozen=True)
class ResolvedSettings:
    """The settings of an :class:`IdentifyConfig` that may be ``"auto"``, resolved: each of its own
    type, none ``"auto"`` (:meth:`IdentifyConfig.resolved`). The choices made for them, with their
    evidence, are :class:`hlaid.identify.auto.Resolution`'s (the clone keeps them:
    :class:`hlaid.record.Settings`).

    Attributes
    ----------
    method, parameters, damping, band_hz, compare : the replay fit's (``refine.*``)
    yield_ratio : HLA's (``hla.stiffness.yield_ratio``)
    """

    method: str
    parameters: tuple[str, ...]
    damping: bool
    band_hz: tuple[float, float]
    compare: str
    yield_ratio: float

    KEYS: ClassVar[tuple[str, ...]] = ("refine.method", "refine.parameters", "refine.damping", "refine.band_hz",
                                       "refine.compare", "hla.stiffness.yield_ratio")
