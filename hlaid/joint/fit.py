"""One set of story parameters fitted to a building's events in time order, the state carried.

The events are one history of one building (:class:`~hlaid.joint.series.EventSeries`: each
replay starts where the previous one left the building), so one set of parameters explains them
all. The search is maximum a posteriori in prior units (:mod:`hlaid.joint.vector`): every story
parameter and the damping ratio move, and the prior holds those the data say little about.
Each event's residuals are weighted by the information they hold; the weights are estimated
again at the optimum and the search repeated from there until they settle (:func:`map_refine`), so a misfit
that is model error, not sensor noise, does not make the data look more certain than they are.
:func:`joint_fit` runs it with an identification config's settings, :func:`best_fit` picks
among searches from several starts and :func:`flags` says where each parameter came from.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import _progress
from ..errors import InputError
from ..identify.config import IdentifyConfig
from ..identify.refine import RefineResult, fit_residuals
from ..identify.refiners import fit_or_fall_back
from ..measurement import Measurement
from ..model import Building
from ..model.state import BuildingState
from ..model.uncertainty import ParameterUncertainty
from ..record import ParameterFlag
from .laws import with_laws
from .priors import StructuralPrior
from .series import REPLAY_RATE_RATIO, WIDE_RATE_RATIO, EventSeries, at_replay_rate, event_series
from .vector import MASS_RATIO_LIMIT, GaussianPrior, PosteriorResiduals, PriorVector, SystemPrior, at_limit

WEIGHT_ROUNDS = 3
"""At most this many searches, each with the weights of the last one's optimum."""

LATER_FTOL = 1e-3
"""A search that starts at an earlier search's optimum (a later weighting round, a start's
search continued) stops where a step lowers the cost by less than this fraction of it: the
reweighting moves the optimum little, and steps below it change a log evidence by about a tenth
of a unit (the steel frame's second round spent its 20 evaluations lowering the cost from 89.74
to 89.36)."""


@dataclass(frozen=True, eq=False)
class JointFit:
    """The outcome of :func:`map_refine`.

    Attributes
    ----------
    building : the MAP building
    result : the last search (in prior units: ``result.x``, ``result.jacobian`` over the data's
        weighted residuals and the prior's)
    vector : the prior-unit layout of ``result.x``
    covariance : ``(P, P)`` the Laplace posterior covariance in prior units
    prior_sd : ``(P,)`` each entry's standard deviation under the prior alone
    states : per event the state the building is left in
    events : per event its weight, ``n_eff`` and residual RMS at the optimum
    rounds : searches run
    seconds : wall time
    squares : ``(event,)`` each event's sum of squared (unweighted) residuals at the optimum
    prior_cost : half the prior's squared residuals at the optimum
    log_det_hessian : ``log det`` of the Gauss-Newton matrix of the posterior at the optimum
    log_det_prior : ``log det`` of the prior's precision over the free entries
    compare : what the events' residuals compared (:data:`hlaid.joint.compare.COMPARES`)
    series : the events' residuals the search ran (for screens from this fit: the candidate
        laws, the prefixes; None where not kept)
    jac_weights : ``(event,)`` the events' weights ``result.jacobian``'s data rows carry
    prior : the prior searched under (None where not kept)
    """

    building: Building
    result: RefineResult
    vector: PriorVector
    covariance: np.ndarray
    prior_sd: np.ndarray
    states: list[BuildingState]
    events: list[dict]
    rounds: int
    seconds: float
    squares: np.ndarray
    prior_cost: float
    log_det_hessian: float = float("nan")
    log_det_prior: float = float("nan")
    compare: str = "acc"
    series: EventSeries | None = None
    jac_weights: np.ndarray | None = None
    prior: SystemPrior | GaussianPrior | None = None

    @property
    def laws(self) -> tuple[str, ...] | None:
        """The stories' laws (None: every entry free)."""
        return self.vector.laws

    @property
    def n_eff(self) -> np.ndarray:
        """``(event,)`` each event's effective number of samples at the optimum."""
        return np.array([e["n_eff"] for e in self.events], dtype=float)

    def score(self, n_eff: np.ndarray) -> float:
        """The negative log posterior with each event's misfit variance at its maximum
        (profiled): ``sum_e n_eff_e / 2 log(squares_e) + prior_cost``; ``n_eff`` ``(event,)``
        common to the fits compared."""
        return float(np.sum(0.5 * np.asarray(n_eff) * np.log(np.maximum(self.squares, 1e-300))) + self.prior_cost)

    def log_evidence(self, n_eff: np.ndarray | None = None) -> float:
        """Laplace log marginal likelihood of the records under this fit's model (its free
        entries and prior): ``-score + 1/2 log det P_prior - 1/2 log det H``, ``n_eff`` common to
        the fits compared (default its own). Only differences between fits of the same events
        mean anything."""
        n_eff = self.n_eff if n_eff is None else n_eff
        return float(-self.score(n_eff) + 0.5 * self.log_det_prior - 0.5 * self.log_det_hessian)

    def informed(self) -> np.ndarray:
        """``(P,)`` how much the data narrowed each entry: 1 - posterior sd / prior sd (0: the
        prior alone; near 1: the data)."""
        sd = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        return np.clip(1.0 - sd / np.maximum(self.prior_sd, 1e-12), 0.0, 1.0)


