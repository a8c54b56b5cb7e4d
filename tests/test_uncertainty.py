"""Identification uncertainty: Laplace covariance, coverage machinery, clone file v1/v2, ensembles."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hlaid.clone import VERSION, Clone, load_clone
from hlaid.errors import HlaidWarning, InputError
from hlaid.model import Building
from hlaid.uncertainty import ParameterUncertainty, calibration_factor, clone_ensemble, covariance, coverage, zscores


# ---------------------------------------------------------------------------- linear-Gaussian toy
def _ar1(rng, n, c, phi):
    """(n, c) stationary AR(1) noise with unit variance."""
    e = rng.standard_normal((n, c)) * np.sqrt(1 - phi**2)
    x = np.empty((n, c))
    x[0] = rng.standard_normal(c)
    for t in range(1, n):
        x[t] = phi * x[t - 1] + e[t]
    return x


def _toy(n=3000, c=2, P=3, seed=0):
    """A design J (n*c, P), rows time-major, smooth in time like a response's sensitivities."""
    t = np.arange(n) / 100.0
    cols = [np.stack([np.sin(2 * np.pi * (0.3 + 0.4 * j + 0.2 * k) * t + j) for k in range(c)], axis=1)
            for j in range(P)]
    return np.stack([col.reshape(-1) for col in cols], axis=1)


def _exact_cov(J, c, phi, sigma):
    """(J^T J)^-1 J^T Sigma J (J^T J)^-1 for independent AR(1) channels, Sigma built explicitly."""
    n = J.shape[0] // c
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    S = sigma**2 * phi**lag
    A = np.linalg.inv(J.T @ J)
    Jc = J.reshape(n, c, -1)
    B = sum(Jc[:, k].T @ S @ Jc[:, k] for k in range(c))
    return A @ B @ A


def test_naive_equals_the_analytic_covariance_for_white_noise():
    J = _toy()
    rng = np.random.default_rng(1)
    sigma = 0.3
    e = sigma * rng.standard_normal(J.shape[0])
    r = e - J @ np.linalg.lstsq(J, e, rcond=None)[0]  # residual at the least-squares solution
    cov, info = covariance(J, r, 2, method="naive")
    exact = sigma**2 * np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(exact)), rtol=0.05)
    assert info["sigma"] == pytest.approx(sigma, rel=0.05)
    # white noise: the sandwich agrees with it
    cov_s, _ = covariance(J, r, 2, method="sandwich")
    np.testing.assert_allclose(np.sqrt(np.diag(cov_s)), np.sqrt(np.diag(exact)), rtol=0.15)


