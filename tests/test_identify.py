"""Automated identification: regressions exact for the forward model, classifier passes,
replay refinement, the pipeline end to end on a short case, its cache and its CLI.

The accuracy studies (5 records x 3 seeds, 30 random structures) are scripts
(``scripts/study_identification.py``), not tests.
"""

from __future__ import annotations

import dataclasses
import importlib
import json

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid import identify_clone
from hlaid.cli.app import main
from hlaid.clone import Clone
from hlaid.identify import IdentifyConfig, OuterConfig, RefineConfig, TrainingConfig, refine_replay
from hlaid.identify.classify import Bins, pass_result
from hlaid.identify.regression import fit_delta_eta, fit_yield_displacement, hysteretic_displacement, hysteretic_work
from hlaid.synthetic import simulate_measurement
from hlaid.uncertainty import zscores


@pytest.fixture(scope="module")
def record():
    return window(paper_record("kocaeli-1999-dzc180"), 14.0, before_peak=4.0)


def test_regressions_exact_for_the_forward_model(table1):
    """eq 12-17 on noise-free simulated data with the true alpha and p return the true
    delta_eta and dy within 0.5 %."""
    meas = simulate_measurement(table1, paper_record("elcentro-1940-ns"), noise_rms=0.0)
    tr = meas.truth
    for i in range(3):
        a, k0, p = table1.alpha[i], table1.k0[i], table1.p[i]
        x, f = tr.drift[:, i], tr.force[:, i]
        z = hysteretic_displacement(f, x, a, k0)
        assert np.allclose(z, tr.z[:, i], atol=1e-9)
        u = hysteretic_work(z, x)
        ke = table1.elastic_stiffness(tr.eta)[:, i]
        de = fit_delta_eta(ke, u, k0=k0, alpha=a, mass=table1.mass[i])
        assert de.value == pytest.approx(table1.delta_eta[i], rel=0.005)
        dx, dz = np.gradient(x), np.gradient(z)
        load = (dx * z > 0) & (np.abs(dx) > 1e-3)
        load &= np.roll(load, 1) & np.roll(load, -1)  # away from the kink at reversals
        k = a * k0 + (1 - a) * k0 * dz[load] / dx[load]
        dy = fit_yield_displacement(ke[load], k, np.abs(z[load]), k0=k0, alpha=a, p=p)
        assert dy.value == pytest.approx(table1.dy[i], rel=0.005)


def test_paper_denominator_would_be_wrong(table1):
    """The paper's eq 13 with ke in the denominator is not what the model gives."""
    meas = simulate_measurement(table1, paper_record("elcentro-1940-ns"), noise_rms=0.0)
    tr, i = meas.truth, 0
    a, k0, m = table1.alpha[i], table1.k0[i], table1.mass[i]
    ke = table1.elastic_stiffness(tr.eta)[:, i]
    u = hysteretic_work(tr.z[:, i], tr.drift[:, i]) * 1e-6
    y_paper = m * (k0 - ke) / ((1 - a) * ke * (ke - a * k0))
    sel = u > 0
    de_paper = np.sum(u[sel] * y_paper[sel]) / np.sum(u[sel] ** 2)
    assert abs(de_paper / table1.delta_eta[i] - 1) > 0.05


def test_bins_and_votes():
    b = Bins.regular(0.0, 0.6, 0.05)
    assert b.n == 12 and np.allclose(b.centers[:2], [0.025, 0.075])
    assert list(b.label(np.array([0.0, 0.049, 0.05, 0.61]))) == [0, 0, 1, 11]
    fine = b.refine(4, 0.01, (0.0, 0.6))  # the paper: bin [0.20, 0.25] -> [0.15, 0.30] by 0.01
    assert fine.range == pytest.approx((0.15, 0.30)) and fine.n == 15
    edge = b.refine(0, 0.01, (0.0, 0.6))
    assert edge.range == pytest.approx((0.0, 0.10))
    stats = {"train_accuracy": 1.0, "test_accuracy": 0.5, "confusion": np.zeros((12, 12)), "n_train": 1,
             "n_test": 1, "seconds": 0.0}
    votes = np.zeros(12)
    votes[[3, 4]] = [1, 3]
    assert pass_result("alpha", "coarse", b, votes, stats, False, "majority").value == pytest.approx(0.225)
    assert pass_result("alpha", "coarse", b, votes, stats, False, "mean").value == pytest.approx(0.2125)


