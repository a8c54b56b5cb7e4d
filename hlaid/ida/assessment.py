"""Collapse fragility with epistemic uncertainty and a re-occupancy indicator.

:func:`assess` draws an ensemble of buildings from the clone's identification uncertainty
(:func:`clone_ensemble`), runs an IDA of every member over the same records, and combines:

* **fragility band**: each member's lognormal collapse fragility (maximum likelihood with
  right-censoring), refitted on ``n_boot`` bootstrap resamples of the records; the median
  curve and the ``ci`` band are pointwise quantiles over all member x resample curves, so the
  band holds both the identification (epistemic) and the record-to-record sampling uncertainty.
  Every member's IM is Sa(T1) at the *nominal* clone's T1 (one common axis).
* **at the building's own record** (``own_motion``, the ground motion it just experienced):
  its Sa(T1); P(collapse) = the ensemble mean of the members' fragilities there, with the
  band over members; P(peak drift > limit) from the members' IDA curves at that intensity
  (fraction of records); and the members' own response to that record (peak and residual
  drift ratio, one batch simulation).
* **re-occupancy indicator** after ATC-20's placards (green INSPECTED, yellow RESTRICTED USE,
  red UNSAFE), from two measures and stated thresholds (:class:`ReoccupancyThresholds`,
  assumptions, not a code requirement): the upper (``quantile``) end over the ensemble of
  P(collapse) at the experienced intensity (red >= 10 %: the collapse probability ASCE 7-16
  accepts at MCE_R for risk category II; yellow >= 2 %), and of the residual drift ratio of
  the clone under the record (red >= 1 %, yellow >= 0.5 %: FEMA P-58-1's residual drift
  damage states DS3 "major realignment, repair may not be feasible" and DS2 "realignment
  necessary"). The worse of the two decides; a clone whose fit is not consistent with the
  noise (``uncertainty.info["fit_consistent"]`` false) is at least yellow. The IDA runs the
  undamaged clone: damage accumulated in the event is not carried into the collapse
  probability (an aftershock assessment would start from the clone's state at the end of the
  record).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.special import ndtr

from .. import _progress
from ..errors import InputError
from ..events.evidence import survivors
from ..uncertainty.config import N_ENSEMBLE, PLACARDS
from ..uncertainty.ensemble import check_ensemble_size, check_uncertain_clone

COLOURS = ("green", "yellow", "red")


@dataclass(frozen=True, kw_only=True)
class ReoccupancyThresholds:
    """Thresholds of the re-occupancy indicator (assumptions; see the module docstring).

    p_collapse_yellow, p_collapse_red : P(collapse) at the experienced intensity
    residual_yellow, residual_red : residual inter-story drift ratio under the record
    quantile : the ensemble quantile compared with them (0.9: nine members in ten below)
    """

    p_collapse_yellow: float = 0.02
    p_collapse_red: float = 0.10
    residual_yellow: float = 0.005
    residual_red: float = 0.01
    quantile: float = 0.90

    def __post_init__(self):
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and 0 < v < 1):
                raise InputError(f"reoccupancy threshold {k} = {v!r}; expected a fraction in (0, 1)")
        if self.p_collapse_yellow > self.p_collapse_red or self.residual_yellow > self.residual_red:
            raise InputError("reoccupancy thresholds: yellow must not exceed red")


@dataclass(frozen=True, eq=False)
class Assessment:
    """What :func:`assess` found (IM in g, drift ratios dimensionless).

    Attributes
    ----------
    n_ensemble, n_records, n_boot, ci : ensemble members, records, record bootstraps per member,
        confidence level of the bands
    im, im_label, period : intensity measure and the common period [s] of Sa(T1)
    im_grid : (G,) IM values of the fragility curves [g]
    fragility_median, fragility_lo, fragility_hi : (G,) P(collapse | IM): pointwise median and band
    collapse_median : median collapse intensity [g] (median over members of their fitted medians)
    collapse_median_band : (lo, hi) its ``ci`` band over members x record resamples [g]
    beta : median dispersion of the members' fragilities
    member_median, member_beta : (n_ensemble,) each member's fitted fragility
    own_im : the experienced record's IM [g] (None without ``own_motion``)
    p_collapse, p_collapse_band : P(collapse) at ``own_im`` (mean over members) and its ``ci`` band
        over members x record resamples
    drift_limits : drift ratios of the exceedance probabilities
    p_exceed, p_exceed_band : per limit, P(peak drift > limit) at ``own_im`` (fraction of records,
        mean over members) and its band over members x record resamples
    own_peak_drift, own_residual_drift : (n_ensemble,) the members' largest story peak and
        residual drift ratio under the experienced record
    indicator : ``"green"``, ``"yellow"``, ``"red"`` (None without ``own_motion``)
    reasons : why (one line per measure, and one when the clone's fit is inconsistent or it
        collapses under an event it was identified from)
    events : per event the clone was identified from whose ground motion is at hand: ``name``,
        ``im`` [g], ``p_collapse`` (mean over members) and ``p_collapse_band``, from the undamaged
        fragility (the building survived every one of them)
    survival : the ensemble conditioned on those events (:meth:`hlaid.events.evidence.Survival.to_dict`:
        members drawn and rejected for collapsing under them, the nominal clone's own check)
    thresholds : the :class:`ReoccupancyThresholds` used, as a mapping
    notes, timing : what was decided on the way and how long it took
    """

    n_ensemble: int
    n_records: int
    n_boot: int
    ci: float
    im: str
    im_label: str
    period: float
    im_grid: np.ndarray
    fragility_median: np.ndarray
    fragility_lo: np.ndarray
    fragility_hi: np.ndarray
    collapse_median: float
    collapse_median_band: tuple
    beta: float
    member_median: np.ndarray
    member_beta: np.ndarray
    own_im: float | None = None
    p_collapse: float | None = None
    p_collapse_band: tuple | None = None
    drift_limits: tuple = ()
    p_exceed: tuple = ()
    p_exceed_band: tuple = ()
    own_peak_drift: np.ndarray | None = None
    own_residual_drift: np.ndarray | None = None
    indicator: str | None = None
    reasons: tuple = ()
    events: tuple = ()
    survival: dict = field(default_factory=dict)
    thresholds: dict = field(default_factory=dict)
    notes: tuple = ()
    timing: dict = field(default_factory=dict)

    @property
    def placard(self) -> str | None:
        """The ATC-20 placard wording of :attr:`indicator`."""
        return None if self.indicator is None else PLACARDS[self.indicator]

    def to_dict(self) -> dict:
        """JSON-able mapping of every field (arrays as lists)."""
        from ..clone import jsonable

        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["placard"] = self.placard
        return jsonable(d)

    def plot(self, ax=None):
        """The fragility band with the experienced intensity marked; returns the figure."""
        import matplotlib.pyplot as plt

        fig, ax = (plt.subplots(figsize=(6.4, 4.2)) if ax is None else (ax.figure, ax))
        ax.fill_between(self.im_grid, self.fragility_lo, self.fragility_hi, color="C0", alpha=0.25,
                        label=f"{self.ci:.0%} band (identification x record sampling)")
        ax.plot(self.im_grid, self.fragility_median, "C0", lw=2,
                label=f"median curve (collapse median {self.collapse_median:.3g} g)")
        if self.own_im is not None:
            ax.axvline(self.own_im, color="k", ls="--", lw=1.2)
            colour = {"green": "tab:green", "yellow": "goldenrod", "red": "tab:red"}[self.indicator]
            lo, hi = self.p_collapse_band
            ax.plot([self.own_im], [self.p_collapse], "o", color=colour, ms=9, mec="k",
                    label=f"experienced {self.im_label} = {self.own_im:.3g} g: P(collapse) {self.p_collapse:.1%} "
                          f"[{lo:.1%}, {hi:.1%}]")
        ax.set_xlabel(f"{self.im_label} [g]")
        ax.set_ylabel("P(collapse)")
        ax.set_ylim(0, 1)
        ax.set_xlim(0, float(self.im_grid[-1]))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
        ax.set_title(f"Collapse fragility over {self.n_ensemble} clones x {self.n_records} records", fontsize=10)
        return fig


def _member_fit(res, idx=None) -> tuple[float, float]:
    from .fragility import fit_capacities

    c = res.collapse_im if idx is None else res.collapse_im[idx]
    cens = res.censored_im if idx is None else res.censored_im[idx]
    obs, cen = c[np.isfinite(c)], cens[np.isfinite(cens)]
    if obs.size < 2 or np.ptp(np.log(obs)) == 0:
        return np.nan, np.nan
    return fit_capacities(obs, cen)


def _fragility(im, median, beta):
    im = np.asarray(im, dtype=float)
    return ndtr(np.log(np.maximum(im, 1e-300) / median) / beta)


def assess(clone, records, *, n_ensemble: int = N_ENSEMBLE, ida_config=None, own_motion=None, seed: int = 0,
           n_boot: int = 30, ci: float = 0.90, thresholds: ReoccupancyThresholds | None = None,
           event_motions=()) -> Assessment:
    """IDA over an ensemble of the clone, fragility band, risk at the experienced intensity.

    Parameters
    ----------
    clone : a :class:`~hlaid.clone.Clone` with ``uncertainty``
    records : what :func:`hlaid.ida.run_ida` takes (``"builtin-suite"``, a folder, files, GroundMotions)
    n_ensemble : members drawn from the uncertainty (1..100000)
    ida_config : :class:`hlaid.ida.IDAConfig` (its records are ignored; default: 10 levels)
    own_motion : the ground motion the building just experienced (GroundMotion, [mm/s^2]);
        None: no probabilities at it and no indicator
    seed : seeds the ensemble and the record bootstrap
    n_boot : record bootstrap resamples per member for the band (0: members only)
    ci : level of the bands
    thresholds : the re-occupancy indicator's (default :class:`ReoccupancyThresholds`)
    event_motions : ground motions of the clone's other events at hand (GroundMotions, matched to
        its events; ``own_motion`` is one too); the others are read from the events' files. The
        ensemble is conditioned on surviving them (:func:`hlaid.events.evidence.survivors`)

    Returns
    -------
    Assessment
    """
    from ..io.records import as_motions
    from .measures import get_intensity_measure, period_for
    from .prepare import prepare_building

    t0 = time.perf_counter()
    cfg, n_ensemble = _checked(clone, ida_config, own_motion, n_ensemble, n_boot, ci)
    thr = thresholds or ReoccupancyThresholds()
    motions = as_motions(records, units=cfg.units)
    if len(motions) < 2:
        raise InputError(f"assess needs at least 2 records for a fragility; got {len(motions)}")
    nominal, notes = prepare_building(clone, pdelta=cfg.pdelta, heights=cfg.heights_mm,
                                      gravity_load=cfg.gravity_load_n())
    measure = get_intensity_measure(cfg.im)
    period = period_for(measure, nominal, cfg.period)
    if measure.needs_period:
        cfg = cfg.replace(period=period)
        notes.append(f"every member's {measure.label} at the nominal clone's T1 = {period:.3f} s")
    if clone.uncertainty.info and clone.uncertainty.info.get("fit_consistent") is False:
        notes.append("identification misfit above the noise level: the ensemble describes the curvature at a "
                     "fit that does not match the record (intervals not trustworthy)")
        _progress.warn(notes[-1])
    cfg = cfg.replace(collapse=nominal.collapse.to_dict() if nominal.collapse is not None else "none")
    surv = survivors(clone, n_ensemble, seed=seed, prepare=member_preparer(cfg), motions=[own_motion, *event_motions],
                     drift_limit=cfg.drift_limit, max_step=cfg.max_step)
    notes.extend(surv.notes)
    members = list(surv.members)
    results = _ensemble_idas(clone, members, cfg, motions)
    t_ida = time.perf_counter() - t0
    band = _FragilityBand(results, n_boot, ci, seed, notes)
    out = dict(n_ensemble=len(members), n_records=len(motions), n_boot=n_boot, ci=float(ci), im=measure.name,
               im_label=measure.label, period=period, **band.summary(), thresholds=asdict(thr),
               drift_limits=tuple(results[0].exceedance_limits), survival=surv.to_dict(),
               events=_at_events(surv, band, measure, period))
    if own_motion is not None:
        out.update(_at_own_motion(clone, members, results, band, own_motion, measure, period, cfg, thr))
        if surv.nominal_survives is False:
            out["reasons"] += (f"the clone collapses under {surv.nominal_collapsed_in}, an event it was identified "
                               "from: its risk is overstated (check the story heights and the collapse law), so the "
                               "indicator is at least yellow",)
            out["indicator"] = COLOURS[max(COLOURS.index(out["indicator"]), 1)]
    out["notes"] = tuple(notes)
    out["timing"] = {"ida_s": t_ida, "total_s": time.perf_counter() - t0,
                     "runs": int(sum(r.timing.get("runs", 0) for r in results))}
    return Assessment(**out)


def member_preparer(cfg):
    """The building an ensemble member runs under the IDA settings ``cfg`` (whose ``collapse`` is the
    nominal clone's law, so every member follows the same one)."""
    from .prepare import prepare_building

    def prepare(member):
        return prepare_building(member, pdelta=cfg.pdelta, heights=cfg.heights_mm, gravity_load=cfg.gravity_load_n(),
                                collapse=cfg.collapse)[0]
    return prepare


def _at_events(surv, band: _FragilityBand, measure, period) -> tuple:
    """P(collapse) of the undamaged fragility at the intensity of every event the clone was
    identified from (each survived)."""
    from .measures import intensity

    q, fits, ok = band.q, band.fits, band.ok
    out = []
    for name, m in surv.motions.available:
        im = float(intensity(m, measure.name, period=None if not measure.needs_period else period)[0])
        p_all = _fragility(im, band.par[:, 0], band.par[:, 1])
        out.append({"name": name, "im": im, "p_collapse": float(_fragility(im, fits[ok, 0], fits[ok, 1]).mean()),
                    "p_collapse_band": [float(v) for v in np.quantile(p_all, (q[0], q[2]))]})
    return tuple(out)


def _checked(clone, ida_config, own_motion, n_ensemble, n_boot, ci):
    """The IDA config (default: 10 levels) and ensemble size of :func:`assess`, its arguments checked."""
    from ..motions import GroundMotion
    from .config import IDAConfig

    check_uncertain_clone(clone)
    n_ensemble = check_ensemble_size(n_ensemble, "n_ensemble")
    if isinstance(n_boot, bool) or not isinstance(n_boot, int) or not 0 <= n_boot <= 10_000:
        raise InputError(f"n_boot = {n_boot!r}; expected a whole number in 0..10000")
    if isinstance(ci, bool) or not isinstance(ci, (int, float)) or not 0 < ci < 1:
        raise InputError(f"ci = {ci!r}; expected a confidence level in (0, 1), e.g. 0.9")
    if own_motion is not None and not isinstance(own_motion, GroundMotion):
        raise InputError(f"own_motion must be a GroundMotion (hlaid.read(path, kind='motion')), got "
                         f"{type(own_motion).__name__}")
    cfg = IDAConfig(n_levels=10) if ida_config is None else ida_config
    if not isinstance(cfg, IDAConfig):
        raise InputError(f"ida_config must be an hlaid.ida.IDAConfig, got {type(cfg).__name__}")
    return cfg, n_ensemble


def _ensemble_idas(clone, members, cfg, motions) -> list:
    """The IDA of every member of the ensemble."""
    from .analysis import ida_from_config

    return [ida_from_config(clone.member(b), cfg, motions)
            for b in _progress.progress(members, desc="ensemble IDA", unit="clones")]


class _FragilityBand:
    """The members' lognormal collapse fragilities and their record-bootstrap resamples.

    ``fits`` ``(member, 2)`` median and beta (NaN for a member that collapsed under fewer than 2
    records, left out with a note); ``par`` ``(fit, 2)`` every finite fit of the members and of
    ``n_boot`` record resamples (``boots``) of each.
    """

    def __init__(self, results: list, n_boot: int, ci: float, seed: int, notes: list[str]):
        R = results[0].collapse_im.size
        self.fits = np.array([_member_fit(r) for r in results])
        self.ok = np.isfinite(self.fits[:, 0])
        if not self.ok.any():
            raise InputError("no ensemble member collapsed under 2 or more records: raise the IDA levels or hunting "
                             "(ida_config.max_hunt) to reach collapse")
        if not self.ok.all():
            notes.append(f"{int((~self.ok).sum())} member(s) collapsed under fewer than 2 records and were left out")
        rng = np.random.default_rng(int(seed) + 1)
        curves_par = [self.fits[self.ok]]
        self.boots = [rng.integers(0, R, R) for _ in range(n_boot)]
        for idx in self.boots:
            curves_par.append(np.array([_member_fit(r, idx) for r, good in zip(results, self.ok) if good]))
        par = np.concatenate(curves_par)
        self.par = par[np.isfinite(par[:, 0])]
        self.q = (0.5 - ci / 2, 0.5, 0.5 + ci / 2)

    def summary(self) -> dict:
        """The :class:`Assessment` fields of the fragility band."""
        par, fits, ok, q = self.par, self.fits, self.ok, self.q
        hi_im = float(np.quantile(par[:, 0] * np.exp(2.0 * par[:, 1]), 0.95))
        grid = np.linspace(0.0, hi_im, 200)
        P = _fragility(grid[None, :], par[:, :1], par[:, 1:])
        lo_c, med_c, hi_c = np.quantile(P, q, axis=0)
        med_band = tuple(float(v) for v in np.quantile(par[:, 0], (q[0], q[2])))
        return dict(im_grid=grid, fragility_median=med_c, fragility_lo=lo_c, fragility_hi=hi_c,
                    collapse_median=float(np.median(fits[ok, 0])), collapse_median_band=med_band,
                    beta=float(np.median(fits[ok, 1])), member_median=fits[:, 0], member_beta=fits[:, 1])


def _at_own_motion(clone, members, results, band: _FragilityBand, own_motion, measure, period, cfg,
                   thr: ReoccupancyThresholds) -> dict:
    """The :class:`Assessment` fields at the experienced record: P(collapse) and drift-limit
    exceedance with their bands, the members' replays and the re-occupancy indicator."""
    from ..simulate import simulate_response
    from .measures import intensity

    q, fits, ok = band.q, band.fits, band.ok
    own_im = float(intensity(own_motion, measure.name, period=None if not measure.needs_period else period)[0])
    pm = _fragility(own_im, fits[ok, 0], fits[ok, 1])
    p_all = _fragility(own_im, band.par[:, 0], band.par[:, 1])  # members x record resamples
    limits = np.array(results[0].exceedance_limits)
    hits = []  # (member, record, limit)
    for r in results:
        e = r.edp_at([own_im])[:, 0]
        e = np.where(np.isnan(e), np.inf, e)  # above the highest level run: counted as exceeding
        hits.append(e[:, None] > limits[None, :])
    hit = np.array(hits, dtype=float)
    exceed = hit.mean(axis=1)
    ex_all = np.concatenate([exceed] + [hit[:, idx].mean(axis=1) for idx in band.boots])
    prepare = member_preparer(cfg)
    bs = [prepare(clone.member(b)) for b in members]
    sub = max(1, int(np.ceil(own_motion.dt / cfg.max_step)))
    h = np.array([np.asarray(b.height, dtype=float) for b in bs])
    sim = simulate_response(bs, own_motion, substeps=sub, outputs="peaks", stop_drift=cfg.drift_limit * h)
    peak = np.max(sim.peak_drift / h, axis=1)
    resid = np.max(np.abs(sim.residual_drift) / h, axis=1)
    resid = np.where(sim.status == 0, resid, np.inf)  # stopped or diverged: no re-occupancy
    colour, reasons = _indicator(p_all, resid, thr)
    if clone.uncertainty.info and clone.uncertainty.info.get("fit_consistent") is False:
        reasons.append(f"the identified clone does not fit the record to the noise level (misfit ratio "
                       f"{clone.uncertainty.info.get('misfit_ratio', float('nan')):.2g}): its intervals are not "
                       "trustworthy, so the indicator is at least yellow")
        colour = COLOURS[max(COLOURS.index(colour), 1)]
    return dict(own_im=own_im, p_collapse=float(pm.mean()),
                p_collapse_band=tuple(float(v) for v in np.quantile(p_all, (q[0], q[2]))),
                p_exceed=tuple(float(v) for v in exceed.mean(axis=0)),
                p_exceed_band=tuple(tuple(float(v) for v in np.quantile(ex_all[:, j], (q[0], q[2])))
                                    for j in range(ex_all.shape[1])),
                own_peak_drift=peak, own_residual_drift=resid, indicator=colour, reasons=tuple(reasons))


def _indicator(p_collapse: np.ndarray, residual: np.ndarray, thr: ReoccupancyThresholds):
    pc = float(np.quantile(p_collapse, thr.quantile))
    rd = float(np.quantile(np.where(np.isfinite(residual), residual, 1.0), thr.quantile))  # stopped runs: 100 %
    level_p = 2 if pc >= thr.p_collapse_red else 1 if pc >= thr.p_collapse_yellow else 0
    level_r = 2 if rd >= thr.residual_red else 1 if rd >= thr.residual_yellow else 0
    q = f"its {100 * thr.quantile:.0f}th percentile over the ensemble"
    reasons = [f"P(collapse) at the experienced intensity, {q} (members x record resamples; the indicator reads "
               f"this upper end, the figure reported is their mean): {pc:.1%} (yellow >= {thr.p_collapse_yellow:.0%}, "
               f"red >= {thr.p_collapse_red:.0%})",
               f"residual drift ratio under the record, {q}: "
               + ("runs stopped at the drift limit" if rd >= 1.0 else f"{rd:.2%}")
               + f" (yellow >= {thr.residual_yellow:.1%}, red >= {thr.residual_red:.1%})"]
    return COLOURS[max(level_p, level_r)], reasons
