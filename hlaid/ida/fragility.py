"""Lognormal fragility functions fitted by maximum likelihood (Baker 2015).

``P(C | IM = x) = Phi(ln(x / median) / beta)``.

Two estimators:

* **from capacities** (IDA): each record's IM at collapse (or at exceeding a drift limit)
  is a sample of the capacity, so the MLE is ``ln(median) = mean(ln x)``,
  ``beta = std(ln x)`` (1/n, the MLE). Records that never collapsed within the intensities
  run are right-censored at the highest IM they survived; with any censored record the
  likelihood ``prod f(x_i) * prod (1 - F(c_j))`` is maximised numerically.
* **from counts** (Baker 2015, eq. 11): at IM levels ``x_j`` with ``z_j`` of ``n_j``
  records collapsed, maximise ``sum ln C(n_j, z_j) + z_j ln p_j + (n_j - z_j) ln(1 - p_j)``
  with ``p_j = Phi(ln(x_j/median)/beta)``.

Uncertainty: a percentile bootstrap over records (records drawn with replacement, the fit
repeated), giving an interval for the median and for beta.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize, special, stats

from ..errors import InputError

FRACTILES = (16, 50, 84)
"""The percentiles of an IDA's fractile curves."""

__all__ = ["LognormalFragility", "fit_capacities", "fit_counts", "fragility_from_capacities",
           "fragility_from_exceedance"]


@dataclass(frozen=True)
class LognormalFragility:
    """A fitted lognormal fragility function.

    Attributes
    ----------
    median : IM with 50 % probability of exceedance [g]
    beta : lognormal standard deviation (dispersion)
    method : ``"capacities"`` or ``"counts"``
    n_records : records used
    n_censored : records that never exceeded within the intensities run (censored)
    median_ci, beta_ci : bootstrap percentile interval ``(low, high)``, or None
    ci : confidence level of the intervals (0.90 is 5 % - 95 %)
    n_boot : bootstrap resamples
    """

    median: float
    beta: float
    method: str
    n_records: int
    n_censored: int = 0
    median_ci: tuple[float, float] | None = None
    beta_ci: tuple[float, float] | None = None
    ci: float = 0.90
    n_boot: int = 0

    def probability(self, im) -> np.ndarray:
        """``P(exceed | IM)`` at ``im`` [g] (any shape)."""
        x = np.asarray(im, dtype=np.float64)
        with np.errstate(divide="ignore"):
            return stats.norm.cdf(np.log(x / self.median) / self.beta)

    def quantile(self, q) -> np.ndarray:
        """IM [g] at which the probability of exceedance is ``q``."""
        return self.median * np.exp(self.beta * stats.norm.ppf(np.asarray(q, dtype=np.float64)))

    def to_dict(self) -> dict:
        return {"median_g": self.median, "beta": self.beta, "method": self.method, "n_records": self.n_records,
                "n_censored": self.n_censored,
                "median_ci_g": list(self.median_ci) if self.median_ci else None,
                "beta_ci": list(self.beta_ci) if self.beta_ci else None, "ci": self.ci, "n_boot": self.n_boot}