def map_refine(start: Building, measurements: Sequence[Measurement], prior: SystemPrior | GaussianPrior | None = None,
               *, system: StructuralPrior | None = None, band_hz=(0.1, 20.0), ground_noise: str = "ignore",
               damping: bool = True, y0: np.ndarray | None = None, names: Sequence[str] = (),
               max_iterations: int = 40, ftol: float = 1e-8, substeps: int = 4, jac_substeps: int = 2,
               tangent_max_mb: float | None = None, compare: str = "acc", laws: Sequence[str] | None = None,
               rounds: int = WEIGHT_ROUNDS, series: EventSeries | None = None, warm: bool = False,
               masses: bool = False, rate_ratio: float = REPLAY_RATE_RATIO) -> JointFit:
    """Maximum a posteriori parameters of one building from its events in time order.

    Parameters
    ----------
    start : the search's start (the paper's estimate of the most informative event, an earlier
        clone, or the prior's median building; with ``laws``, its fixed entries set by
        :func:`hlaid.joint.laws.with_laws`)
    measurements : the events, oldest first
    prior : the prior over the prior-unit vector (None: ``system``'s, with k0 around ``start``'s)
    system : the structural system (with ``prior`` None)
    band_hz : band of the compared channels [Hz]
    ground_noise : ``"ignore"`` (least squares of each event's residuals) or ``"tangent"``
        (each event's residuals whitened against its ground sensor's noise, errors in variables,
        the tangent taken once, along the start's replay from the state it carries into that
        event; accelerations only)
    damping : the damping ratio is fitted (else held at ``start``'s)
    y0 : the state before the first event (``(4*story,)``; None: at rest)
    names : the events' labels (for the states)
    compare : what the residuals compare (:data:`hlaid.joint.compare.COMPARES`)
    laws : each story's law (:data:`hlaid.joint.laws.LAWS`; None: every entry free)
    rounds : at most this many searches, each with the weights of the last one's optimum
    series : the events' residuals already built (for fits of the same events under other laws:
        one tangent for all); None: built here
    warm : ``start`` is an earlier search's optimum: every round stops at :data:`LATER_FTOL`
        (else only the rounds after the first)
    masses : the floor-mass ratios are fitted too (the masses unknown; equal under the prior,
        :data:`hlaid.joint.vector.MASS_BETA`)
    rate_ratio : the replays' samples per period of the band's upper corner
        (:func:`hlaid.joint.series.at_replay_rate`)
    """
    t0 = time.perf_counter()
    if prior is None and system is None:
        raise InputError("map_refine needs a prior or a structural system")
    vector = PriorVector(start, damping=damping, laws=laws, masses=masses)
    if prior is None:
        assert system is not None
        prior = SystemPrior(system, vector, start.k0)
    if series is None:
        events = [at_replay_rate(m, float(band_hz[1]), rate_ratio) for m in measurements]
        series = event_series(start, events, band_hz, ground_noise, substeps, jac_substeps, y0, tangent_max_mb,
                              compare=compare)
    rr, info, fits, weights = _weighted_rounds(series, vector, prior, start, rounds=rounds, warm=warm, ftol=ftol,
                                               max_iterations=max_iterations, jac_substeps=jac_substeps)
    current = rr.building
    for d, w in zip(info, series.weights):
        d["weight"] = float(w)
    J = np.asarray(rr.jacobian)
    H = J.T @ J
    cov = _pinv(H)
    Jp = _prior_jacobian(prior, vector, np.asarray(rr.x))
    P = Jp.T @ Jp
    prior_sd = np.sqrt(np.clip(np.diag(_pinv(P)), 0.0, None))
    states = series.states(current, names)
    parts, _, _ = series.run([current])
    squares = np.array([float(np.sum(r[0] ** 2)) for r in parts])
    prior_cost = 0.5 * float(np.sum(prior.residuals(np.asarray(rr.x)) ** 2))
    return JointFit(building=current, result=rr, vector=vector, covariance=cov, prior_sd=prior_sd, states=states,
                    events=info, rounds=fits, seconds=time.perf_counter() - t0, squares=squares,
                    prior_cost=prior_cost, **log_dets(J, Jp), compare=compare,
                    series=series, jac_weights=None if weights is None else weights.copy(),
                    prior=prior)


