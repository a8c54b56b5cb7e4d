"""A building's parameters in prior units, and the priors over them.

Per story ``log k0, logit(alpha / 0.95), log(p - 1), log Cy, log delta_eta`` (``Cy = k0 dy /
W_above``, :mod:`hlaid.joint.priors`) and ``log zeta`` (and ``log zeta2``, the second Rayleigh
ratio, where the building has one: :attr:`hlaid.model.Damping.ratio2`): the vector a MAP search moves
(:class:`PriorVector`, which owns this layout and its map onto the clone's own parameters), the
structural system's prior over it (:class:`SystemPrior`), an earlier clone's posterior
(:class:`GaussianPrior`) and the posterior residuals a search minimises
(:class:`PosteriorResiduals`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..model import Building
from ..model.schema import DAMPING_RATIO_MAX, STORY_BOUNDS
from ..model.uncertainty import ParameterUncertainty
from .priors import ALPHA_MAX, StructuralPrior, elf_profile, prior_record, system_residuals, weight_above
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
    ``base``'s damping ratio): the inverse of :func:`to_units`, every parameter clipped to the
    model's bounds (:data:`~hlaid.model.schema.STORY_BOUNDS`; a search that holds ``Cy`` while it
    moves ``k0`` moves ``dy`` with it, and a long step can leave them)."""
    with np.errstate(over="ignore"):
        e = np.exp(np.clip(np.asarray(u, dtype=float), -700.0, 700.0))
        k0 = _clip("k0", e[:, 0])
        alpha = ALPHA_MAX / (1.0 + 1.0 / e[:, 1])
        p = _clip("p", 1.0 + e[:, 2])
        dy = _clip("dy", e[:, 3] * weight_above(base) / k0)
        delta_eta = _clip("delta_eta", e[:, 4])
    d = base.damping
    ratio = d.ratio if log_zeta is None else _ratio_of(log_zeta)
    return base.replace(k0=k0, alpha=alpha, p=p, dy=dy, delta_eta=delta_eta,
                        damping=dataclasses.replace(d, ratio=ratio))


RATIO_BOUNDS = (1e-6, DAMPING_RATIO_MAX)
"""The damping ratios a search can reach (:func:`_ratio_of` clips to them): a fitted ratio at
either end sits at a bound of the search, not where the records put it."""

MASS_RATIO_LIMIT = 5.0
"""A floor mass over the top floor's that moves stays within ``exp(+-MASS_RATIO_LIMIT)``."""


def _ratio_of(log_zeta: float) -> float:
    """A damping ratio of its log, within :data:`RATIO_BOUNDS`."""
    return max(float(min(np.exp(min(log_zeta, 0.0)), RATIO_BOUNDS[1])), RATIO_BOUNDS[0])


def at_limit(name: str, value: float, *, rel: float = 1e-3) -> bool:
    """Whether a fitted parameter sits at a bound of the search (within ``rel``): alpha at 0 or
    0.95, p at 1, delta_eta below 1e-6, a damping ratio at :data:`RATIO_BOUNDS`, k0 or dy at
    the model's bounds (:data:`~hlaid.model.schema.STORY_BOUNDS`, where :func:`from_units` clips)."""
    v = float(value)
    if name == "alpha":
        return not 1e-3 < v < ALPHA_MAX - 1e-3
    if name == "p":
        return v < 1.005
    if name == "delta_eta":
        return v < 1e-6
    if name in ("damping", "damping2"):
        return not RATIO_BOUNDS[0] * (1 + rel) < v < RATIO_BOUNDS[1] * (1 - rel)
    if name in ("k0", "dy"):
        b = STORY_BOUNDS[name]
        return not b.lo * (1 + rel) < v < b.upper() * (1 - rel)
    return False


def _log_ratio(ratio: float | None) -> float:
    return float(np.log(max(float(ratio or 0.0), 1e-5)))


def _clip(name: str, v: np.ndarray) -> np.ndarray:
    b = STORY_BOUNDS[name]
    return np.clip(v, max(b.lo, 1e-300), b.upper())


