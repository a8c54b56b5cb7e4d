"""Path-driven training: the story law along a drift path against the batch simulator, the
sparse segment operator against the HLA segment slopes, one feature function for measured
and simulated data, the drift reconstruction and the force-drift loop fit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import paper_record, random_building, window

from hlaid.hla import run_hla
from hlaid.hla.halfcycles import half_cycle_bounds
from hlaid.hla.stiffness import segment_slopes
from hlaid.identify.drift import hla_drift, reconstruct_drift
from hlaid.identify.loopfit import fit_story_loop
from hlaid.identify.pathtrain import StoryPath, noise_bank, path_training_set, segment_operator, story_features
from hlaid.motions import GroundMotion
from hlaid.signal import bandpass
from hlaid.simulate import simulate_response
from hlaid.simulate.path import drive_story
from hlaid.synthetic import simulate_measurement


def _fine(gm: GroundMotion, rate: float, seconds: float) -> GroundMotion:
    g = gm.resampled(rate)
    return GroundMotion(dt=g.dt, acc=g.acc[: int(round(seconds / g.dt))], name=g.name)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_drive_story_matches_the_batch_simulator(seed):
    """The same drift in (the simulator's, with its velocity), the same force out to 1e-8 of
    the peak force: random 3-story buildings, 10 s of a real record at 1000 Hz."""
    rng = np.random.default_rng(seed)
    b = random_building(rng, 3)
    gm = _fine(paper_record("elcentro-1940-ns"), 1000.0, 10.0)
    r = simulate_response(b, gm, substeps=2)
    assert r.status[0] == 0
    for i in range(3):
        out = drive_story(r.drift[0][:, i], k0=b.k0[i], alpha=b.alpha[i], p=b.p[i], dy=b.dy[i],
                          delta_eta=b.delta_eta[i], mass=b.mass[i], dt=gm.dt, velocity=r.vel[0][:, i] - (
                              r.vel[0][:, i - 1] if i else 0.0), substeps=2)
        f = r.force[0][:, i]
        assert np.max(np.abs(out.force[0] - f)) <= 1e-8 * np.max(np.abs(f))
        assert np.allclose(out.z[0], r.z[0][:, i], atol=1e-8 * b.dy[i])


def test_drive_story_batches_parameters_and_paths(table1):
    """A batch of parameter sets equals the same sets one at a time; one path per set works."""
    gm = _fine(paper_record("kobe-1995-nis000"), 200.0, 8.0)
    x = simulate_response(table1, gm).drift[0][:, 0]
    alphas = np.array([0.1, 0.2, 0.3])
    batch = drive_story(x, k0=1.9e4, alpha=alphas, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=gm.dt)
    for j, a in enumerate(alphas):
        one = drive_story(x, k0=1.9e4, alpha=a, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=gm.dt)
        assert np.array_equal(batch.force[j], one.force[0])
    two = drive_story(np.stack([x, 0.5 * x]), k0=1.9e4, alpha=[0.2, 0.2], p=2.0, dy=6.0, delta_eta=0.5, mass=17.5,
                      dt=gm.dt)
    half = drive_story(0.5 * x, k0=1.9e4, alpha=0.2, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=gm.dt)
    assert np.array_equal(two.force[1], half.force[0])
    ke = batch.elastic_stiffness(1.9e4, alphas, 0.5, 17.5)
    assert np.all(ke[:, 0] == 1.9e4) and np.all(ke[:, -1] < 0.95 * 1.9e4)  # degraded by the end
    assert np.all(ke > alphas[:, None] * 1.9e4) and np.all(ke <= 1.9e4 * (1 + 1e-9))
    with pytest.raises(ValueError, match="paths"):
        drive_story(np.stack([x, x]), k0=1.9e4, alpha=alphas, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=gm.dt)
    lean = drive_story(x, k0=1.9e4, alpha=alphas, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=gm.dt, state=False)
    assert np.array_equal(lean.force, batch.force) and lean.z is None and lean.energy is None
    with pytest.raises(ValueError, match="state=True"):
        lean.elastic_stiffness(1.9e4, alphas, 0.5, 17.5)


@pytest.mark.parametrize("hermite", [False, True])
def test_drive_story_lanes_are_independent(hermite):
    """The kernel steps blocks of parameter sets in lockstep: a batch over several blocks (37
    sets, two paths, some with a dy so small that their steps are redone with more sub-steps)
    gives every set exactly what it gives alone."""
    rng = np.random.default_rng(5)
    t = np.arange(600) * 0.01
    x = np.stack([40.0 * np.sin(2 * np.pi * 0.8 * t) * np.minimum(t, 1.0), 25.0 * np.sin(2 * np.pi * 1.3 * t)])
    v = np.gradient(x, 0.01, axis=1) if hermite else None
    n = 38  # two paths: sets 0, 2, 4, ... follow the first
    par = {"k0": rng.uniform(8e3, 2e4, n), "alpha": rng.uniform(0.05, 0.4, n), "p": rng.uniform(1.0, 3.0, n),
           "dy": np.exp(rng.uniform(np.log(0.05), np.log(8.0), n)), "delta_eta": rng.uniform(0.0, 1.5, n)}
    batch = drive_story(x, **par, mass=20.0, dt=0.01, velocity=v, substeps=2)
    for b in (0, 1, 15, 16, 17, 36, 37):
        one = drive_story(x[b % 2], **{k: a[b] for k, a in par.items()}, mass=20.0, dt=0.01,
                          velocity=None if v is None else v[b % 2], substeps=2)
        assert np.array_equal(batch.force[b], one.force[0]) and np.array_equal(batch.energy[b], one.energy[0])
    assert np.any(par["dy"] < 0.1)  # the redo is exercised


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_drive_story_stays_on_the_law_when_a_sample_spans_many_dy():
    """A drift increment of up to 100 dy per sample (a coarse-pass draw of a small dy): the
    sub-step redo and the law's limit keep |z| <= dy and the force bounded by the
    elastic-perfectly-plastic envelope (it was 1e105-1e169 N, or NaN). Paths the plain RK4
    integrates well are left as they were (the test above against the batch simulator)."""
    t = np.arange(400) * 0.01
    x = 80.0 * np.sin(2 * np.pi * t) * np.minimum(t, 1.0)
    dy = np.array([0.05, 0.1, 0.3, 1.0, 5.0])
    for p in (1.2, 2.0, 3.0):
        r = drive_story(x, k0=1e4, alpha=0.1, p=p, dy=dy, delta_eta=0.5, mass=20.0, dt=0.01, substeps=1)
        assert np.isfinite(r.force).all() and np.isfinite(r.energy).all()
        assert np.all(np.abs(r.z) <= dy[:, None] * (1 + 1e-5))
        assert np.all(np.abs(r.force) <= 0.1e4 * 80.0 + 0.9e4 * dy[:, None] * (1 + 1e-5))


def test_segment_operator_equals_segment_slopes():
    """W @ f is exactly the least-squares segment slopes of hlaid.hla.stiffness."""
    rng = np.random.default_rng(3)
    t = np.linspace(0, 6, 1200)
    x = 20 * np.sin(2 * np.pi * 1.1 * t) * (1 + 0.3 * np.sin(0.7 * t))
    f = 1e4 * np.tanh(x / 8) + 50 * rng.standard_normal(t.size)
    bounds = half_cycle_bounds(x, 1.0)[1:4]
    W = segment_operator(x, bounds, 10)
    got = story_features(W, f, 1.0).reshape(len(bounds), 10)
    for j, (s, e) in enumerate(bounds):
        assert np.allclose(got[j], segment_slopes(x, f, s, e, 10), rtol=1e-10, atol=1e-8)
    batch = story_features(W, np.stack([f, 2 * f], axis=1), 2.0)
    assert batch.shape == (2, 30) and np.allclose(batch[1], got.ravel())


def test_measured_and_simulated_features_through_one_function(table1):
    """A noise-free path sample at the true parameters reproduces the features of the true
    force along the same path (the measured side), within the RK4 error of the path."""
    gm = paper_record("elcentro-1940-ns")
    meas = simulate_measurement(table1, gm, noise_rms=0.0)
    i = 1
    x, f = meas.truth.drift[:, i], meas.truth.force[:, i]
    res = run_hla(meas)
    hc = res.stories[i].half_cycles
    bounds = np.stack([hc.start, hc.end], axis=1)[np.argsort(hc.drift_increment)[-8:]]
    sp = StoryPath(drift=x, force=f, bounds=np.sort(bounds, axis=0), k0=float(table1.k0[i]),
                   mass=float(table1.mass[i]), noise_std=0.0, dt=meas.dt, cutoff_hz=20.0)
    S = path_training_set(sp, k0=table1.k0[i], dy=table1.dy[i], delta_eta=table1.delta_eta[i],
                          alpha_range=(table1.alpha[i],) * 2, p_range=(table1.p[i],) * 2, n_samples=2, spread=0.0,
                          seed=0)
    measured = sp.measured_features()
    assert S.X.shape == (2, 80)
    assert np.max(np.abs(S.X[0] - measured)) < 5e-3 * np.max(np.abs(measured))
    # the noise enters with the covariance of the low-passed force noise
    noisy = dataclasses.replace(sp, noise_std=1e3)
    Sn = path_training_set(noisy, k0=table1.k0[i], dy=table1.dy[i], delta_eta=table1.delta_eta[i],
                           alpha_range=(table1.alpha[i],) * 2, p_range=(table1.p[i],) * 2, n_samples=400,
                           spread=0.0, seed=1)
    direct = story_features(sp.operator, bandpass(np.random.default_rng(2).standard_normal((sp.end, 400)) * 1e3,
                                                       sp.dt, (0.0, 20.0)), sp.k0)
    sd_model, sd_direct = (Sn.X - S.X[0]).std(axis=0), direct.std(axis=0)
    assert np.median(np.abs(sd_model / sd_direct - 1)) < 0.15
    # a run's shared bank, longer than this path, carries the same covariance; a shorter one is refused
    bank = noise_bank(sp.end + 500, sp.dt, 20.0, seed=3)
    Sb = path_training_set(noisy, k0=table1.k0[i], dy=table1.dy[i], delta_eta=table1.delta_eta[i],
                           alpha_range=(table1.alpha[i],) * 2, p_range=(table1.p[i],) * 2, n_samples=400,
                           spread=0.0, seed=1, noise=bank)
    assert np.median(np.abs((Sb.X - S.X[0]).std(axis=0) / sd_direct - 1)) < 0.15
    assert not np.allclose(Sb.X, Sn.X)
    with pytest.raises(ValueError, match="noise bank"):
        path_training_set(noisy, k0=table1.k0[i], dy=table1.dy[i], delta_eta=table1.delta_eta[i],
                          alpha_range=(0.1, 0.2), p_range=(1.5, 2.0), n_samples=4, spread=0.0, seed=1,
                          noise=bank[: sp.end - 1])


def test_drift_reconstruction_beats_hla_and_falls_back(table1):
    """With the true building the reconstructed drift is several times closer to the truth
    than HLA's (10 % noise); without a building it is HLA's drift."""
    meas = simulate_measurement(table1, paper_record("kocaeli-1999-dzc180"), noise_rms=0.10, seed=0)
    res = run_hla(meas)
    ground = GroundMotion(dt=meas.dt, acc=bandpass(np.asarray(meas.ground_acc), meas.dt, (0.0, res.band_hz[1])))
    true = meas.truth.drift

    def rms(a):
        return np.sqrt(np.mean(a**2, axis=0))

    e_hla = rms(hla_drift(res) - true) / rms(true)
    e_rec = rms(reconstruct_drift(res, ground, table1) - true) / rms(true)
    assert np.all(e_rec < 0.5 * e_hla)
    assert np.array_equal(reconstruct_drift(res, ground, None), hla_drift(res))


def test_loop_fit_recovers_k0_along_the_true_path(table1):
    """k0 started 10 % off comes back to the truth along the true drift (noise-free)."""
    gm = window(paper_record("elcentro-1940-ns"), 12.0)
    meas = simulate_measurement(table1, gm, noise_rms=0.0)
    i = 0
    start = {"k0": 1.1 * table1.k0[i], "alpha": table1.alpha[i], "p": table1.p[i], "dy": table1.dy[i],
             "delta_eta": table1.delta_eta[i]}
    fit = fit_story_loop(meas.truth.drift[:, i], meas.truth.force[:, i], meas.dt, float(table1.mass[i]), start)
    assert abs(fit.params["k0"] / table1.k0[i] - 1) < 2e-3
    assert fit.rms_final < 0.05 * fit.rms_initial


def test_cross_validated_C_and_bagged_ensemble_match_scikit_learn():
    """choose_hyper's fold accuracies are scikit-learn SVC's on the same folds, for every C and
    every factor of gamma = "scale"; the ensemble has n_bags machines whose votes sum to n_bags
    per measured vector, standardised features."""
    from sklearn.svm import SVC

    from hlaid.identify.classify import Bins, apply_scaler, choose_hyper, fit_ensemble, scaler_of, vote
    from hlaid.identify.config import SVMConfig
    from hlaid.identify.training import TrainingSet

    rng = np.random.default_rng(5)
    n = 300
    a = rng.uniform(0.0, 0.3, n)
    X = np.column_stack([a * 40 + rng.normal(0, 1.0, n), rng.normal(0, 1, (n, 4)) * [1, 10, 100, 1000]]) + 5.0
    cfg = SVMConfig(C_grid=(1.0, 100.0), gamma_grid=(0.1, 1.0), cv_folds=2, n_bags=5, bag_fraction=0.5)
    bins = Bins.regular(0.0, 0.3, 0.1)
    y = bins.label(a)
    Z = apply_scaler(X, scaler_of(X))
    assert np.allclose(Z.mean(axis=0), 0, atol=1e-12) and np.allclose(Z.std(axis=0), 1)
    h = choose_hyper(Z, y, cfg)
    folds = np.arange(n) % 2
    assert {(r["C"], r["gamma_factor"]) for r in h.cv_accuracy} == {(1.0, 0.1), (1.0, 1.0), (100.0, 0.1), (100.0, 1.0)}
    for r in h.cv_accuracy:  # "scale" on standardised features is 1 / n_features
        svc = SVC(C=r["C"], gamma=r["gamma_factor"] / Z.shape[1])
        ref = np.mean([np.mean(svc.fit(Z[folds != k], y[folds != k]).predict(Z[folds == k]) == y[folds == k])
                       for k in (0, 1)])
        assert abs(r["accuracy"] - ref) <= 0.01
    best = max(r["accuracy"] for r in h.cv_accuracy)
    assert [r["accuracy"] for r in h.cv_accuracy if (r["C"], r["gamma_factor"]) == (h.C, h.gamma_factor)] == [best]
    assert h.gamma == pytest.approx(h.gamma_factor / Z.shape[1])
    machines, st = fit_ensemble(TrainingSet(X=X, alpha=a, p=a, sim=np.arange(n)), "alpha", bins, cfg, 0.2, seed=1)
    assert len(machines) == 5 and st["bags"] == 5 and st["C"] in cfg.C_grid and len(st["cv_accuracy"]) == 4
    assert st["gamma_factor"] in cfg.gamma_grid and all(m.gamma == st["gamma"] for m in machines)
    assert st["test_accuracy"] > 0.8
    v = vote(machines, X[:1], bins, scaler=st["scaler"])
    assert v.sum() == 5 and v.argmax() == y[0]


def test_hyper_parameters_without_grids_and_reused_choice():
    """Without grids the configured C and gamma are used as they are (no cross-validation);
    a later pass reuses an earlier choice as one (C, gamma factor) pair, gamma resolved on its
    own features; an empty or non-positive gamma grid is refused."""
    from hlaid.errors import InputError
    from hlaid.identify.classify import choose_hyper
    from hlaid.identify.config import SVMConfig
    from hlaid.identify.passes import _chosen

    rng = np.random.default_rng(0)
    X, y = rng.normal(size=(40, 8)), np.arange(40) % 3
    h = choose_hyper(X, y, SVMConfig(C=7.0, C_grid=None, gamma_grid=None))
    assert (h.C, h.gamma, h.cv_accuracy) == (7.0, "scale", [])
    again = choose_hyper(2.0 * X, y, _chosen(SVMConfig(), 1000.0, 0.1))
    assert again.C == 1000.0 and again.cv_accuracy == [] and again.gamma == pytest.approx(0.1 / (8 * (2.0 * X).var()))
    for bad in ((), (0.0, 1.0)):
        with pytest.raises(InputError, match="gamma_grid"):
            SVMConfig(gamma_grid=bad)


def test_config_kernel_names_are_the_svm_kernels():
    """The identify config names the kernels without importing torch; they are the machines' kernels,
    and an unknown one is refused by name."""
    from hlaid.errors import InputError
    from hlaid.identify.config import KERNEL_NAMES, SVMConfig
    from hlaid.svm import KERNELS

    assert sorted(KERNEL_NAMES) == sorted(KERNELS)
    for name in KERNEL_NAMES:
        assert SVMConfig(kernel=name).kernel == name
    with pytest.raises(InputError, match="svm.kernel = 'gauss' is unknown; expected one of linear, poly, rbf"):
        SVMConfig(kernel="gauss")


def test_loop_fit_recovers_all_five_parameters_along_the_true_path(table1):
    """All five story parameters, started 10 % off, come back along the true drift against the
    true restoring force (noise-free), on every story: the estimator behind
    ``scripts/study_loop_bound.py`` is consistent, so what that study measures is the path's and
    the noise's doing."""
    gm = window(paper_record("elcentro-1940-ns"), 12.0)
    meas = simulate_measurement(table1, gm, noise_rms=0.0)
    names = ("k0", "alpha", "p", "dy", "delta_eta")
    for i in range(table1.n_stories):
        truth = {n: float(getattr(table1, n)[i]) for n in names}
        start = {n: v * (1.1 if j % 2 else 0.9) for j, (n, v) in enumerate(truth.items())}
        fit = fit_story_loop(meas.truth.drift[:, i], meas.truth.force[:, i], meas.dt, float(table1.mass[i]), start,
                             free=names, max_nfev=60)
        err = {n: abs(fit.params[n] / truth[n] - 1) for n in names}
        assert max(err.values()) < 5e-3, (i, err)  # 0.3-2.4e-3: the path is straight between samples


def test_vectorised_power_is_libms_within_two_ulps_of_one():
    """The path drive's ``|z/dy|^p`` (exp(p log w) in vectorising arithmetic) against ``w ** p``:
    within 4.5e-16 absolute (two ulps of 1) over w in [0, 1 + 1e-5] and p in [1, 10], exact at 0 and 1, 0
    below 1e-300."""
    import numba as nb

    from hlaid.simulate import path

    @nb.njit
    def power(w, p):
        W = np.zeros((path._ROWS, w.size))
        W[path._W] = w
        par = np.zeros((5, w.size))
        par[path._P] = p
        path._pow_lanes(0, w.size, 0, W, W.view(np.int64), par)
        return W[path._Q].copy()

    rng = np.random.default_rng(0)
    w = np.concatenate([rng.uniform(0.0, 1.0 + 1e-5, 200_000), 10.0 ** rng.uniform(-300, 0, 50_000),
                        [0.0, 1.0, 1e-301, 0.5]])
    p = np.concatenate([rng.uniform(1.0, 10.0, w.size - 4), [2.0, 2.5, 1.0, 1.0]])
    q = power(w, p)
    assert np.max(np.abs(q - w**p)) <= 4.5e-16
    assert q[-4] == 0.0 and q[-3] == 1.0 and q[-2] == 0.0 and q[-1] == 0.5
