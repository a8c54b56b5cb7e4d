"""Candidate story laws and prefix clones judged from one joint fit, without a fit of their own.

The story laws are nested (:mod:`hlaid.joint.laws`): an elastic or non-degrading story is a
degrading one with entries held at fixed values. The joint fit under the system's law already
holds what a candidate's fit would start from: its optimum and the Jacobian of its weighted
residuals there. :func:`screen_laws` judges every candidate from it:

1. each candidate's start is the joint optimum with the entries its law holds set
   (:func:`~hlaid.joint.laws.with_laws`);
2. a few Levenberg-Marquardt steps over the entries the law leaves free, the data's Jacobian
   frozen at the joint optimum (its columns for those entries: the same prior units), the
   prior's residuals and Jacobian exact, every step of every candidate replayed in one batch;
   a step is kept only where the replayed cost fell;
3. the Laplace evidence at the best point reached, as :meth:`~hlaid.joint.fit.JointFit.log_evidence`
   computes it (profiled misfit variances, ``log det`` of the Gauss-Newton matrix with the frozen
   columns).

The score at a point the steps reached is never lower than the candidate's optimum's, so the
screen's evidence is a lower bound up to the ``log det`` term: a candidate it finds better than
the system's law is better; one within :data:`SCREEN_MARGIN` of beating it is fitted in full
before it is chosen (:func:`hlaid.events.identify.select_laws`).

:func:`prefix_point` is the same idea for the prediction's start rule: the clone of the first
``j`` records is the joint fit's optimum moved by one Newton step of the first ``j`` events'
posterior (their Jacobian rows and the prior's, the later events' pull removed: an approximate
leave-future-out posterior mode), accepted where the replayed cost of those events fell by at
least :data:`NEWTON_AGREEMENT` of what the step predicted and the step stays within
:data:`NEWTON_REACH` posterior standard deviations, and refitted otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model import Building
from ..model.state import BuildingState
from .fit import JointFit, _prior_jacobian, log_dets
from .laws import with_laws
from .priors import StructuralPrior
from .series import effective_samples
from .vector import PriorVector, SystemPrior

SCREEN_STEPS = 4
"""Batched replays of the candidates' Levenberg-Marquardt steps (each one a replay of every
candidate through every event)."""

SCREEN_MARGIN = 5.0
"""A candidate whose screened log evidence comes within this much of beating the system's law
(by :data:`~hlaid.joint.laws.TIE_LOG_UNITS`) is fitted in full before the laws are chosen."""

NEWTON_AGREEMENT = 0.25
"""A prefix's Newton step is kept where the replayed cost fell by at least this fraction of the
fall the step's linear model predicted."""

NEWTON_REACH = 2.0
"""A prefix's Newton step is kept only where it is at most this many of the prefix posterior's
standard deviations long (Mahalanobis): farther, the later events moved the optimum beyond where
one Gaussian describes both posteriors (the role of the Pareto k diagnostic of approximate
leave-future-out), and the prefix is fitted. On the steel frame's s1..s2 a step of 3.5 sd passed
the cost check yet predicted s3 at R 0.944 carried / 0.938 from rest where the prefix's own fit
gives 0.882 / 0.914."""


@dataclass(frozen=True, eq=False)
class Screened:
    """A candidate law judged from the joint fit (:func:`screen_laws`).

    Attributes
    ----------
    laws : the stories' laws
    building : the best point the steps reached
    squares : ``(event,)`` each event's sum of squared residuals there
    n_eff : ``(event,)`` their effective sample counts
    prior_cost : half the prior's squared residuals there
    log_det_hessian, log_det_prior : as :class:`~hlaid.joint.fit.JointFit`'s (frozen data columns)
    steps : steps kept
    """

    laws: tuple[str, ...]
    building: Building
    squares: np.ndarray
    n_eff: np.ndarray
    prior_cost: float
    log_det_hessian: float
    log_det_prior: float
    steps: int

    def log_evidence(self, n_eff: np.ndarray) -> float:
        """As :meth:`hlaid.joint.fit.JointFit.log_evidence`, with ``n_eff`` common to the fits compared."""
        score = float(np.sum(0.5 * np.asarray(n_eff) * np.log(np.maximum(self.squares, 1e-300))) + self.prior_cost)
        return float(-score + 0.5 * self.log_det_prior - 0.5 * self.log_det_hessian)


def data_jacobian(fit: JointFit) -> np.ndarray | None:
    """``(data residuals, P)`` the joint fit's Jacobian of the events' *unweighted* residuals at its
    optimum (its weighted data rows divided by each event's weight); None where the fit kept none."""
    series, w = fit.series, fit.jac_weights
    J = np.asarray(fit.result.jacobian)
    if series is None or w is None or J.ndim != 2 or J.shape[0] < series.n_residuals:
        return None
    sizes = [ev.n_residuals for ev in series.events]
    scale = np.repeat(1.0 / np.asarray(w, dtype=float), sizes)
    return J[: series.n_residuals] * scale[:, None]


