"""Simulated drift-path errors (``training.path_errors``): the error bank against the real
path's error, training samples driven along ``path - error`` against the story law driven
sample by sample, the identification with the option, its validation."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.errors import InputError
from hlaid.hla import HLAConfig, run_hla
from hlaid.identify import IdentifyConfig, OuterConfig, RefineConfig, TrainingConfig, identify_clone
from hlaid.identify.drift import hla_drift, reconstruct_drift
from hlaid.identify.patherrors import path_error_bank
from hlaid.identify.pathtrain import StoryPath, path_training_set, story_features
from hlaid.measurement import measured_ground
from hlaid.simulate.path import drive_story
from hlaid.synthetic import simulate_measurement


@pytest.fixture(scope="module")
def measured(table1):
    meas = simulate_measurement(table1, paper_record("kocaeli-1999-dzc180"), noise_rms=0.10, seed=4)
    res = run_hla(meas)
    return meas, res, measured_ground(meas, res.band_hz[1])


def _rms(a, axis=-2):
    return np.sqrt(np.mean(a ** 2, axis=axis))


@pytest.mark.parametrize("reconstruct", [False, True])
def test_error_bank_has_the_real_path_error(table1, measured, reconstruct):
    """Repeating the measurement on the true building gives path errors of the size of the
    measured path's own (per story within 25 % RMS); HLA's drift error is mostly systematic
    (the high-pass drops the plastic offsets), so there the histories follow the real error."""
    meas, res, ground = measured
    path = reconstruct_drift(res, ground, table1) if reconstruct else hla_drift(res)
    real = path - meas.truth.drift
    bank = path_error_bank(res, ground, table1, noise_rms=0.10, n=3, seed=11, reconstruct=reconstruct,
                           crossover_hz=1.0, hla_config=HLAConfig())
    assert bank.shape == (3,) + real.shape
    ratio = _rms(bank) / _rms(real)
    assert np.all(np.abs(ratio - 1) < 0.25), ratio
    assert not np.array_equal(bank[0], bank[1])  # independent noise per history
    if not reconstruct:
        corr = [np.corrcoef(bank[0][:, i], real[:, i])[0, 1] for i in range(3)]
        assert min(corr) > 0.4, corr
    # per story: reconstructed where asked, HLA's drift elsewhere (the same noise, seed 11)
    mixed = path_error_bank(res, ground, table1, noise_rms=0.10, n=1, seed=11, reconstruct=[True, False, True],
                            crossover_hz=1.0, hla_config=HLAConfig())
    other = path_error_bank(res, ground, table1, noise_rms=0.10, n=1, seed=11, reconstruct=not reconstruct,
                            crossover_hz=1.0, hla_config=HLAConfig())
    rec, raw = (bank[0], other[0]) if reconstruct else (other[0], bank[0])
    np.testing.assert_array_equal(mixed[0], np.stack([rec[:, 0], raw[:, 1], rec[:, 2]], axis=1))


def test_samples_follow_path_minus_error(table1, measured):
    """Sample b is the story law along ``path - error[b % histories]``, its features taken with
    the path's operator; a zero error bank is the plain path bit for bit."""
    meas, res, _ = measured
    i = 0
    s = res.stories[i]
    hc = s.half_cycles
    bounds = np.stack([hc.start, hc.end], axis=1)[np.sort(np.argsort(hc.drift_increment)[-6:])]
    sp = StoryPath(drift=s.drift, force=s.force, bounds=bounds, k0=float(table1.k0[i]), mass=float(table1.mass[i]),
                   noise_std=0.0, dt=meas.dt, cutoff_hz=20.0)
    kw = {"k0": table1.k0[i], "dy": table1.dy[i], "delta_eta": table1.delta_eta[i], "alpha_range": (0.05, 0.3),
          "p_range": (1.2, 2.8), "spread": 0.0, "seed": 3, "substeps": 1}
    rng = np.random.default_rng(5)
    err = np.cumsum(rng.standard_normal((3, s.drift.shape[0])), axis=1) * 0.01  # (history, time)
    for n in (6, 7):  # the histories divide the samples, or not
        S = path_training_set(sp, n_samples=n, path_errors=err, **kw)
        for b in range(n):
            f = drive_story(sp.drift[: sp.end] - err[b % 3, : sp.end], k0=table1.k0[i], alpha=S.alpha[b], p=S.p[b],
                            dy=table1.dy[i], delta_eta=table1.delta_eta[i], mass=sp.mass, dt=sp.dt,
                            substeps=1).force[0]
            np.testing.assert_allclose(S.X[b], story_features(sp.operator, f, sp.k0), rtol=1e-12, atol=1e-12)
    plain = path_training_set(sp, n_samples=6, **kw)
    assert np.array_equal(path_training_set(sp, n_samples=6, path_errors=np.zeros((2, sp.end)), **kw).X, plain.X)
    assert np.array_equal(path_training_set(sp, n_samples=6, path_errors=np.zeros((0, sp.end)), **kw).X, plain.X)
    assert not np.allclose(path_training_set(sp, n_samples=6, path_errors=err, **kw).X, plain.X)