def test_refine_recovers_perturbed_parameters(table1, record):
    meas = simulate_measurement(table1, record, noise_rms=0.0)
    rng = np.random.default_rng(0)
    start = table1.replace(k0=table1.k0 * rng.uniform(0.95, 1.05, 3), alpha=table1.alpha + 0.03,
                           p=table1.p * rng.uniform(0.85, 1.15, 3), dy=table1.dy * rng.uniform(0.9, 1.1, 3),
                           delta_eta=table1.delta_eta * rng.uniform(0.85, 1.15, 3))
    r = refine_replay(start, meas)
    assert r.cost_final < 1e-3 * r.cost_initial
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        assert np.allclose(getattr(r.building, name), getattr(table1, name), rtol=0.01), name


def test_refine_runs_blas_on_one_thread_only_for_small_problems(table1):
    """The refinement's BLAS limit is read from the call's own arguments (bound with their
    defaults): one thread for residuals x parameters^2 below ``_BLAS_ONE_THREAD``, the process's
    own setting above it and after the call."""
    from types import SimpleNamespace

    from threadpoolctl import threadpool_info

    rf = importlib.import_module("hlaid.identify.refine")

    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    @rf._blas_threads
    def probe(building, measurement, *, parameters=("k0", "alpha"), damping=False):
        return blas_threads()

    before = blas_threads()
    small = SimpleNamespace(floor_acc=np.zeros((1000, 3)))  # 3e3 x (2 x 3)^2 = 1e5
    large = SimpleNamespace(floor_acc=np.broadcast_to(0.0, (10**6, 3)))  # 3e6 x (5 x 3 + 1)^2 = 8e8
    assert probe(table1, small) == [1] * len(before)
    assert probe(table1, large, parameters=("k0", "alpha", "p", "dy", "delta_eta"), damping=True) == before
    assert blas_threads() == before
    assert probe.__name__ == "probe"


def test_refine_jacobian_substeps_keep_the_optimum(table1, record):
    """Fewer RK4 sub-steps in the Jacobian's replays steer the search differently but the
    residuals (4 sub-steps) define the optimum: the same building, and the same cost."""
    meas = simulate_measurement(table1, record, noise_rms=0.1, seed=4)
    start = table1.replace(k0=table1.k0 * 1.04, alpha=table1.alpha + 0.02, p=table1.p * 0.9, dy=table1.dy * 1.08,
                           delta_eta=table1.delta_eta * 1.1)
    ref = refine_replay(start, meas, jac_substeps=4)
    fast = refine_replay(start, meas, jac_substeps=1)
    assert fast.cost_final == pytest.approx(ref.cost_final, rel=1e-5)
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_allclose(getattr(fast.building, name), getattr(ref.building, name), rtol=1e-3, err_msg=name)


def _small_config(**kw) -> IdentifyConfig:
    return IdentifyConfig(training=TrainingConfig(samples=60, n_segments=8),
                          outer=OuterConfig(max_iterations=1), **kw)


def test_identify_end_to_end_cached_and_logged(table1, record, tmp_path):
    """The pipeline on 14 s of Kocaeli at 5 % noise with small training sets: every parameter
    within 4 % of the truth and within 4 standard deviations of its own uncertainty; the file,
    the logs and the cache."""
    meas = simulate_measurement(table1, record, noise_rms=0.05, seed=1)
    cfg = _small_config()
    res = identify_clone(meas, cfg, tensorboard=str(tmp_path / "tb"), cache_dir=str(tmp_path / "cache"))
    b = res.clone.building
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        err = np.abs(getattr(b, name) / getattr(table1, name) - 1)
        assert err.max() < 0.04, (name, err)
    u = res.clone.uncertainty
    z = zscores(u, [getattr(table1, k)[i] for k, i in u.slots])
    assert np.all(np.abs(z) < 4), dict(zip(u.names, z.round(2)))
    assert np.all(res.replay.r_true > 0.999) and np.all(res.replay.r_measured > 0.95)
    d = res.clone.to_dict()
    assert d["format"] == "hlaid-clone" and len(d["stories"]) == 3
    assert d["provenance"]["hlaid_version"] and "timings" in d["provenance"]
    assert {"outer_iterations", "passes", "stories", "replay"} <= set(d["diagnostics"])
    # the refinement's Laplace uncertainty, stored in the file (version 2); a fit at the noise level
    assert d["version"] == 4 and len(d["uncertainty"]["parameters"]) == len(u.slots) > 0
    assert u.info["fit_consistent"] and np.all(u.std > 0) and np.all(u.std < 0.5)
    assert any(p.name.startswith("events.out.tfevents") for p in (tmp_path / "tb").iterdir())
    cached = sorted((p.relative_to(tmp_path), p.stat().st_size) for p in (tmp_path / "cache").rglob("*"))
    again = identify_clone(meas, cfg, cache_dir=str(tmp_path / "cache"))
    # every kernel machine comes from the cache (none trained, nothing written) and gives the same clone
    assert all(v["cached"] for p in again.passes for s in p["stories"] if s for v in s.values())
    assert sorted((p.relative_to(tmp_path), p.stat().st_size) for p in (tmp_path / "cache").rglob("*")) == cached
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_allclose(getattr(again.clone.building, name), getattr(b, name), rtol=1e-9, err_msg=name)


