"""One set of story parameters fitted to a building's events in time order, the state carried.

An engineer monitoring a building gets one event after another. Each event's replay starts from
the state the previous one left the building in (its degradation, residual drift and hysteretic
displacement, after a free vibration that lets it come to rest: :class:`EventSeries`), so the
events are one history of one building and one set of parameters explains them all.

The search is maximum a posteriori in prior units (:mod:`hlaid.identify.priors`): every story
parameter and the damping ratio move, and the prior holds those the data say little about.
Each event's residuals are weighted by what they hold: ``w^2 = n_eff / sum r^2`` at the current
building, ``n_eff`` their effective number of independent samples (:func:`effective_samples`:
a first-mode-dominated misfit of a 40 s record holds a few dozen, not thousands). The weights
are estimated again at the optimum and the search repeated until they settle
(:func:`map_refine`), so a misfit that is model error, not sensor noise, does not make the data
look more certain than they are.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import _progress
from ..errors import InputError
from ..measurement import Measurement
from ..model import Building
from ..model.state import BuildingState, settle_time
from ..signal import lowpass
from .priors import StructuralPrior, elf_profile, from_units, system_residuals, to_units
from .refine import RefineResult, fit_residuals
from .residuals import ReplayResiduals

REPLAY_RATE_RATIO = 16.0
"""Replays of a fit run at least this many samples per period of the fitted band's upper corner:
a record sampled far above its band (a shake table at 256 Hz fitted below 2.5 Hz) is low-passed
and decimated first (:func:`at_replay_rate`), a sixth of the work with the same residuals."""

WEIGHT_ROUNDS = 3
"""At most this many searches, each with the weights of the last one's optimum."""


def at_replay_rate(meas: Measurement, hi_hz: float) -> Measurement:
    """``meas`` low-passed at ``hi_hz`` and decimated to at least :data:`REPLAY_RATE_RATIO`
    samples per period of ``hi_hz`` (``meas`` itself where it is not sampled above that)."""
    factor = int(1.0 / (REPLAY_RATE_RATIO * hi_hz * meas.dt))
    if factor < 2:
        return meas
    ground = lowpass(np.asarray(meas.ground_acc), meas.dt, hi_hz)[::factor]
    floor = lowpass(np.asarray(meas.floor_acc), meas.dt, hi_hz)[::factor]
    return dataclasses.replace(meas, dt=meas.dt * factor, ground_acc=ground.copy(), floor_acc=floor.copy(),
                               floor_disp=None, truth=None)


def effective_samples(r: np.ndarray) -> float:
    """Effective number of independent samples of residuals ``r`` ``(time, channel)``: per
    channel the spectral degrees of freedom ``2 (sum S)^2 / sum S^2`` of its spectrum ``S``
    (``2 B T`` for noise of bandwidth ``B`` over ``T`` seconds, ``N`` for white noise), taken
    from the periodogram ``P`` as ``4 (sum P)^2 / sum P^2`` (a Gaussian's periodogram ordinates
    have ``E P^2 = 2 S^2``), summed and scaled by the channels' effective count over their number
    (``(sum l)^2 / sum l^2`` of the eigenvalues of their covariance: floors that move as one mode
    count once)."""
    r = np.asarray(r, dtype=float)
    if r.ndim == 1:
        r = r[:, None]
    P = np.abs(np.fft.rfft(r - r.mean(axis=0), axis=0)) ** 2
    dof = 4.0 * P.sum(axis=0) ** 2 / np.maximum((P**2).sum(axis=0), 1e-300)
    lam = np.clip(np.linalg.eigvalsh(np.atleast_2d(np.cov(r.T))), 0.0, None)
    channels = lam.sum() ** 2 / max(float((lam**2).sum()), 1e-300) if lam.sum() > 0 else 1.0
    return float(min(dof.sum() * channels / r.shape[1], r.shape[0] * r.shape[1]))


