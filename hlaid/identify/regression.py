"""Regressions for the degradation ``delta_eta`` (eq 12-14) and the yield displacement ``dy``
(eq 15-17), written to be exact for the forward model of :mod:`hlaid.model`.

From ``ke = alpha k0 + (1-alpha) k0 / eta`` (eq 11) and ``eta = 1 + delta_eta eps`` with
``eps = (1-alpha) (k0/m) u`` (``u = integral(z dx)`` in m^2, docs/DESIGN.md section 3):

    y = m (k0 - ke) / ((1-alpha) k0 (ke - alpha k0)) = delta_eta * u          (eq 12-13)

(the paper prints ``ke`` instead of ``k0`` in the denominator; ``k0`` is what the model
gives). On a loading branch (``dx z > 0``) eq 10 gives ``ke - k = (1-alpha) k0 |z/dy|^p / eta``,
so

    |z| = dy * ((ke - k) / (ke - alpha k0))^(1/p)                              (eq 15-16)

Both are fitted by least squares through the origin (eq 14, 17).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate

from ..model import equations as eq


@dataclass(frozen=True)
class RegressionFit:
    """A least-squares fit through the origin ``y = value * u``.

    Attributes
    ----------
    value : the slope (the identified parameter)
    stderr : its standard error
    r2 : coefficient of determination (uncentred)
    n : number of points used
    """

    value: float
    stderr: float
    r2: float
    n: int


def through_origin(u: np.ndarray, y: np.ndarray, w: np.ndarray | None = None) -> RegressionFit:
    """Weighted least squares ``y = c u`` (eq 14 / eq 17)."""
    ok = np.isfinite(u) & np.isfinite(y)
    u, y = u[ok], y[ok]
    w = np.ones_like(u) if w is None else np.asarray(w, dtype=float)[ok]
    suu = float(np.sum(w * u * u))
    if u.size < 2 or suu <= 0:
        return RegressionFit(np.nan, np.inf, np.nan, int(u.size))
    c = float(np.sum(w * u * y)) / suu
    r = y - c * u
    s2 = float(np.sum(w * r * r)) / max(u.size - 1, 1)
    syy = float(np.sum(w * y * y))
    return RegressionFit(c, float(np.sqrt(s2 / suu)), 1.0 - float(np.sum(w * r * r)) / syy if syy > 0 else np.nan,
                         int(u.size))


def hysteretic_displacement(force: np.ndarray, drift: np.ndarray, alpha: float, k0: float) -> np.ndarray:
    """``z = (f - alpha k0 x) / ((1 - alpha) k0)`` [mm], from eq 3."""
    return (force - alpha * k0 * drift) / ((1.0 - alpha) * k0)


def hysteretic_work(z: np.ndarray, drift: np.ndarray) -> np.ndarray:
    """``u(t) = integral(z dx)`` [mm^2], signed, cumulative."""
    return integrate.cumulative_trapezoid(z, drift, initial=0.0)


def fit_delta_eta(ke: np.ndarray, u_mm2: np.ndarray, *, k0: float, alpha: float, mass: float) -> RegressionFit:
    """``delta_eta`` [s^2/m^2] from elastic stiffnesses ``ke`` and the hysteretic work ``u``
    [mm^2] at the same instants (eq 12-14). Points with ``ke <= alpha k0`` (outside the
    model) are left out."""
    ke = np.asarray(ke, dtype=float)
    ok = ke > alpha * k0 * (1.0 + 1e-6)
    y = mass * (k0 - ke[ok]) / ((1.0 - alpha) * k0 * (ke[ok] - alpha * k0))
    return through_origin(np.asarray(u_mm2, dtype=float)[ok] * eq.ENERGY_SCALE, y)


def fit_yield_displacement(ke: np.ndarray, k: np.ndarray, z_abs: np.ndarray, *, k0: float, alpha: float,
                           p: float) -> RegressionFit:
    """``dy`` [mm] from loading-branch points: elastic ``ke``, tangent ``k`` [N/mm] and
    ``|z|`` [mm] (eq 15-17). Ratios outside [0, 1] (noise) are clipped."""
    ke, k = np.asarray(ke, dtype=float), np.asarray(k, dtype=float)
    ok = ke > alpha * k0 * (1.0 + 1e-6)
    ratio = np.clip((ke[ok] - k[ok]) / (ke[ok] - alpha * k0), 0.0, 1.0)
    return through_origin(ratio ** (1.0 / p), np.asarray(z_abs, dtype=float)[ok])


def story_delta_eta(story, *, mass: float, alpha: float, k0: float) -> RegressionFit:
    """eq 12-14 on one story's HLA: ``ke`` of every half cycle against ``u`` at its reversal."""
    z = hysteretic_displacement(story.force, story.drift, alpha, k0)
    u = hysteretic_work(z, story.drift)
    hc = story.half_cycles
    return fit_delta_eta(hc.ke, u[hc.start], k0=k0, alpha=alpha, mass=mass)


def story_yield_displacement(story, features, *, alpha: float, p: float, k0: float) -> RegressionFit:
    """eq 15-17 on one story's HLA: over the loading segments of the yielding half cycles
    (``features``, see :func:`hlaid.hla.features.half_cycle_features`), the segment slope as
    ``k`` and the segment's mean ``|z|``."""
    from ..hla.stiffness import segment_index

    z = hysteretic_displacement(story.force, story.drift, alpha, k0)
    hc = story.half_cycles
    n = features.slopes.shape[1]
    ke_pts, k_pts, z_pts = [], [], []
    for row, j in enumerate(features.index):
        s, e = int(hc.start[j]), int(hc.end[j])
        seg = segment_index(story.drift, s, e, n)
        zs = z[s:e + 1]
        direction = np.sign(story.drift[e] - story.drift[s])
        for q in range(n):
            sel = seg == q
            if not sel.any():
                continue
            zm = float(zs[sel].mean())
            if np.sign(zm) != direction:  # still unloading: eq 16 holds on loading branches only
                continue
            ke_pts.append(hc.ke[j])
            k_pts.append(features.slopes[row, q])
            z_pts.append(abs(zm))
    return fit_yield_displacement(np.array(ke_pts), np.array(k_pts), np.array(z_pts), k0=k0, alpha=alpha, p=p)


ETA_MAX = 20.0
"""Largest degradation ``eta`` a plausible estimate may reach on the record (the hysteretic
stiffness down to 5 % of its initial value), see :func:`plausible_limits`."""


def plausible_limits(story, *, mass: float, alpha: float, k0: float) -> tuple[float, float]:
    """Upper limits ``(delta_eta_max, dy_max)`` for one story's regressions: ``eta`` stays
    below :data:`ETA_MAX` over the largest hysteretic work the story reached, and a story
    that yielded has ``dy`` below its peak drift. A regression whose ``ke`` lies close to
    ``alpha k0`` (alpha over-estimated) would otherwise return a delta_eta thousands of times
    too large."""
    z = hysteretic_displacement(story.force, story.drift, alpha, k0)
    u = float(np.max(np.abs(hysteretic_work(z, story.drift)))) * eq.ENERGY_SCALE
    eps = (1.0 - alpha) * (k0 / mass) * u
    de_max = (ETA_MAX - 1.0) / eps if eps > 0 else np.inf
    return de_max, float(np.max(np.abs(story.drift)))