def test_worker_processes_give_the_same_clone(table1, record):
    """The kernel machines trained on worker processes (n_jobs 2, overlapping the next story's
    samples) are the machines trained in the process itself: the same clone to the digit."""
    meas = simulate_measurement(table1, record, noise_rms=0.05, seed=2)
    cfg = _small_config(refine=RefineConfig(method="none"))
    one = identify_clone(meas, dataclasses.replace(cfg, n_jobs=1), cache_dir="")
    two = identify_clone(meas, dataclasses.replace(cfg, n_jobs=2), cache_dir="")
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_array_equal(getattr(one.clone.building, name), getattr(two.clone.building, name))
    def votes(res):
        return [[{k: (v["votes"], v["test_accuracy"]) for k, v in s.items()} for s in p["stories"]] for p in res.passes]

    assert votes(one) == votes(two)


def test_refinement_restarts_from_a_neutral_start_when_the_fit_misses_the_noise(table1, record):
    """``refine.restart_ratio``: above it the refinement runs again from the neutral start and
    keeps the clearly better fit; below it (Table 1 fits to its noise) it does not; the ratio
    is reported."""
    meas = simulate_measurement(table1, record, noise_rms=0.05, seed=2)
    base = _small_config(refine=RefineConfig(method="least_squares", max_iterations=4))
    plain = identify_clone(meas, base, cache_dir="").clone.diagnostics["refine"]
    assert "restart" not in plain and 0 < plain["noise_ratio"] < base.refine.restart_ratio
    res = identify_clone(meas, dataclasses.replace(base, refine=RefineConfig(method="least_squares", max_iterations=4,
                                                                             restart_ratio=1e-6)), cache_dir="")
    info = res.clone.diagnostics["refine"]
    assert info["restart"]["noise_ratio"] == pytest.approx(plain["noise_ratio"])
    kept = info["restart"]["kept"]
    assert info["cost_final"] == pytest.approx(info["restart"]["cost_final"] if kept else plain["cost_final"])
    if kept:
        assert info["restart"]["cost_final"] < 0.8 * plain["cost_final"]
    assert res.refinement.cost_final == pytest.approx(info["cost_final"])


def test_elastic_story_marked_not_identifiable(table1, record):
    strong_top = table1.replace(dy=np.array([7.0, 6.0, 60.0]))  # the top story cannot yield
    meas = simulate_measurement(strong_top, record, noise_rms=0.02, seed=2)
    res = identify_clone(meas, _small_config(refine=RefineConfig(method="none")), cache_dir="")
    assert res.clone.paper is not None
    top = res.clone.paper.stories[2]
    assert not top.identifiable and "elastic" in top.reason
    assert res.clone.building.dy[2] >= np.max(np.abs(meas.truth.drift[:, 2]))


def test_cli_identify(table1, record, tmp_path, capsys):
    meas = simulate_measurement(table1, record, noise_rms=0.05, seed=3).save(tmp_path / "m.npz")
    cfg = tmp_path / "id.yaml"
    cfg.write_text("training: {samples: 60, n_segments: 8}\nouter: {max_iterations: 1}\n"
                   "refine: {method: none}\n")
    out = tmp_path / "clone.json"
    assert main(["identify", str(meas), "-o", str(out), "--config", str(cfg), "--no-cache", "-q"]) == 0
    clone = Clone.load(out)
    assert clone.building.n_stories == 3
    assert main(["identify", str(meas), "-o", str(out), "--config", str(cfg), "--no-cache", "-q"]) == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text("training: {samplez: 3}\n")
    assert main(["identify", str(meas), "-o", str(tmp_path / "c2.json"), "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "samplez" in err and "bad.yaml:1" in err and "Traceback" not in err
    assert not (tmp_path / "c2.json").exists()
    json.loads(out.read_text())