# ---------------------------------------------------------------------------- estimators
def fit_capacities(capacities, censored=None) -> tuple[float, float]:
    """Maximum-likelihood lognormal fit of capacities.

    Parameters
    ----------
    capacities : (n,) observed capacities [g] (> 0)
    censored : (m,) lower bounds [g] of the capacities of records that did not exceed
        (right-censored); None or empty for none

    Returns
    -------
    (median [g], beta)
    """
    x = np.asarray(capacities, dtype=np.float64).reshape(-1)
    c = np.zeros(0) if censored is None else np.asarray(censored, dtype=np.float64).reshape(-1)
    if np.any(~np.isfinite(x)) or np.any(x <= 0) or np.any(~np.isfinite(c)) or np.any(c <= 0):
        raise InputError("capacities must be positive finite intensities")
    lx = np.log(x)
    if x.size < 2 or np.ptp(lx) == 0:
        raise InputError(f"a lognormal fit needs at least 2 different observed capacities; got {x.size}")
    mu, beta = lx.mean(), lx.std()
    if c.size == 0:
        return float(np.exp(mu)), float(beta)
    lc = np.log(c)

    def nll(theta):
        m, lb = theta
        b = math.exp(lb)
        u = (lx - m) / b
        return -((-0.5 * u * u - lb).sum() + special.log_ndtr(-(lc - m) / b).sum())

    res = optimize.minimize(nll, [max(mu, lc.mean()), math.log(beta)], method="Nelder-Mead",
                            options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000})
    return float(np.exp(res.x[0])), float(np.exp(res.x[1]))


def fit_counts(levels, n_exceed, n_total) -> tuple[float, float]:
    """Baker (2015) binomial maximum-likelihood fit from counts at IM levels.

    Parameters
    ----------
    levels : (level,) IM levels [g] (> 0)
    n_exceed : (level,) number of records that exceeded (collapsed) at each level
    n_total : (level,) number of records run at each level (a number broadcasts)

    Returns
    -------
    (median [g], beta)
    """
    x = np.asarray(levels, dtype=np.float64).reshape(-1)
    z = np.asarray(n_exceed, dtype=np.float64).reshape(-1)
    n = np.broadcast_to(np.asarray(n_total, dtype=np.float64), x.shape)
    if x.shape != z.shape or np.any(x <= 0) or np.any(z < 0) or np.any(z > n):
        raise InputError("counts need positive levels and 0 <= n_exceed <= n_total at each level")
    frac = z / np.where(n > 0, n, 1)
    if not (np.any(frac > 0) and np.any(frac < 1)):
        raise InputError("a fit from counts needs some levels with exceedances and some without")
    lx = np.log(x)
    if np.all(z[frac > 0] == n[frac > 0]) and np.all(z[frac < 1] == 0) and lx[frac > 0].min() > lx[frac < 1].max():
        raise InputError("the counts jump from none to all exceeding between two levels; the dispersion "
                         "cannot be estimated (add levels in between)")
    a, b = _probit_mle(lx, z, n)
    if not b > 0:
        raise InputError("the fraction exceeding does not increase with the IM; no fragility can be fitted")
    return float(np.exp(-a / b)), float(1.0 / b)


def _loglik(a, b, lx, z, n) -> float:
    u = a + b * lx
    return float((z * special.log_ndtr(u) + (n - z) * special.log_ndtr(-u)).sum())


def _probit_mle(lx, z, n, iters: int = 100):
    """Maximum likelihood of ``P = Phi(a + b lx)`` for binomial counts, by Fisher scoring
    (Newton with the expected information) with step halving; returns ``(a, b)``."""
    use = n > 0
    lx, z, n = lx[use], z[use], n[use]
    f = np.clip(z / n, 0.5 / n, 1 - 0.5 / n)  # start: least squares on the probit scale
    b, a = np.polyfit(lx, special.ndtri(f), 1) if np.ptp(lx) > 0 else (1.0, 0.0)
    b = max(b, 1e-3)
    ll = _loglik(a, b, lx, z, n)
    for _ in range(iters):
        u = a + b * lx
        p = np.clip(special.ndtr(u), 1e-300, 1 - 1e-16)
        phi = np.exp(-0.5 * u * u) / np.sqrt(2 * np.pi)
        w = phi / (p * (1 - p))
        r = (z - n * p) * w
        g = np.array([r.sum(), (r * lx).sum()])
        wi = n * phi * w
        info = np.array([[wi.sum(), (wi * lx).sum()], [(wi * lx).sum(), (wi * lx * lx).sum()]])
        try:
            step = np.linalg.solve(info, g)
        except np.linalg.LinAlgError:
            break
        t = 1.0
        while t > 1e-8:
            a1, b1 = a + t * step[0], b + t * step[1]
            ll1 = _loglik(a1, b1, lx, z, n)
            if np.isfinite(ll1) and ll1 >= ll - 1e-12:
                break
            t *= 0.5
        done = abs(ll1 - ll) < 1e-13 * (1 + abs(ll)) and np.all(np.abs(t * step) < 1e-10 * (1 + np.abs([a, b])))
        a, b, ll = a1, b1, ll1
        if done:
            break
    return float(a), float(b)