class PriorVector:
    """A building's parameters in prior units: the vector a MAP
    search moves, unbounded (the transforms keep every parameter inside its physical range).

    Parameters
    ----------
    building : the start (its other properties are kept; with ``laws``, its entries that the
        laws hold fixed are kept too: :func:`hlaid.joint.laws.with_laws` sets them)
    damping : the damping ratio moves too (and the second Rayleigh ratio where the building
        has one)
    masses : the floor-mass ratios move too (where the masses are unknown): ``log(m_i / m_top)``
        of every floor below the top, the total mass kept
    laws : each story's law (:data:`hlaid.joint.laws.LAWS`; None: every entry free, the
        degrading law): only the entries a story's law leaves free are in the vector

    Attributes
    ----------
    slots : ``(name, story)`` per entry (``("cy", i)`` the yield shear coefficient that sets dy;
        ``("damping", -1)``)
    free : ``(5 * story (+ 1),)`` which entries of the full layout are in the vector
    x0, lower, upper, scale : the start, open bounds and unit scale (for ``fit_residuals``)
    """

    NAMES = ("k0", "alpha", "p", "cy", "delta_eta")

    def __init__(self, building: Building, *, damping: bool = True, laws: Sequence[str] | None = None,
                 masses: bool = False):
        from .laws import check_laws, law_mask

        self.building = building
        self.damping = damping
        self.damping2 = bool(damping and building.damping.ratio2 is not None)
        self.masses = bool(masses and building.n_stories > 1)
        self.n = building.n_stories
        self.laws = None if laws is None else check_laws(laws, self.n)
        mask = np.ones((self.n, 5), dtype=bool) if self.laws is None else law_mask(self.laws)
        self.mask = mask
        self.base = self._full(building)
        self.free = np.concatenate([mask.ravel(), np.ones(self.base.size - mask.size, dtype=bool)])
        every = ([(name, i) for i in range(self.n) for name in self.NAMES] + ([("damping", -1)] if damping else [])
                 + ([("damping2", -1)] if self.damping2 else [])
                 + ([("mass", i) for i in range(self.n - 1)] if self.masses else []))
        self.slots = [s for s, f in zip(every, self.free) if f]
        self.x0 = self.base[self.free].copy()
        self.lower = np.full(self.x0.size, -np.inf)
        self.upper = np.full(self.x0.size, np.inf)
        self.scale = np.ones(self.x0.size)

    def _full(self, building: Building) -> np.ndarray:
        """The full layout of ``building``: every story's five entries, ``log zeta`` where the
        damping moves and ``log zeta2`` where its second ratio does."""
        u, lz = to_units(building)
        extra = ([lz] if self.damping else []) + ([_log_ratio(building.damping.ratio2)] if self.damping2 else [])
        if self.masses:
            m = np.asarray(building.mass, dtype=float)
            extra += list(np.log(m[:-1] / m[-1]))
        return np.append(u.ravel(), extra)

    def log_mass_ratios(self, x: np.ndarray) -> np.ndarray | None:
        """``(story - 1,)`` the ``log(m_i / m_top)`` of ``x`` (None where the masses do not move)."""
        return self.expand(x)[-(self.n - 1):] if self.masses else None

    def expand(self, x: np.ndarray) -> np.ndarray:
        """The full layout (every story's five entries, and ``log zeta``) of ``x``, the fixed
        entries at the start's values."""
        full = self.base.copy()
        full[self.free] = np.asarray(x, dtype=float)
        return full

    def split(self, x: np.ndarray) -> tuple[np.ndarray, float | None]:
        """``x`` as ``(story, 5)`` prior units (fixed entries included) and ``log zeta``."""
        full = self.expand(x)
        return full[: 5 * self.n].reshape(self.n, 5), (float(full[5 * self.n]) if self.damping else None)

    def log_zeta2(self, x: np.ndarray) -> float | None:
        """``log`` of the second Rayleigh ratio in ``x`` (None where it does not move)."""
        return float(self.expand(x)[5 * self.n + 1]) if self.damping2 else None

    def building_at(self, x: np.ndarray) -> Building:
        x = np.asarray(x, dtype=float)
        u, lz = self.split(x)
        base = self.building
        lm = self.log_mass_ratios(x)
        if lm is not None:
            r = np.exp(np.clip(np.append(lm, 0.0), -MASS_RATIO_LIMIT, MASS_RATIO_LIMIT))
            base = base.replace(mass=float(np.sum(base.mass)) * r / r.sum())
        b = from_units(base, u, lz)
        lz2 = self.log_zeta2(x)
        if lz2 is None:
            return b
        return b.replace(damping=dataclasses.replace(b.damping, ratio2=_ratio_of(lz2)))

    def of(self, building: Building) -> np.ndarray:
        """The vector of ``building`` (the inverse of :meth:`building_at`)."""
        return self._full(building)[self.free]

    CLONE_TRANSFORMS = {"k0": "log", "alpha": "logit", "p": "log1", "cy": "log", "delta_eta": "log", "damping": "log",
                        "damping2": "log"}
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
            if ("cy", i) in where:
                A[where["cy", i], where["k0", i]] = -1.0
                offset[where["cy", i]] = log_w[i]
        keep = [j for j, (name, _) in enumerate(self.slots) if name != "mass"]  # the masses: not a clone slot
        return A[keep], offset[keep]

    def clone_slots(self) -> tuple[tuple[tuple[str, int], ...], tuple[str, ...]]:
        """The clone's ``(name, story)`` per entry (``dy`` for ``cy``) and each one's transform."""
        slots = [s for s in self.slots if s[0] != "mass"]
        return (tuple(("dy" if name == "cy" else name, i) for name, i in slots),
                tuple(self.CLONE_TRANSFORMS[name] for name, _ in slots))


