"""A building's parameters in prior units, and the priors over them.

Per story ``log k0, logit(alpha / 0.95), log(p - 1), log Cy, log delta_eta`` (``Cy = k0 dy /
W_above``, :mod:`hlaid.events.priors`) and ``log zeta``: the vector a MAP search moves
(:class:`PriorVector`, which owns this layout and its map onto the clone's own parameters), the
structural system's prior over it (:class:`SystemPrior`), an earlier clone's posterior
(:class:`GaussianPrior`) and the posterior residuals a search minimises
(:class:`PosteriorResiduals`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Building, Damping
from ..model.uncertainty import ParameterUncertainty
from .priors import ALPHA_MAX, StructuralPrior, elf_profile, system_residuals, weight_above
from .series import EventSeries


def to_units(building) -> tuple[np.ndarray, float]:
    """A building's parameters in prior units: ``(story, 5)`` columns ``log k0, logit(alpha /
    0.95), log(p - 1), log Cy, log delta_eta`` and ``log zeta`` (values at their limits are
    nudged inside them: alpha in [1e-6, 0.95 - 1e-6], p >= 1 + 1e-6, delta_eta >= 1e-8,
    zeta >= 1e-5)."""
    b = building
    a = np.clip(np.asarray(b.alpha, dtype=float) / ALPHA_MAX, 1e-6, 1 - 1e-6)
    cy = np.asarray(b.k0) * np.asarray(b.dy) / weight_above(b)
    u = np.column_stack([np.log(b.k0), np.log(a / (1 - a)), np.log(np.maximum(np.asarray(b.p) - 1.0, 1e-6)),
                         np.log(cy), np.log(np.maximum(b.delta_eta, 1e-8))])
    return u, float(np.log(max(b.damping.ratio, 1e-5)))


def from_units(base, u: np.ndarray, log_zeta: float | None = None):
    """The building ``base`` with the parameters of ``u`` ``(story, 5)`` (and ``log_zeta``; None:
    ``base``'s damping ratio): the inverse of :func:`to_units`."""
    k0 = np.exp(u[:, 0])
    alpha = ALPHA_MAX / (1.0 + np.exp(-u[:, 1]))
    p = 1.0 + np.exp(u[:, 2])
    dy = np.exp(u[:, 3]) * weight_above(base) / k0
    d = base.damping
    ratio = d.ratio if log_zeta is None else float(min(np.exp(log_zeta), 0.5))
    return base.replace(k0=k0, alpha=alpha, p=np.minimum(p, 50.0), dy=dy, delta_eta=np.exp(u[:, 4]),
                        damping=Damping(kind=d.kind, ratio=ratio, modes=d.modes))


class PriorVector:
    """A building's parameters in prior units: the vector a MAP
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

    CLONE_TRANSFORMS = {"k0": "log", "alpha": "logit", "p": "log1", "cy": "log", "delta_eta": "log", "damping": "log"}
    """Per entry the transform of the clone's own parameter (:class:`ParameterUncertainty`)."""

    def clone_units(self, building: Building) -> tuple[np.ndarray, np.ndarray]:
        """``(A, offset)`` ``((P, P), (P,))``: the clone's transformed parameters (per story
        ``log k0, logit(alpha / 0.95), log(p - 1), log dy, log delta_eta``, and ``log zeta``) are
        ``A x + offset`` of this vector's ``x``, exactly: ``log dy = log Cy - log k0 + log W``
        with ``W`` the weight above each story of ``building``."""
        where = {slot: j for j, slot in enumerate(self.slots)}
        A, offset = np.eye(len(self.slots)), np.zeros(len(self.slots))
        log_w = np.log(weight_above(building))
        for i in range(self.n):
            A[where["cy", i], where["k0", i]] = -1.0
            offset[where["cy", i]] = log_w[i]
        return A, offset

    def clone_slots(self) -> tuple[tuple[tuple[str, int], ...], tuple[str, ...]]:
        """The clone's ``(name, story)`` per entry (``dy`` for ``cy``) and each one's transform."""
        return (tuple(("dy" if name == "cy" else name, i) for name, i in self.slots),
                tuple(self.CLONE_TRANSFORMS[name] for name, _ in self.slots))


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


def prior_of_clone(unc: ParameterUncertainty | None, building: Building, vector: PriorVector,
                   fallback: StructuralPrior, widen: float = 1.0) -> GaussianPrior | SystemPrior:
    """A clone's posterior as the prior of its update, in ``vector``'s prior units: exact where
    the clone stores the joint fit's posterior (:func:`hlaid.events.fit.posterior_uncertainty`), else from 4000
    draws of its uncertainty; the structural system's prior around the clone where it has none
    (or it does not cover every parameter). ``widen``: its standard deviations multiplied (to let
    a building that changed move)."""
    if unc is None or len(unc.slots) < len(vector.slots):
        return SystemPrior(fallback, vector, building.k0)
    if unc.method == "laplace-posterior" and len(unc.slots) == len(vector.slots):
        A, offset = vector.clone_units(building)
        Ai = np.linalg.inv(A)
        return GaussianPrior(Ai @ (np.asarray(unc.centre, dtype=float) - offset), widen**2 * Ai @ unc.covariance @ Ai.T)
    rng = np.random.default_rng(0)
    draws = unc.sample(4000, rng)
    xs = np.array([vector.of(unc.apply(building, d)) for d in draws])
    return GaussianPrior(xs.mean(axis=0), widen**2 * np.cov(xs.T))