class EventSeries:
    """Residuals of replays against a building's events in time order, each replay starting
    where the previous one left the building.

    Parameters
    ----------
    events : one :class:`~hlaid.identify.residuals.ReplayResiduals` per event, oldest first
    y0 : ``(4*story,)`` the state before the first event (None: at rest)
    tail_s : free vibration after each event [s] (None: :func:`settle_time` of each building)

    Attributes
    ----------
    weights : ``(event,)`` each event's residuals are multiplied by its weight (1 until
        :meth:`reweigh`)
    n_residuals, channels, substeps, criterion : as a single event's, ``n_residuals`` summed
    """

    def __init__(self, events: Sequence[ReplayResiduals], *, y0: np.ndarray | None = None,
                 tail_s: float | None = None):
        if not events:
            raise InputError("an event series needs at least one event")
        self.events = list(events)
        self.y0 = None if y0 is None else np.asarray(y0, dtype=float)
        self.tail_s = tail_s
        self.weights = np.ones(len(self.events))
        self.substeps = self.events[0].substeps
        self.criterion = self.events[0].criterion
        self.channels = self.events[0].channels
        self.n_residuals = int(sum(e.n_residuals for e in self.events))

    def run(self, buildings: Sequence[Building], substeps: int | None = None
            ) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
        """Per event the residuals of ``buildings`` ``(batch, n)`` (unweighted), the summed plain
        costs ``(batch,)`` and per event the state each building ends it in ``(batch, 4*story)``."""
        tails = [self.tail_s if self.tail_s is not None else settle_time(b) for b in buildings]
        tail = float(max(tails))
        y = None if self.y0 is None else np.broadcast_to(self.y0, (len(buildings), self.y0.size)).copy()
        parts, finals = [], []
        plain = np.zeros(len(buildings))
        n = buildings[0].n_stories
        for ev in self.events:
            res, pl, final = ev.run(buildings, substeps, y0=y, tail_s=tail)
            parts.append(res)
            plain += pl
            final = final.copy()
            final[:, n:2 * n] = 0.0  # at rest: the free vibration has died out
            bad = ~np.all(np.isfinite(final), axis=1)
            final[bad] = 0.0 if y is None else y[bad]
            finals.append(final)
            y = final
        return parts, plain, finals

    def __call__(self, buildings: Sequence[Building], substeps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        parts, plain, _ = self.run(buildings, substeps)
        return np.concatenate([w * r for w, r in zip(self.weights, parts)], axis=1), plain

    def reweigh(self, building: Building) -> list[dict]:
        """Set each event's weight from its residuals at ``building``: ``w^2 = n_eff / sum r^2``
        (the misfit's mean square as its variance, :func:`effective_samples` as its count).
        Returns per event ``n_eff`` and the RMS of its residuals."""
        parts, _, _ = self.run([building])
        info = []
        for k, (ev, r) in enumerate(zip(self.events, parts)):
            r = r[0].reshape(-1, ev.channels)
            n_eff = effective_samples(r)
            ss = float(np.sum(r**2))
            self.weights[k] = np.sqrt(n_eff / ss) if ss > 0 else 1.0
            info.append({"n_eff": n_eff, "rms": float(np.sqrt(np.mean(r**2)))})
        return info

    def states(self, building: Building, names: Sequence[str] = ()) -> list[BuildingState]:
        """The state ``building`` is left in after each event (names: the events' labels)."""
        _, _, finals = self.run([building])
        labels = list(names) or [f"event {k + 1}" for k in range(len(finals))]
        peaks = _peak_drifts(self, building)
        return [BuildingState.from_vector(f[0], peaks=pk, events=tuple(labels[:k + 1]))
                for k, (f, pk) in enumerate(zip(finals, peaks))]


def _peak_drifts(series: EventSeries, building: Building) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per event the largest drift per direction up to its end ``((story,), (story,))`` [mm]."""
    from ..simulate import simulate_response

    y = series.y0
    n = building.n_stories
    pp, pn = np.zeros(n), np.zeros(n)
    out = []
    tail = series.tail_s if series.tail_s is not None else settle_time(building)
    for ev in series.events:
        r = simulate_response(building, ev.ground, substeps=series.substeps, y0=y, free_vibration=tail)
        drift = np.nan_to_num(np.asarray(r.drift)[0])
        pp, pn = np.maximum(pp, drift.max(axis=0)), np.maximum(pn, (-drift).max(axis=0))
        out.append((pp.copy(), pn.copy()))
        y = np.array(r.final_state[0], dtype=float)
        y[n:2 * n] = 0.0
    return out


class PriorVector:
    """A building's parameters in prior units (:mod:`hlaid.identify.priors`): the vector a MAP
    search moves, unbounded (the transforms keep every parameter inside its physical range).

    Parameters
    ----------
    building : the start (its other properties are kept)
    damping : the damping ratio moves too

    Attributes
    ----------
    slots : ``(name, story)`` per entry (``("cy", i)`` the yield shear coefficient that sets dy;
        ``("damping", -1)``)
    x0, lower, upper, scale : the start, open bounds and unit scale (for ``fit_residuals``)
    """

    NAMES = ("k0", "alpha", "p", "cy", "delta_eta")

    def __init__(self, building: Building, *, damping: bool = True):
        self.building = building
        self.damping = damping
        u, lz = to_units(building)
        self.n = building.n_stories
        self.slots = [(name, i) for i in range(self.n) for name in self.NAMES] + ([("damping", -1)] if damping else [])
        self.x0 = np.append(u.ravel(), lz) if damping else u.ravel().copy()
        self.lower = np.full(self.x0.size, -np.inf)
        self.upper = np.full(self.x0.size, np.inf)
        self.scale = np.ones(self.x0.size)

    def split(self, x: np.ndarray) -> tuple[np.ndarray, float | None]:
        return x[: 5 * self.n].reshape(self.n, 5), (float(x[-1]) if self.damping else None)

    def building_at(self, x: np.ndarray) -> Building:
        u, lz = self.split(np.asarray(x, dtype=float))
        return from_units(self.building, u, lz)

    def of(self, building: Building) -> np.ndarray:
        """The vector of ``building`` (the inverse of :meth:`building_at`)."""
        u, lz = to_units(building)
        return np.append(u.ravel(), lz) if self.damping else u.ravel()


class SystemPrior:
    """The prior of a structural system over a :class:`PriorVector`'s entries (k0 around
    ``k0_ref``)."""

    def __init__(self, prior: StructuralPrior, vector: PriorVector, k0_ref: np.ndarray):
        self.prior, self.vector = prior, vector
        self.k0_ref = np.asarray(k0_ref, dtype=float)
        self.elf = elf_profile(vector.building)
        self.size = len(self.residuals(vector.x0))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        u, lz = self.vector.split(x)
        return system_residuals(self.prior, u, lz, self.k0_ref, self.elf)

    def to_dict(self) -> dict:
        return {"kind": "system", **self.prior.to_dict(), "k0_ref": self.k0_ref.tolist()}


class GaussianPrior:
    """A Gaussian over a :class:`PriorVector`'s entries (an earlier clone's posterior, the
    prior of a sequential update): residuals ``L^-1 (x - mean)``, ``covariance = L L^T``."""

    def __init__(self, mean: np.ndarray, covariance: np.ndarray):
        self.mean = np.asarray(mean, dtype=float)
        cov = np.asarray(covariance, dtype=float)
        cov = 0.5 * (cov + cov.T) + 1e-12 * np.eye(cov.shape[0])
        self.chol = np.linalg.cholesky(cov)
        self.size = self.mean.size

    def residuals(self, x: np.ndarray) -> np.ndarray:
        import scipy.linalg

        return scipy.linalg.solve_triangular(self.chol, np.asarray(x) - self.mean, lower=True)

    def to_dict(self) -> dict:
        return {"kind": "posterior", "mean": self.mean.tolist()}


class PosteriorResiduals:
    """Data residuals of an :class:`EventSeries` followed by a prior's (the MAP criterion), for
    :func:`~hlaid.identify.refine.fit_residuals`."""

    def __init__(self, series: EventSeries, vector: PriorVector, prior: SystemPrior | GaussianPrior):
        self.series, self.vector, self.prior = series, vector, prior
        self.substeps, self.criterion, self.channels = series.substeps, series.criterion, series.channels
        self.n_residuals = series.n_residuals + prior.size

    def __call__(self, buildings: Sequence[Building], substeps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        res, plain = self.series(buildings, substeps)
        pri = np.array([self.prior.residuals(self.vector.of(b)) for b in buildings])
        return np.concatenate([res, pri], axis=1), plain


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

    def score(self, n_eff: np.ndarray) -> float:
        """The negative log posterior with each event's misfit variance at its maximum
        (profiled): ``sum_e n_eff_e / 2 log(squares_e) + prior_cost``; ``n_eff`` ``(event,)``
        common to the fits compared."""
        return float(np.sum(0.5 * np.asarray(n_eff) * np.log(np.maximum(self.squares, 1e-300))) + self.prior_cost)

    def informed(self) -> np.ndarray:
        """``(P,)`` how much the data narrowed each entry: 1 - posterior sd / prior sd (0: the
        prior alone; near 1: the data)."""
        sd = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        return np.clip(1.0 - sd / np.maximum(self.prior_sd, 1e-12), 0.0, 1.0)


def map_refine(start: Building, measurements: Sequence[Measurement], prior: SystemPrior | GaussianPrior | None = None,
               *, system: StructuralPrior | None = None, band_hz=(0.1, 20.0), ground_noise: str = "ignore",
               damping: bool = True, y0: np.ndarray | None = None, names: Sequence[str] = (),
               max_iterations: int = 40, ftol: float = 1e-8, substeps: int = 4, jac_substeps: int = 2,
               tangent_max_mb: float | None = None) -> JointFit:
    """Maximum a posteriori parameters of one building from its events in time order.

    Parameters
    ----------
    start : the search's start (the paper's estimate of the most informative event, an earlier
        clone, or the prior's median building)
    measurements : the events, oldest first
    prior : the prior over the prior-unit vector (None: ``system``'s, with k0 around ``start``'s)
    system : the structural system (with ``prior`` None)
    band_hz : band of the compared floor accelerations [Hz]
    ground_noise : ``"ignore"`` (least squares of each event's residuals) or ``"tangent"``
        (each event's residuals whitened against its ground sensor's noise, errors in variables,
        the tangent taken once, along the start's replay from the state it carries into that event)
    damping : the damping ratio is fitted (else held at ``start``'s)
    y0 : the state before the first event (``(4*story,)``; None: at rest)
    names : the events' labels (for the states)
    """
    t0 = time.perf_counter()
    if prior is None and system is None:
        raise InputError("map_refine needs a prior or a structural system")
    vector = PriorVector(start, damping=damping)
    if prior is None:
        assert system is not None
        prior = SystemPrior(system, vector, start.k0)
    hi = float(band_hz[1])
    events = [at_replay_rate(m, hi) for m in measurements]
    info: list[dict] = []
    current = start
    rr: RefineResult | None = None
    weights: np.ndarray | None = None
    fits = 0
    series = _series(start, events, band_hz, ground_noise, substeps, jac_substeps, y0, tangent_max_mb)
    for _ in range(WEIGHT_ROUNDS):
        info = series.reweigh(current)
        if weights is not None and bool(np.all(np.abs(np.log(series.weights / weights)) < np.log(1.2))):
            break
        weights = series.weights.copy()
        fits += 1
        _progress.info(f"[identify] joint fit over {len(events)} event(s), round {fits}: effective samples "
                       + ", ".join(f"{d['n_eff']:.0f}" for d in info))
        rr = fit_residuals(vector, PosteriorResiduals(series, vector, prior), max_iterations=max_iterations,
                           ftol=ftol, jac_substeps=jac_substeps)
        current = rr.building
    assert rr is not None
    for d, w in zip(info, series.weights):
        d["weight"] = float(w)
    J = np.asarray(rr.jacobian)
    cov = np.linalg.pinv(J.T @ J)
    Jp = _prior_jacobian(prior, vector, np.asarray(rr.x))
    prior_sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(Jp.T @ Jp)), 0.0, None))
    states = series.states(current, names)
    parts, _, _ = series.run([current])
    squares = np.array([float(np.sum(r[0] ** 2)) for r in parts])
    prior_cost = 0.5 * float(np.sum(prior.residuals(np.asarray(rr.x)) ** 2))
    return JointFit(building=current, result=rr, vector=vector, covariance=cov, prior_sd=prior_sd, states=states,
                    events=info, rounds=fits, seconds=time.perf_counter() - t0, squares=squares,
                    prior_cost=prior_cost)


def _series(at: Building, events: Sequence[Measurement], band_hz, ground_noise: str, substeps: int,
            jac_substeps: int, y0, max_mb) -> EventSeries:
    """The event series with each event's residuals (for ``"tangent"`` whitened along ``at``'s
    replay from the state carried into that event)."""
    units: list[ReplayResiduals] = []
    y = y0
    tail = settle_time(at)
    for m in events:
        unit = ReplayResiduals(m, band_hz=band_hz, substeps=substeps, ground_noise=ground_noise, at=at,
                               tangent_substeps=jac_substeps, max_mb=max_mb, at_state=y)
        units.append(unit)
        if ground_noise == "tangent":
            _, _, final = unit.run([at], y0=None if y is None else y[None], tail_s=tail)
            y = final[0].copy()
            y[at.n_stories:2 * at.n_stories] = 0.0
    return EventSeries(units, y0=y0)


def _prior_jacobian(prior, vector: PriorVector, x: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """Finite-difference Jacobian of the prior's residuals at ``x``."""
    r0 = prior.residuals(x)
    cols = [(prior.residuals(x + h * (np.arange(x.size) == j)) - r0) / h for j in range(x.size)]
    return np.array(cols).T