MASS_BETA = 0.3
"""Log standard deviation of a floor's mass over the top floor's under the prior, around equal
masses (the masses are unknown where they move): floors of one building carry similar loads,
a roof or a plant floor a third lighter or heavier."""


class SystemPrior:
    """The prior of a structural system over a :class:`PriorVector`'s entries (k0 around
    ``k0_ref``); with story laws, each shape parameter is held near the building's value over the
    stories whose law leaves it free (a story of another law, an isolation layer, is not pulled
    towards the others)."""

    def __init__(self, prior: StructuralPrior, vector: PriorVector, k0_ref: np.ndarray):
        self.prior, self.vector = prior, vector
        self.k0_ref = np.asarray(k0_ref, dtype=float)
        self.elf = elf_profile(vector.building)
        self.size = len(self.residuals(vector.x0))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        u, lz = self.vector.split(x)
        out = system_residuals(self.prior, u, lz, self.k0_ref, self.elf,
                               free=None if self.vector.laws is None else self.vector.mask)
        lz2 = self.vector.log_zeta2(x)
        if lz2 is not None:
            d = self.prior.damping  # the second ratio: the system's damping too, as widely
            out = np.append(out, (lz2 - np.log(d.median)) / d.beta)
        lm = self.vector.log_mass_ratios(x)
        if lm is not None:  # the floor masses: equal (the start's) unless the records say otherwise
            out = np.append(out, lm / MASS_BETA)
        return out

    def to_dict(self) -> dict:
        return {"kind": "system", **prior_record(self.prior), "k0_ref": self.k0_ref.tolist()}


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
    the clone stores the joint fit's posterior (:func:`hlaid.joint.fit.posterior_uncertainty`), else from 4000
    draws of its uncertainty; the structural system's prior around the clone where it has none
    (or it does not cover every parameter). ``widen``: its standard deviations multiplied (to let
    a building that changed move)."""
    if unc is None or len(unc.slots) < len(vector.slots):
        return SystemPrior(fallback, vector, building.k0)
    if (unc.method == "laplace-posterior" and tuple(unc.slots) == vector.clone_slots()[0]
            and len(unc.slots) == len(vector.slots)):
        A, offset = vector.clone_units(building)
        Ai = np.linalg.inv(A)
        return GaussianPrior(Ai @ (np.asarray(unc.centre, dtype=float) - offset), widen**2 * Ai @ unc.covariance @ Ai.T)
    rng = np.random.default_rng(0)
    draws = unc.sample(4000, rng)
    xs = np.array([vector.of(unc.apply(building, d)) for d in draws])
    return GaussianPrior(xs.mean(axis=0), widen**2 * np.cov(xs.T))