def test_drive_story_paths_dividing_the_batch(table1):
    x = np.sin(np.linspace(0, 20, 800))[None, :] * np.array([[8.0], [12.0]])
    alphas = np.array([0.1, 0.2, 0.3, 0.4])
    two = drive_story(x, k0=1.9e4, alpha=alphas, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=0.005, state=False)
    for b, a in enumerate(alphas):
        one = drive_story(x[b % 2], k0=1.9e4, alpha=a, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=0.005)
        assert np.array_equal(two.force[b], one.force[0])
    with pytest.raises(ValueError, match="divides 4"):
        drive_story(np.stack([x[0]] * 3), k0=1.9e4, alpha=alphas, p=2.0, dy=6.0, delta_eta=0.5, mass=17.5, dt=0.005)


@pytest.mark.parametrize("n", [-1, 65])
def test_path_errors_is_validated(n):
    with pytest.raises(InputError, match="path_errors"):
        TrainingConfig(path_errors=n)


def test_identify_with_path_errors(table1):
    """The option runs through the identification (two outer iterations: HLA's drift, then the
    reconstruction), records its time and changes the training, not the measured features."""
    meas = simulate_measurement(table1, window(paper_record("kocaeli-1999-dzc180"), 14.0, before_peak=4.0),
                                noise_rms=0.05, seed=1)

    def cfg(k):
        return IdentifyConfig(training=TrainingConfig(samples=60, n_segments=8, path_errors=k),
                              outer=OuterConfig(max_iterations=2, tol=1e-9), refine=RefineConfig(method="none"))

    plain, eiv = identify_clone(meas, cfg(0), cache_dir=""), identify_clone(meas, cfg(2), cache_dir="")
    assert "path_errors" in eiv.timings and "path_errors" not in plain.timings
    assert eiv.iterations == 2
    for name in ("alpha", "p", "dy", "delta_eta"):
        err = np.abs(getattr(eiv.paper_estimate, name) / getattr(table1, name) - 1)
        assert err.max() < 0.5, (name, err)
    def votes(res):
        return [[{k: v["votes"] for k, v in s.items()} for s in p["stories"]] for p in res.passes]

    assert votes(plain) != votes(eiv)


def test_failed_pseudo_measurements_are_left_out(table1, measured, monkeypatch):
    """A pseudo-measurement whose HLA fails (ValueError) is left out; none left: an empty bank."""
    pe = sys.modules[path_error_bank.__module__]
    meas, res, ground = measured
    real_hla = pe.hla
    calls = []

    def flaky(m, cfg):
        calls.append(1)
        if len(calls) == 2:
            raise ValueError("Initial guess is outside of provided bounds")
        return real_hla(m, cfg)

    monkeypatch.setattr(pe, "run_hla", flaky)
    kw = {"noise_rms": 0.10, "seed": 11, "reconstruct": False, "crossover_hz": 1.0, "hla_config": HLAConfig()}
    bank = path_error_bank(res, ground, table1, n=3, **kw)
    assert bank.shape[0] == 2
    monkeypatch.setattr(pe, "run_hla", lambda m, cfg: (_ for _ in ()).throw(ValueError("no")))
    assert path_error_bank(res, ground, table1, n=2, **kw).shape == (0,) + res.stories[0].drift.shape + (3,)