def _weighted_rounds(series: EventSeries, vector: PriorVector, prior, start: Building, *, rounds: int, warm: bool,
                     ftol: float, max_iterations: int, jac_substeps: int
                     ) -> tuple[RefineResult, list[dict], int, np.ndarray | None]:
    """The searches of :func:`map_refine`: each with the events' weights at the last one's optimum,
    until the weights settle or ``rounds`` are done. Returns the last search, the events' weights
    record, the searches made and the weights of the last one."""
    info: list[dict] = []
    current = start
    rr: RefineResult | None = None
    weights: np.ndarray | None = None
    fits = 0
    with _progress.stage(f"[identify] joint fit over {len(series.events)} event(s)", unit="rounds") as st:
        for _ in range(max(int(rounds), 1)):
            info = series.reweigh(current)
            if weights is not None and bool(np.all(np.abs(np.log(series.weights / weights)) < np.log(1.2))):
                break
            weights = series.weights.copy()
            fits += 1
            _progress.step(f"[identify] joint fit over {len(series.events)} event(s), round {fits}: effective "
                           "samples " + ", ".join(f"{d['n_eff']:.0f}" for d in info))
            tol = max(ftol, LATER_FTOL) if (warm or fits > 1) else ftol
            if fits > 1:
                vector.x0 = vector.of(current)  # each round from the last one's optimum
            rr = fit_residuals(vector, PosteriorResiduals(series, vector, prior), max_iterations=max_iterations,
                               ftol=tol, jac_substeps=jac_substeps)
            current = rr.building
            st.update(1, note=f"cost {rr.cost_initial:.4g} -> {rr.cost_final:.4g}")
    assert rr is not None
    return rr, info, fits, weights


def _pinv(A: np.ndarray) -> np.ndarray:
    """The pseudo-inverse of ``A`` (NaN where it has no finite one: an SVD that did not converge)."""
    try:
        return np.linalg.pinv(A)
    except (np.linalg.LinAlgError, ValueError):
        return np.full_like(A, np.nan)