# ---------------------------------------------------------------------------- with bootstrap
def _bootstrap(fit: Callable[[np.ndarray], tuple[float, float]], n_records: int, n_boot: int, ci: float,
               seed: int | None):
    if n_boot <= 0:
        return None, None
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_boot):
        idx = rng.integers(0, n_records, n_records)
        try:
            out.append(fit(idx))
        except InputError:  # a resample without enough collapses: skipped
            continue
    if len(out) < max(10, n_boot // 2):
        return None, None
    a = np.array(out)
    lo, hi = 50 * (1 - ci), 50 * (1 + ci)
    med = tuple(float(v) for v in np.percentile(a[:, 0], [lo, hi]))
    bet = tuple(float(v) for v in np.percentile(a[:, 1], [lo, hi]))
    return med, bet


def fragility_from_capacities(capacities, censored=None, *, n_boot: int = 1000, ci: float = 0.90,
                              seed: int | None = 0) -> LognormalFragility:
    """Lognormal fragility from per-record capacities, with a bootstrap interval.

    Parameters
    ----------
    capacities : (record,) capacity IM [g] of each record; NaN where the record never
        exceeded, in which case ``censored`` gives its highest IM survived
    censored : (record,) highest IM [g] survived by the records with NaN capacity (ignored
        elsewhere); None when every capacity is observed
    n_boot, ci, seed : bootstrap resamples, confidence level, random seed
    """
    cap = np.asarray(capacities, dtype=np.float64).reshape(-1)
    cen = np.full(cap.shape, np.nan) if censored is None else np.asarray(censored, dtype=np.float64).reshape(-1)
    obs = np.isfinite(cap)
    if np.any(~obs & ~np.isfinite(cen)):
        raise InputError("every record needs a capacity or, if it never exceeded, the highest IM it survived")

    def fit(idx):
        o = obs[idx]
        return fit_capacities(cap[idx][o], cen[idx][~o])

    median, beta = fit(np.arange(cap.size))
    mci, bci = _bootstrap(fit, cap.size, n_boot, ci, seed)
    return LognormalFragility(median, beta, "capacities", int(cap.size), int((~obs).sum()), mci, bci, ci,
                              n_boot if mci else 0)


def fragility_from_exceedance(levels, exceeded, *, n_boot: int = 1000, ci: float = 0.90,
                              seed: int | None = 0) -> LognormalFragility:
    """Lognormal fragility by the binomial MLE from a record x level table of outcomes.

    Parameters
    ----------
    levels : (level,) IM levels [g]
    exceeded : (record, level) True where the record collapsed (exceeded) at that level;
        the bootstrap resamples its rows (records)
    """
    x = np.asarray(levels, dtype=np.float64).reshape(-1)
    e = np.asarray(exceeded, dtype=bool)
    if e.ndim != 2 or e.shape[1] != x.size:
        raise InputError(f"exceeded must be (record, level) = (n, {x.size}), got shape {e.shape}")

    def fit(idx):
        return fit_counts(x, e[idx].sum(axis=0), idx.size)

    median, beta = fit(np.arange(e.shape[0]))
    mci, bci = _bootstrap(fit, e.shape[0], n_boot, ci, seed)
    return LognormalFragility(median, beta, "counts", int(e.shape[0]), 0, mci, bci, ci, n_boot if mci else 0)