def _columns(fit: JointFit, vector: PriorVector) -> list[int] | None:
    """The joint fit's columns of ``vector``'s entries (None: ``vector`` moves an entry the fit held)."""
    where = {slot: j for j, slot in enumerate(fit.vector.slots)}
    try:
        return [where[s] for s in vector.slots]
    except KeyError:
        return None


class _Candidate:
    """One candidate's Levenberg-Marquardt state with the data Jacobian frozen."""

    def __init__(self, laws, vector: PriorVector, prior: SystemPrior, Jd: np.ndarray):
        self.laws, self.vector, self.prior, self.Jd = laws, vector, prior, Jd
        self.x = vector.x0.copy()
        self.mu = 1e-3
        self.cost = np.inf
        self.rd: np.ndarray | None = None
        self.parts: list[np.ndarray] | None = None
        self.steps = 0
        self.trial: np.ndarray | None = None

    def prior_parts(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.prior.residuals(x), _prior_jacobian(self.prior, self.vector, x)

    def propose(self, w_rows: np.ndarray) -> None:
        """The next trial point from the current one (None where no step is left to try)."""
        rp, Jp = self.prior_parts(self.x)
        J = np.vstack([self.Jd * w_rows[:, None], Jp])
        r = np.concatenate([self.rd, rp])
        A = J.T @ J
        g = J.T @ r
        D = np.diag(np.maximum(np.diag(A), 1e-12))
        try:
            dx = -np.linalg.solve(A + self.mu * D, g)
        except np.linalg.LinAlgError:
            self.trial = None
            return
        self.trial = self.x + dx if np.all(np.isfinite(dx)) else None


def screen_laws(fit: JointFit, laws_list: Sequence[tuple[str, ...]], system: StructuralPrior, k0_ref: np.ndarray,
                *, steps: int = SCREEN_STEPS) -> dict[tuple[str, ...], Screened]:
    """Every candidate of ``laws_list`` judged from ``fit`` (see the module); a candidate that is
    not nested in the fit's laws (it frees an entry the fit held) is left out of the answer."""
    series = fit.series
    Jd_all = data_jacobian(fit)
    if series is None or Jd_all is None:
        return {}
    sizes = [ev.n_residuals for ev in series.events]
    w_rows = np.repeat(np.asarray(series.weights, dtype=float), sizes)
    cands: list[_Candidate] = []
    for laws in laws_list:
        b = with_laws(fit.building, laws, system)
        vector = PriorVector(b, damping=fit.vector.damping, laws=laws)
        cols = _columns(fit, vector)
        if cols is None:
            continue
        cands.append(_Candidate(tuple(laws), vector, SystemPrior(system, vector, k0_ref), Jd_all[:, cols]))
    if not cands:
        return {}

    def replay(points: list[tuple[_Candidate, np.ndarray]]) -> list[tuple[list[np.ndarray], float]]:
        parts, _, _ = series.run([c.vector.building_at(x) for c, x in points])
        out = []
        for k, (c, x) in enumerate(points):
            pk = [p[k] for p in parts]
            rd = np.concatenate([wt * p for wt, p in zip(series.weights, pk)])
            rp = c.prior.residuals(x)
            cost = 0.5 * float(np.sum(rd**2) + np.sum(rp**2))
            out.append((pk, cost if np.isfinite(cost) else np.inf))
        return out

    for c, (pk, cost) in zip(cands, replay([(c, c.x) for c in cands])):
        c.parts, c.cost = pk, cost
        c.rd = np.concatenate([wt * p for wt, p in zip(series.weights, pk)])
    for _ in range(max(int(steps) - 1, 0)):
        live = []
        for c in cands:
            if np.isfinite(c.cost):
                c.propose(w_rows)
                if c.trial is not None:
                    live.append(c)
        if not live:
            break
        for c, (pk, cost) in zip(live, replay([(c, c.trial) for c in live if c.trial is not None])):
            if cost < c.cost:
                c.x, c.cost, c.parts, c.steps = c.trial, cost, pk, c.steps + 1
                c.rd = np.concatenate([wt * p for wt, p in zip(series.weights, pk)])
                c.mu = max(c.mu / 10.0, 1e-7)
            else:
                c.mu *= 10.0
    out: dict[tuple[str, ...], Screened] = {}
    for c in cands:
        if c.parts is None or not np.isfinite(c.cost):
            continue
        rp, Jp = c.prior_parts(c.x)
        J = np.vstack([c.Jd * w_rows[:, None], Jp])
        n_eff = np.array([effective_samples(p.reshape(-1, ev.channels)) for p, ev in zip(c.parts, series.events)])
        out[c.laws] = Screened(laws=c.laws, building=c.vector.building_at(c.x),
                               squares=np.array([float(np.sum(p**2)) for p in c.parts]), n_eff=n_eff,
                               prior_cost=0.5 * float(np.sum(rp**2)), **log_dets(J, Jp), steps=c.steps)
    return out


@dataclass(frozen=True, eq=False)
class PrefixPoint:
    """The clone of a joint fit's first ``j`` events by one Newton step (:func:`prefix_point`).

    Attributes
    ----------
    building : the prefix's approximate posterior mode (None: the step was not accepted)
    state : the state it is left in by the prefix's events (None with ``building``)
    predicted, achieved : the fall of the prefix's cost the step's linear model predicted, and the
        replay's
    agreement : ``achieved / predicted`` (1 where the step is negligible)
    step_sd : the step's length in posterior standard deviations (Mahalanobis under the prefix's
        Gauss-Newton matrix)
    """

    building: Building | None
    state: BuildingState | None
    predicted: float
    achieved: float
    agreement: float
    step_sd: float

    def to_dict(self) -> dict:
        return {"accepted": self.building is not None, "predicted": self.predicted, "achieved": self.achieved,
                "agreement": self.agreement, "step_sd": self.step_sd}


def prefix_point(fit: JointFit, j: int, names: Sequence[str] = ()) -> PrefixPoint | None:
    """The posterior mode of ``fit``'s first ``j`` events (its prior, its events' weights),
    approximated by one Newton step from ``fit``'s optimum: the later events' pull on the
    optimum removed (their Jacobian rows dropped, the gradient the remaining rows and the prior
    then have at the optimum followed), checked by replaying the ``j`` events at the optimum and
    at the step (one batch): kept where the cost fell by at least :data:`NEWTON_AGREEMENT` of
    the predicted fall and the step is within :data:`NEWTON_REACH`. None where ``fit`` keeps no
    Jacobian to step with."""
    series, w = fit.series, fit.jac_weights
    J = np.asarray(fit.result.jacobian)
    r = np.asarray(fit.result.residuals)
    if series is None or w is None or J.ndim != 2 or r.shape[0] != J.shape[0] or not 0 < j <= len(series.events):
        return None
    from .series import EventSeries

    nd = series.n_residuals
    rows = int(sum(ev.n_residuals for ev in series.events[:j]))
    Jk = np.vstack([J[:rows], J[nd:]])
    rk = np.concatenate([r[:rows], r[nd:]])
    H = Jk.T @ Jk
    g = Jk.T @ rk
    D = np.diag(np.maximum(np.diag(H), 1e-12))
    try:
        dx = -np.linalg.solve(H + 1e-9 * D, g)
    except np.linalg.LinAlgError:
        return None
    predicted = float(-(g @ dx + 0.5 * dx @ H @ dx))
    step_sd = float(np.sqrt(max(dx @ H @ dx, 0.0)))
    x0 = np.asarray(fit.result.x, dtype=float)
    vector = fit.vector
    if not np.all(np.isfinite(dx)) or step_sd > NEWTON_REACH:  # beyond the Gaussian's reach: no replay
        return PrefixPoint(None, None, predicted, float("nan"), float("nan"), step_sd)
    prior = _fit_prior(fit)
    sub = EventSeries(series.events[:j], y0=series.y0, tail_s=series.tail_s)
    b0, b1 = vector.building_at(x0), vector.building_at(x0 + dx)
    parts, _, _ = sub.run([b0, b1])
    costs = []
    for k, x in enumerate((x0, x0 + dx)):
        data = sum(float(np.sum((wt * p[k]) ** 2)) for wt, p in zip(w[:j], parts))
        pr = float(np.sum(prior.residuals(x) ** 2)) if prior is not None else float(np.sum(r[nd:] ** 2))
        costs.append(0.5 * (data + pr))
    achieved = costs[0] - costs[1] if np.all(np.isfinite(costs)) else float("nan")
    if predicted <= 1e-6:  # nothing to move: the later events did not pull the optimum
        agreement, ok, b1 = 1.0, True, b0
    else:
        agreement = achieved / predicted if np.isfinite(achieved) else float("nan")
        ok = bool(np.isfinite(agreement) and agreement >= NEWTON_AGREEMENT and step_sd <= NEWTON_REACH)
    state = sub.states(b1, list(names)[:j])[-1] if ok else None
    return PrefixPoint(b1 if ok else None, state, predicted, achieved, agreement, step_sd)


def _fit_prior(fit: JointFit):
    """The prior ``fit`` was searched under (kept by its series' residual object where it was)."""
    return fit.prior


__all__ = ["SCREEN_STEPS", "SCREEN_MARGIN", "NEWTON_AGREEMENT", "NEWTON_REACH", "PrefixPoint", "Screened",
           "data_jacobian", "prefix_point", "screen_laws"]
