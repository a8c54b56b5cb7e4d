"""Lognormal fragility fits (Baker 2015) against scipy and against known synthetic truths.

* the capacity MLE equals ``scipy.stats.lognorm.fit(x, floc=0)``; with right-censored
  records it equals scipy's censored-data fit;
* the binomial (counts) MLE equals a direct Nelder-Mead maximisation of the likelihood
  written with scipy.stats;
* on synthetic data (200 records, 50 seeds) both estimators recover a known median and
  dispersion: mean error below 5 %, small bias, and the bootstrap interval covers the truth
  about as often as its confidence level says.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize, stats

from hlaid.errors import InputError
from hlaid.ida import (
    fit_capacities,
    fit_counts,
    fragility_from_capacities,
    fragility_from_exceedance,
)

MEDIAN, BETA = 1.6, 0.45


def test_capacity_mle_equals_scipy():
    x = np.random.default_rng(3).lognormal(np.log(MEDIAN), BETA, 37)
    m, b = fit_capacities(x)
    shape, _, scale = stats.lognorm.fit(x, floc=0)
    assert m == pytest.approx(scale, rel=1e-6) and b == pytest.approx(shape, rel=1e-6)


def test_censored_capacity_mle_equals_scipy():
    x = np.random.default_rng(4).lognormal(np.log(MEDIAN), BETA, 60)
    top = 2.2  # records still standing at the highest IM run
    m, b = fit_capacities(x[x <= top], np.full((x > top).sum(), top))
    data = stats.CensoredData(uncensored=x[x <= top], right=np.full((x > top).sum(), top))
    shape, _, scale = stats.lognorm.fit(data, floc=0)
    assert (x > top).sum() >= 10
    assert m == pytest.approx(scale, rel=1e-4) and b == pytest.approx(shape, rel=1e-4)
    # ignoring the censored records would bias the median low: the censoring matters
    assert fit_capacities(x[x <= top])[0] < 0.95 * m


def test_counts_mle_equals_direct_maximisation():
    rng = np.random.default_rng(5)
    x = np.linspace(0.3, 4.0, 12)
    n = rng.integers(15, 40, x.size)
    z = rng.binomial(n, stats.norm.cdf(np.log(x / MEDIAN) / BETA))
    m, b = fit_counts(x, z, n)

    def nll(th):
        u = (np.log(x) - th[0]) / th[1]
        return -(z * stats.norm.logcdf(u) + (n - z) * stats.norm.logsf(u)).sum()
    r = optimize.minimize(nll, [0.0, 0.3], method="Nelder-Mead",
                          options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 20000})
    assert m == pytest.approx(np.exp(r.x[0]), rel=1e-6) and b == pytest.approx(r.x[1], rel=1e-6)


def _recovery(method: str, n_records=200, seeds=50):
    levels = np.linspace(0.2, 5.0, 25)
    est, covered = [], []
    for seed in range(seeds):
        cap = np.random.default_rng(seed).lognormal(np.log(MEDIAN), BETA, n_records)
        if method == "capacities":
            f = fragility_from_capacities(cap, n_boot=200 if seed < 20 else 0, seed=seed)
        else:  # IDA-style counts: the same records at every level
            f = fragility_from_exceedance(levels, levels[None, :] >= cap[:, None], n_boot=200 if seed < 20 else 0,
                                          seed=seed)
        est.append((f.median, f.beta))
        if f.median_ci is not None:
            covered.append((f.median_ci[0] <= MEDIAN <= f.median_ci[1], f.beta_ci[0] <= BETA <= f.beta_ci[1]))
    e = np.array(est) / [MEDIAN, BETA] - 1
    return e, np.array(covered)


@pytest.mark.parametrize("method", ["capacities", "counts"])
def test_recovers_known_median_and_dispersion_with_200_records(method):
    e, covered = _recovery(method)
    mean_abs, worst, bias = np.abs(e).mean(0), np.abs(e).max(0), e.mean(0)
    # sampling error with 200 records: sd(median) ~ beta/sqrt(200) = 3.2 %, sd(beta) ~ 1/sqrt(400) = 5 %
    assert np.all(mean_abs < 0.05), mean_abs
    assert np.all(np.abs(bias) < 0.02), bias
    assert np.all(worst < 0.16), worst  # no seed is off by more than ~3.5 standard errors
    assert 0.7 <= covered.mean() <= 1.0  # 90 % intervals over 20 seeds x 2 parameters


def test_fragility_object():
    f = fragility_from_capacities(np.random.default_rng(0).lognormal(0.0, 0.4, 50), n_boot=100)
    assert f.probability(f.median) == pytest.approx(0.5)
    assert f.probability(f.quantile(0.16)) == pytest.approx(0.16)
    assert f.median_ci[0] < f.median < f.median_ci[1] and f.beta_ci[0] < f.beta < f.beta_ci[1]
    assert f.to_dict()["n_boot"] == 100


def test_fit_errors():
    with pytest.raises(InputError, match="at least 2 different observed capacities"):
        fit_capacities([1.0])
    with pytest.raises(InputError, match="some levels with exceedances and some without"):
        fit_counts([0.5, 1.0], [0, 0], 10)
    with pytest.raises(InputError, match="jump from none to all"):
        fit_counts([0.5, 1.0], [0, 10], 10)
    with pytest.raises(InputError, match="capacity or, if it never exceeded"):
        fragility_from_capacities([1.0, np.nan, 2.0])