def log_dets(J: np.ndarray, Jp: np.ndarray) -> dict[str, float]:
    """``log_det_hessian`` and ``log_det_prior`` of a fit whose posterior Jacobian is ``J`` and
    prior Jacobian ``Jp`` (both ``(rows, P)``), over the entries that move the residuals: an entry
    held at a bound of its transform (a zero column of ``J``, e.g. a damping ratio at its cap) is
    fixed there, in the Hessian and the prior alike, instead of making both singular."""
    J, Jp = np.asarray(J, dtype=float), np.asarray(Jp, dtype=float)
    keep = np.any(J != 0.0, axis=0)
    Jk, Jpk = J[:, keep], Jp[:, keep]
    return {"log_det_hessian": _logdet(Jk.T @ Jk), "log_det_prior": _logdet(Jpk.T @ Jpk)}


def _logdet(A: np.ndarray) -> float:
    """``log det A`` of a symmetric positive semi-definite matrix (NaN where it is singular)."""
    try:
        sign, value = np.linalg.slogdet(A)
    except (np.linalg.LinAlgError, ValueError):
        return float("nan")
    return float(value) if sign > 0 else float("nan")


def _prior_jacobian(prior, vector: PriorVector, x: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """Finite-difference Jacobian of the prior's residuals at ``x``."""
    r0 = prior.residuals(x)
    cols = [(prior.residuals(x + h * (np.arange(x.size) == j)) - r0) / h for j in range(x.size)]
    return np.array(cols).T


INFORMED = 0.5
"""A parameter whose posterior standard deviation is more than ``1 - INFORMED`` of its prior's
is flagged as coming from the prior: the data narrowed it by less than half."""


def flags(fit: JointFit, prior: str = "prior") -> tuple[ParameterFlag, ...]:
    """Per fitted parameter: value, where it comes from (``"data"``, or ``prior`` where the data
    narrowed it by less than :data:`INFORMED`: ``"prior"`` for the structural system's,
    ``"earlier events"`` for an update's), and whether it sits at a bound of the search
    (:func:`~hlaid.joint.vector.at_limit`: alpha at 0 or 0.95, p at 1, delta_eta below
    1e-6, a damping ratio at the search's clip, a floor mass ratio at its clip: a value the search
    could only approach)."""
    b, informed = fit.building, fit.informed()
    lm = fit.vector.log_mass_ratios(fit.vector.of(b)) if fit.vector.masses else None
    out = []
    for (name, i), inf in zip(fit.vector.slots, informed):
        if name == "damping":
            value = b.damping.ratio
        elif name == "damping2":
            value = float(b.damping.ratio2 if b.damping.ratio2 is not None else b.damping.ratio)
        elif name == "mass":
            value = float(b.mass[i])
        elif name == "cy":
            value, name = float(b.dy[i]), "dy"
        else:
            value = float(getattr(b, name)[i])
        at = at_limit(name, value) or (name == "mass" and lm is not None and i < lm.size
                                       and abs(abs(lm[i]) - MASS_RATIO_LIMIT) < 1e-3)
        out.append(ParameterFlag(name=name, story=i + 1 if i >= 0 else None, value=float(value),
                                 source="data" if inf >= INFORMED else prior, informed=float(inf),
                                 at_limit=bool(at)))
    return tuple(out)


def joint_fit(start: Building, measurements: Sequence[Measurement], prior, cfg: IdentifyConfig, *, y0=None,
              names: Sequence[str] = (), k0_ref: np.ndarray | None = None, laws: Sequence[str] | None = None,
              rounds: int = WEIGHT_ROUNDS, max_iterations: int | None = None, warm: bool = False,
              masses: bool | None = None) -> JointFit:
    """:func:`map_refine` with the settings of ``cfg.refine`` (errors in variables per event for
    ``method: eiv`` where the accelerations alone are compared, least squares otherwise), the
    stories following ``laws`` (None: every entry free; with a structural system's prior the
    start's fixed entries are set by the laws). A numerical failure of the errors-in-variables
    weighting falls back to least squares, with a note
    (:func:`hlaid.identify.refiners.fit_or_fall_back`). ``masses``: the floor-mass ratios are
    fitted (None: :func:`masses_free`). Where the band reaches the higher modes
    (:func:`wide_band`) and the damping is fitted, the second mode's Rayleigh ratio is fitted
    apart from the first's (:attr:`hlaid.model.Damping.ratio2`, from the first's)."""
    rc, settings = cfg.refine, cfg.resolved()
    damping, compare = settings.damping, settings.compare
    masses = masses_free(measurements, cfg) if masses is None else masses
    if damping and wide_band(cfg) and start.damping.kind == "rayleigh" and start.damping.ratio2 is None:
        start = start.replace(damping=dataclasses.replace(start.damping, ratio2=start.damping.ratio))
    if laws is not None and isinstance(prior, StructuralPrior):
        start = with_laws(start, laws, prior)
    if isinstance(prior, StructuralPrior):
        prior = SystemPrior(prior, PriorVector(start, damping=damping, laws=laws, masses=masses),
                            start.k0 if k0_ref is None else k0_ref)
    fit = functools.partial(map_refine, start, measurements, prior, band_hz=settings.band_hz,
                            damping=damping, y0=y0, names=names, max_iterations=max_iterations or rc.max_iterations,
                            tangent_max_mb=rc.tangent_max_mb, compare=compare, laws=laws, rounds=rounds, warm=warm,
                            masses=masses, rate_ratio=WIDE_RATE_RATIO if wide_band(cfg) else REPLAY_RATE_RATIO)
    eiv = settings.method == "eiv" and compare == "acc"
    return fit_or_fall_back(fit, "tangent" if eiv else "ignore")


def wide_band(cfg: IdentifyConfig) -> bool:
    """Whether the replay fit's band reaches above HLA's (a first-mode band): the records'
    higher modes are compared, so what sets them (the floor masses, the higher modes' damping)
    can be fitted."""
    hla, rb = cfg.hla.preprocess.band_hz, cfg.refine.band_hz
    if not isinstance(hla, (tuple, list)) or not isinstance(rb, (tuple, list)):
        return False
    return float(rb[1]) > 1.5 * float(hla[1])


def masses_free(measurements: Sequence[Measurement], cfg: IdentifyConfig) -> bool:
    """The floor-mass ratios are fitted where no record gives masses, no mass ratios are given,
    the band reaches the higher modes (:func:`wide_band`) and the fit compares the floor
    accelerations (their higher-mode content is what informs the masses: on the steel frame a fit
    of displacements and drifts left them at the prior's equal masses, the posterior's standard
    deviation 50-70 % of the prior's); equal masses are the prior."""
    compare = cfg.refine.compare
    return (all(m.mass is None for m in measurements) and cfg.hla.force.mass_ratios is None and wide_band(cfg)
            and isinstance(compare, str) and "acc" in compare)


def best_fit(fits: Sequence[JointFit]) -> JointFit:
    """The fit of highest posterior among searches from different starts (the posterior of a
    first-mode-dominated record can have more than one mode): the lowest
    :meth:`JointFit.score`, each event's ``n_eff`` the mean of the fits'."""
    n_eff = np.mean([[e["n_eff"] for e in f.events] for f in fits], axis=0)
    return min(fits, key=lambda f: f.score(n_eff))


def posterior_uncertainty(fit: JointFit, level: float = 0.9) -> ParameterUncertainty:
    """The Laplace posterior of a joint fit as a Gaussian over the clone's parameters: per story
    ``log k0, logit(alpha / 0.95), log(p - 1), log dy, log delta_eta`` (and ``log zeta``), an exact
    linear map of the prior units (``log dy = log Cy + log W - log k0``)."""
    A, offset = fit.vector.clone_units(fit.building)
    c = A @ np.asarray(fit.result.x) + offset
    slots, transforms = fit.vector.clone_slots()
    info = {"prior": "joint MAP", "informed": fit.informed().tolist(), "level": level}
    return ParameterUncertainty(slots=slots, transform=transforms, centre=c, covariance=A @ fit.covariance @ A.T,
                                method="laplace-posterior", info=info)