def test_sandwich_matches_brute_force_for_correlated_noise():
    """AR(1) noise with correlation time ~20 samples: the naive covariance is far too narrow, the
    sandwich matches both the analytic covariance and a Monte Carlo of the estimates."""
    c, phi, sigma = 2, 0.9, 0.5
    J = _toy(n=1500, c=c)
    exact = np.sqrt(np.diag(_exact_cov(J, c, phi, sigma)))
    rng = np.random.default_rng(2)
    est, std_s, std_n = [], [], []
    for _ in range(200):
        e = sigma * _ar1(rng, J.shape[0] // c, c, phi).reshape(-1)
        theta = np.linalg.lstsq(J, -e, rcond=None)[0]  # model J theta fitted to data -e: residual J theta + e
        r = J @ theta + e
        est.append(theta)
        if len(std_s) < 20:
            std_s.append(np.sqrt(np.diag(covariance(J, r, c, method="sandwich")[0])))
            std_n.append(np.sqrt(np.diag(covariance(J, r, c, method="naive")[0])))
    brute = np.std(est, axis=0, ddof=1)
    np.testing.assert_allclose(brute, exact, rtol=0.15)  # the Monte Carlo agrees with the formula
    np.testing.assert_allclose(np.mean(std_s, axis=0), exact, rtol=0.2)
    assert np.all(np.mean(std_n, axis=0) < 0.5 * exact)  # naive: too narrow by > 2x


def test_coverage_machinery_on_a_tiny_case():
    """The toy above, 200 replicates: 90 % intervals from the sandwich hold the truth ~90 % of the time,
    the naive ones far less; a calibration factor fitted on half fixes the naive ones on the other half."""
    c, phi, sigma = 1, 0.8, 1.0
    J = _toy(n=1200, c=c, P=2, seed=3)
    rng = np.random.default_rng(4)
    z_s, z_n = [], []
    for _ in range(200):
        e = sigma * _ar1(rng, J.shape[0], c, phi).reshape(-1)
        theta = np.linalg.lstsq(J, -e, rcond=None)[0]
        r = J @ theta + e
        for method, out in (("sandwich", z_s), ("naive", z_n)):
            cov, _ = covariance(J, r, c, method=method)
            u = ParameterUncertainty(slots=(("alpha", 0), ("p", 0)), transform=("linear", "linear"), centre=theta,
                                     covariance=cov)
            out.append(zscores(u, np.zeros(2)))
    z_s, z_n = np.concatenate(z_s), np.concatenate(z_n)
    assert 0.85 <= coverage(z_s, 0.9) <= 0.95
    assert coverage(z_n, 0.9) < 0.7
    f = calibration_factor(z_n[: z_n.size // 2], 0.9)
    assert f > 1.5 and 0.85 <= coverage(z_n[z_n.size // 2:], 0.9, f) <= 0.95


def test_covariance_bad_input():
    with pytest.raises(InputError, match="method 'bogus' is unknown"):
        covariance(np.zeros((4, 1)), np.zeros(4), 1, method="bogus")
    with pytest.raises(InputError, match="do not match"):
        covariance(np.zeros((5, 1)), np.zeros(4), 1)


# ---------------------------------------------------------------------------- clone files
def _building():
    return Building(mass=[20.0, 15.0], k0=[2e4, 1.5e4], alpha=[0.2, 0.1], p=[2.0, 1.5], dy=[6.0, 4.0],
                    delta_eta=[0.8, 0.0], height=[3000.0, 3000.0], name="toy")


def _uncertain_clone():
    b = _building()
    slots = (("k0", 0), ("alpha", 0), ("dy", 1), ("delta_eta", 1))
    x = np.array([2e4, 0.2, 4.0, 0.0])
    tr = ("log", "log", "log", "linear")
    centre = np.where(np.array(tr) == "log", np.log(np.where(x > 0, x, 1)), x)
    L = np.array([[0.02, 0, 0, 0], [0.01, 0.03, 0, 0], [0, 0.005, 0.04, 0], [0, 0, 0.01, 0.05]])
    unc = ParameterUncertainty(slots=slots, transform=tr, centre=centre, covariance=L @ L.T, method="laplace-sandwich",
                               info={"sigma": 0.05})
    return Clone(building=b, uncertainty=unc)


def test_clone_uncertainty_round_trip(tmp_path):
    c = _uncertain_clone()
    c.save(tmp_path / "c.json")
    d = json.loads((tmp_path / "c.json").read_text())
    assert d["version"] == VERSION and d["uncertainty"]["parameters"][0]["name"] == "k0"
    back = load_clone(tmp_path / "c.json")
    np.testing.assert_allclose(back.uncertainty.covariance, c.uncertainty.covariance, rtol=1e-12)
    np.testing.assert_allclose(back.uncertainty.centre, c.uncertainty.centre, rtol=1e-12)
    assert back.uncertainty.slots == c.uncertainty.slots and back.uncertainty.transform == c.uncertainty.transform
    iv = back.uncertainty.interval(0.9)
    lo, hi = iv["k0[1]"]
    assert lo < 2e4 < hi and hi / 2e4 == pytest.approx(np.exp(1.6448536 * 0.02), rel=1e-6)
    assert iv["delta_eta[2]"][0] == 0.0  # clipped to the bound
    # a clone without uncertainty is written with null and read back
    Clone(building=_building()).save(tmp_path / "plain.json")
    assert load_clone(tmp_path / "plain.json").uncertainty is None


def test_version_1_files_still_read(tmp_path):
    d = Clone(building=_building()).to_dict()
    d["version"] = 1
    for key in ("uncertainty", "system", "events", "state", "identification", "settings"):  # later versions' fields
        d.pop(key, None)
    (tmp_path / "v1.json").write_text(json.dumps(d))
    c = load_clone(tmp_path / "v1.json")
    assert c.uncertainty is None and c.building.n_stories == 2
    d["uncertainty"] = None  # v1 has no such field: strict reading rejects it
    (tmp_path / "v1u.json").write_text(json.dumps(d))
    with pytest.raises(InputError, match="unknown field 'uncertainty'"):
        load_clone(tmp_path / "v1u.json")
    d["version"] = VERSION + 1
    (tmp_path / "vnext.json").write_text(json.dumps(d))
    with pytest.raises(InputError, match=f"clone version {VERSION + 1} is not supported; this hlaid reads"):
        load_clone(tmp_path / "vnext.json")


@pytest.mark.parametrize("change, message", [
    (lambda u: u.update(extra=1), "uncertainty.extra: unknown field"),
    (lambda u: u["parameters"][0].update(name="stiffness"), r"parameters\[0\].name must be one of"),
    (lambda u: u["parameters"][0].update(story=0), r"parameters\[0\].story must be a story number"),
    (lambda u: u["parameters"][1].update(story=7), "names a story beyond the clone's 2"),
    (lambda u: u["parameters"][0].update(transform="sqrt"), "transform must be one of log, linear, logit, log1"),
    (lambda u: u.update(covariance=[[1.0]]), "covariance must be a 4x4"),
    (lambda u: u["covariance"][0].__setitem__(1, 5.0), "symmetric"),
    (lambda u: u.update(covariance=(-np.eye(4)).tolist()), "positive semi-definite"),
])
def test_v2_uncertainty_block_is_read_strictly(tmp_path, change, message):
    d = _uncertain_clone().to_dict()
    change(d["uncertainty"])
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(InputError, match=message) as err:
        load_clone(tmp_path / "bad.json")
    assert str(err.value).startswith(str(tmp_path / "bad.json"))


# ---------------------------------------------------------------------------- ensembles
def test_ensemble_reproducible_by_seed_and_follows_the_covariance():
    c = _uncertain_clone()
    a, b = clone_ensemble(c, 5, seed=3), clone_ensemble(c, 5, seed=3)
    assert [m.k0.tolist() for m in a] == [m.k0.tolist() for m in b]
    other = clone_ensemble(c, 5, seed=4)
    assert [m.k0.tolist() for m in a] != [m.k0.tolist() for m in other]
    big = clone_ensemble(c, 4000, seed=0)
    theta = np.array([[np.log(m.k0[0]), np.log(m.alpha[0]), np.log(m.dy[1])] for m in big])
    np.testing.assert_allclose(np.cov(theta.T), c.uncertainty.covariance[:3, :3], atol=3e-5, rtol=0.1)
    # parameters without uncertainty are kept; the bound of delta_eta is respected
    assert all(m.p.tolist() == [2.0, 1.5] and m.k0[1] == 1.5e4 for m in big)
    assert min(m.delta_eta[1] for m in big) >= 0.0
    assert a[0].name == "toy#0" and a[0].height.tolist() == [3000.0, 3000.0]


@pytest.mark.parametrize("n", [0, -1, 1.5, True, 10**6, "5"])
def test_ensemble_size_out_of_bounds(n):
    with pytest.raises(InputError, match="ensemble members in 1..100000"):
        clone_ensemble(_uncertain_clone(), n)


def test_clone_without_uncertainty_is_refused():
    from hlaid.ida import assess

    plain = Clone(building=_building())
    with pytest.raises(InputError, match="this clone has no uncertainty"):
        clone_ensemble(plain, 10)
    with pytest.raises(InputError, match="this clone has no uncertainty"):
        assess(plain, "builtin-suite")
    with pytest.raises(InputError, match="expected an hlaid Clone"):
        clone_ensemble(_building(), 10)
    with pytest.raises(InputError, match="seed"):
        clone_ensemble(_uncertain_clone(), 3, seed=-1)


def test_interval_level_checked():
    u = _uncertain_clone().uncertainty
    with pytest.raises(InputError, match="interval level"):
        u.interval(1.5)
    assert u.interval(0.5)["k0[1]"][1] < u.interval(0.9)["k0[1]"][1]


# ---------------------------------------------------------------------------- assess
def _motions(n=4, seconds=6.0, dt=0.01, seed=0):
    from scipy import signal

    from hlaid.motions import GroundMotion

    rng = np.random.default_rng(seed)
    sos = signal.butter(2, [0.5, 8.0], btype="bandpass", fs=1 / dt, output="sos")
    t = np.arange(int(seconds / dt)) * dt
    env = np.minimum(t / 1.0, 1.0) * np.exp(-np.maximum(t - 3.0, 0.0) / 1.5)
    return [GroundMotion(dt=dt, acc=2000.0 * env * signal.sosfilt(sos, rng.standard_normal(t.size)) / 0.3,
                         name=f"synthetic-{j}") for j in range(n)]


@pytest.fixture(scope="module")
def small_assessment():
    from hlaid.ida import IDAConfig, assess

    c = _uncertain_clone()
    cfg = IDAConfig(n_levels=4, max_hunt=8, max_fill=3, tolerance=0.1, max_step=0.005)
    own = _motions(1, seed=9)[0]
    a = assess(c, _motions(), n_ensemble=3, ida_config=cfg, own_motion=own, seed=1, n_boot=5)
    return c, cfg, own, a


def test_assess_gives_a_consistent_band_and_indicator(small_assessment):
    from hlaid.ida import intensity

    c, cfg, own, a = small_assessment
    assert a.n_ensemble == 3 and a.n_records == 4 and len(a.member_median) == 3
    assert np.all(a.fragility_lo <= a.fragility_median + 1e-12) and np.all(a.fragility_median <= a.fragility_hi + 1e-12)
    assert np.all(np.diff(a.fragility_median) >= -1e-12) and a.fragility_median[0] == 0.0
    lo, hi = a.collapse_median_band
    assert lo <= a.collapse_median <= hi
    # the common period is the nominal clone's T1, and own_im is the record's Sa(T1) there
    assert a.period == pytest.approx(c.building.periods()[0])
    assert a.own_im == pytest.approx(float(intensity(own, "sa_t1", period=a.period)[0]))
    assert 0 <= a.p_collapse <= 1 and a.p_collapse_band[0] <= a.p_collapse_band[1]
    assert len(a.p_exceed) == len(a.drift_limits) and all(0 <= p <= 1 for p in a.p_exceed)
    assert list(a.p_exceed) == sorted(a.p_exceed, reverse=True)  # larger limits are exceeded less often
    assert a.indicator in ("green", "yellow", "red") and len(a.reasons) == 2
    d = json.loads(json.dumps(a.to_dict()))
    assert d["indicator"] == a.indicator and d["placard"]


def test_assess_reproducible_and_indicator_follows_intensity(small_assessment):
    from hlaid.ida import assess

    c, cfg, own, a = small_assessment
    weak = own.scaled(0.01 / max(a.own_im, 1e-9))  # Sa(T1) = 0.01 g: elastic, nothing happens
    strong = own.scaled(3.0 * a.collapse_median / a.own_im)  # three times the median collapse intensity
    aw = assess(c, _motions(), n_ensemble=3, ida_config=cfg, own_motion=weak, seed=1, n_boot=5)
    np.testing.assert_allclose(aw.member_median, a.member_median)  # same seed: same ensemble and IDA
    assert aw.indicator == "green" and aw.p_collapse < 0.01
    as_ = assess(c, _motions(), n_ensemble=3, ida_config=cfg, own_motion=strong, seed=1, n_boot=5)
    assert as_.indicator == "red" and as_.p_collapse > 0.5


@pytest.mark.parametrize("kw, message", [
    ({"n_ensemble": 0}, "n_ensemble = 0"), ({"n_boot": -1}, "n_boot = -1"), ({"ci": 1.0}, "ci = 1.0"),
    ({"own_motion": "elcentro"}, "own_motion must be a GroundMotion"), ({"ida_config": {}}, "ida_config must be"),
])
def test_assess_bad_input(kw, message):
    from hlaid.ida import assess

    with pytest.raises(InputError, match=message):
        assess(_uncertain_clone(), _motions(2), **kw)


def test_inconsistent_fit_is_never_green(small_assessment):
    import dataclasses

    from hlaid.ida import assess

    c, cfg, own, a = small_assessment
    weak = own.scaled(0.01 / max(a.own_im, 1e-9))
    u = dataclasses.replace(c.uncertainty, info={"misfit_ratio": 4.0, "fit_consistent": False})
    bad = Clone(building=c.building, uncertainty=u)
    with pytest.warns(HlaidWarning, match="misfit above the noise level"):
        ab = assess(bad, _motions(), n_ensemble=3, ida_config=cfg, own_motion=weak, seed=1, n_boot=5)
    assert ab.indicator == "yellow" and "misfit ratio 4" in ab.reasons[-1]
    assert any("misfit" in n for n in ab.notes)


def test_misfit_check_widens_an_inconsistent_fit():
    """The default uncertainty: the calibrated sandwich, and the misfit ratio against the noise-only
    residual level; a fit whose residuals are far above the noise is flagged and widened."""
    from types import SimpleNamespace

    from hlaid.uncertainty import laplace

    J = _toy(n=2000, c=1, P=2)
    rng = np.random.default_rng(5)
    s0 = laplace.noise_residual_rms(0.1, (0.1, 20.0), 0.005)
    assert s0 == pytest.approx(0.1 * np.sqrt(2 * 19.9 * 0.005))

    base = rng.standard_normal(J.shape[0])
    base /= np.sqrt(np.mean(base**2))

    def rr(sigma):  # the same residual pattern at another level
        r = sigma * base
        return SimpleNamespace(slots=(("k0", 0), ("alpha", 0)), x=np.array([2e4, 0.2]), jacobian=J / [2e4, 0.2],
                               residuals=r)

    good = laplace.uncertainty_of_refinement(rr(1.1 * s0), 1, noise_rms=0.1, band_hz=(0.1, 20.0), dt=0.005)
    bad = laplace.uncertainty_of_refinement(rr(4.0 * s0), 1, noise_rms=0.1, band_hz=(0.1, 20.0), dt=0.005)
    plain = laplace.from_refinement(rr(1.1 * s0), 1)
    assert good.info["fit_consistent"] and good.info["misfit_ratio"] == pytest.approx(1.1, rel=0.01)
    np.testing.assert_allclose(good.std, laplace.CALIBRATION * plain.std, rtol=1e-9)
    assert not bad.info["fit_consistent"] and bad.info["misfit_ratio"] == pytest.approx(4.0, rel=0.01)
    np.testing.assert_allclose(bad.std, laplace.CALIBRATION_MISFIT * 4.0 / 1.1 * plain.std, rtol=1e-6)
    eiv = rr(1.1 * s0)
    eiv.criterion = "tangent"  # the errors-in-variables fit (the default) has its own factor
    good = laplace.uncertainty_of_refinement(eiv, 1, noise_rms=0.1, band_hz=(0.1, 20.0), dt=0.005)
    np.testing.assert_allclose(good.std, laplace.CALIBRATION_TANGENT * plain.std, rtol=1e-9)
    assert laplace.CALIBRATION_TANGENT != laplace.CALIBRATION
