"""Measurements: simulated accelerometer records (noise statistics), NPZ/CSV round trips and
one-line errors for bad files."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import window

from hlaid.errors import InputError
from hlaid.io.native import read_native
from hlaid.measurement import TRUTH_FIELDS, Measurement
from hlaid.motions import load_builtin
from hlaid.simulate import simulate_response
from hlaid.synthetic import add_noise, simulate_measurement

SEEDS = (0, 1, 2, 3, 4)


@pytest.fixture(scope="module")
def elcentro():
    """El Centro N-S at 0.62 g (its own 100 Hz; simulate_measurement resamples to 200 Hz)."""
    return load_builtin("elcentro-1940-ns").scaled_to_pga(0.62)


@pytest.fixture(scope="module")
def noisy(table1, elcentro):
    return {seed: simulate_measurement(table1, elcentro, noise_rms=0.10, seed=seed) for seed in SEEDS}


def test_noise_std_is_noise_rms_times_channel_rms(table1, elcentro, noisy):
    """Per channel: std(noise) = 0.10 * RMS(channel), white, zero-mean, independent channels."""
    gm = elcentro.resampled(200.0)
    clean = simulate_response(table1, gm, substeps=4)
    ratios = []
    for m in noisy.values():
        assert m.dt == 0.005 and m.n_samples == gm.npts and m.noise_rms == 0.10
        signal = np.column_stack([gm.acc, clean.acc[0]])
        noise = np.column_stack([m.ground_acc, m.floor_acc]) - signal
        rms = np.sqrt(np.mean(signal**2, axis=0))
        ratios.append(noise.std(axis=0) / rms)
        n = noise.shape[0]
        assert (np.abs(noise.mean(axis=0)) < 5 * 0.10 * rms / np.sqrt(n)).all()  # zero mean (5 sigma)
        lag1 = [np.corrcoef(noise[1:, j], noise[:-1, j])[0, 1] for j in range(4)]
        assert np.abs(lag1).max() < 5 / np.sqrt(n)  # white
        cross = np.corrcoef(noise.T) - np.eye(4)
        assert np.abs(cross).max() < 5 / np.sqrt(n)  # channels independent
    ratios = np.array(ratios)  # (seed, channel); sampling error of one ratio ~ 0.1/sqrt(2 n) = 0.7%
    assert np.abs(ratios / 0.10 - 1).max() < 0.035, ratios
    assert np.abs(ratios.mean() / 0.10 - 1) < 0.01, ratios.mean()


def test_seeds_and_truth(table1, elcentro, noisy):
    again = simulate_measurement(table1, elcentro, noise_rms=0.10, seed=0)
    np.testing.assert_array_equal(again.floor_acc, noisy[0].floor_acc)
    assert not np.allclose(noisy[0].floor_acc, noisy[1].floor_acc)
    clean = simulate_measurement(table1, elcentro, noise_rms=0.0)
    r = simulate_response(table1, elcentro.resampled(200.0))
    np.testing.assert_array_equal(clean.floor_acc, r.acc[0])
    t = noisy[3].truth
    assert t.building is table1
    for k in TRUTH_FIELDS:
        np.testing.assert_array_equal(getattr(t, k), getattr(r, k)[0])
    np.testing.assert_array_equal(noisy[3].mass, table1.mass)
    with pytest.raises(InputError, match="noise_rms"):
        simulate_measurement(table1, elcentro, noise_rms=-0.1)


def test_add_noise_scales_each_column():
    rng = np.random.default_rng(0)
    x = np.column_stack([np.full(40000, 3.0), np.full(40000, -300.0)])
    noise = add_noise(x, 0.2, rng) - x
    np.testing.assert_allclose(noise.std(axis=0), [0.6, 60.0], rtol=0.02)


# ---------------------------------------------------------------------- round trips
def _assert_same(a: Measurement, b: Measurement):
    assert a.dt == b.dt and a.pdelta == b.pdelta and a.noise_rms == b.noise_rms
    for name in ("ground_acc", "floor_acc", "mass", "height", "floor_disp"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y)
    assert (a.truth is None) == (b.truth is None)
    if a.truth is not None:
        assert a.truth.building.to_dict() == b.truth.building.to_dict()
        for k in TRUTH_FIELDS:
            np.testing.assert_array_equal(getattr(a.truth, k), getattr(b.truth, k))


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_round_trip_simulated(tmp_path, table1, noisy, suffix):
    m = noisy[0]
    m2 = Measurement(dt=m.dt, ground_acc=m.ground_acc[:3000], floor_acc=m.floor_acc[:3000], mass=m.mass,
                     height=np.array([3000.0, 3000.0, 3500.0]), pdelta=False, noise_rms=m.noise_rms,
                     truth=type(m.truth)(building=table1, **{k: getattr(m.truth, k)[:3000] for k in TRUTH_FIELDS}))
    path = m2.save(tmp_path / f"meas{suffix}")
    back = read_native(path)
    _assert_same(m2, back)
    assert back.source == str(path) and back.name == "meas"


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_round_trip_real_layout(tmp_path, suffix):
    """No masses (mass-normalised analysis), measured floor displacements, no truth."""
    rng = np.random.default_rng(5)
    m = Measurement(dt=1 / 256, ground_acc=rng.normal(0, 500, 400), floor_acc=rng.normal(0, 900, (400, 2)),
                    floor_disp=rng.normal(0, 5, (400, 2)), source="lab")
    back = read_native(m.save(tmp_path / f"lab{suffix}"))
    _assert_same(m, back)
    assert back.mass is None and not back.mass_known and back.truth is None


def test_save_does_not_overwrite_without_force(tmp_path, noisy):
    p = tmp_path / "m.npz"
    noisy[0].save(p)
    before = p.read_bytes()
    with pytest.raises(InputError, match="already exists"):
        noisy[1].save(p, force=False)
    with pytest.raises(InputError, match="already exists"):  # the default
        noisy[1].save(p)
    assert p.read_bytes() == before
    assert [q.name for q in tmp_path.iterdir()] == ["m.npz"]  # no temporary file left behind


# ---------------------------------------------------------------------- bad input
_OK = {"dt": 0.01, "ground_acc": np.linspace(500.0, 1500.0, 100),
       "floor_acc": np.linspace(500.0, 1500.0, 200).reshape(100, 2)}


@pytest.mark.parametrize("change,match", [
    ({"dt": 0.0}, "dt = 0.0; expected a positive"),
    ({"floor_acc": np.ones((99, 2))}, "different lengths"),
    ({"ground_acc": np.ones((100, 2))}, "ground_acc has shape"),
    ({"ground_acc": np.r_[np.full(99, 1000.0), np.nan]}, "ground_acc has 1 NaN or inf samples"),
    ({"floor_acc": np.r_[np.full((99, 2), 1000.0), [[1.0, np.inf]]]}, "floor_acc has 1 NaN or inf"),
    ({"ground_acc": np.full(100, 0.1), "floor_acc": np.full((100, 2), 0.1)}, "check the units"),
    ({"ground_acc": np.full(100, 1e6), "floor_acc": np.full((100, 2), 1e6)}, "check the units"),
    ({"mass": [1.0, 2.0, 3.0]}, "mass has 3 values but there are 2 floor channels"),
    ({"mass": [1.0, -2.0]}, "mass must be positive"),
    ({"floor_disp": np.ones((100, 3))}, "floor_disp has shape"),
    ({"ground_acc": np.full(10, 1000.0), "floor_acc": np.full((10, 2), 1000.0)}, "record has 10 samples"),
])
def test_measurement_validation(change, match):
    with pytest.raises(InputError, match=match) as err:
        Measurement(**(_OK | change), source="rec.npz")
    assert str(err.value).startswith("rec.npz: ") and "\n" not in str(err.value)


def test_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_native(tmp_path / "none.npz")
    bad = tmp_path / "bad.npz"
    bad.write_text("not a zip")
    with pytest.raises(InputError, match="not a readable NPZ"):
        read_native(bad)
    partial = tmp_path / "partial.npz"
    np.savez(partial, dt=0.01, ground_acc=np.ones(100))
    with pytest.raises(InputError, match="missing field 'floor_acc'") as err:
        read_native(partial)
    assert str(err.value).startswith(str(partial))


@pytest.mark.parametrize("text,match", [
    ("# dt_s: 0.01\ntime_s,ground_acc\n0,1\n0.01,2\n", "must name ground_acc and floor_acc_1..n"),
    ("# dt_s: 0.01\nground_acc,floor_acc_1\n1,2\n3\n", "data row 2 has 1 values but the header names 2"),
    ("# dt_s: 0.01\nground_acc,floor_acc_1\n1,2\n3,x\n", "non-numeric value"),
    ("# dt_s: fast\nground_acc,floor_acc_1\n1,2\n3,4\n", "header 'dt_s' must be a comma-separated list"),
    ("ground_acc,floor_acc_1\n1,2\n3,4\n", "no '# dt_s:' header line"),
    ("# dt_s: 0.01\n# true_params: {oops\nground_acc,floor_acc_1,true_disp_1,true_drift_1,true_force_1,"
     "true_z_1,true_eta_1\n" + "1000,1,0,0,0,0,1\n" * 20, "true_params:' is not a valid building"),
])
def test_malformed_csv(tmp_path, text, match):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(InputError, match=match) as err:
        read_native(p)
    assert str(err.value).startswith(str(p) + ": ") and "\n" not in str(err.value)


def test_windowed_measurement_of_real_record(table1, records):
    """A measurement can be simulated from any GroundMotion (here a window at the paper's rate)."""
    gm = window(records["kocaeli-1999-dzc180"], 5.0)
    m = simulate_measurement(table1, gm, rate_hz=None, noise_rms=0.05, seed=9)
    assert m.dt == gm.dt and m.n_samples == gm.npts and m.n_floors == 3


def test_given_corners_checked_against_an_auto_default():
    """A run config's ``refine.band_hz`` given as corners, the setting's default being ``auto``:
    the corners are checked (the high one against 0.9 x Nyquist), not compared with the word."""
    from hlaid.measurement import check_band

    meas = Measurement(**_OK)
    check_band(meas, [0.3, 2.5], "identify.refine.band_hz", default="auto")  # within 45 Hz: passes
    with pytest.raises(InputError, match="high corner 48 Hz is above 45 Hz"):
        check_band(meas, [0.3, 48.0], "identify.refine.band_hz", default="auto")


def test_ground_motion_is_the_recorded_ground():
    acc = 1000.0 * np.sin(np.arange(200) * 0.1)  # mm/s^2
    meas = Measurement(dt=0.01, ground_acc=acc, floor_acc=np.column_stack([acc, acc]), source="runs/a.npz", name="a")
    gm = meas.ground_motion()
    assert (gm.dt, gm.name, gm.source) == (0.01, "a", "runs/a.npz")
    np.testing.assert_array_equal(gm.acc, meas.ground_acc)
    other = meas.ground_motion(name="recorded", source="x.npz")
    assert (other.name, other.source) == ("recorded", "x.npz")
    unnamed = Measurement(dt=0.01, ground_acc=acc, floor_acc=acc[:, None])
    assert unnamed.ground_motion().name == "measured"


def test_ground_motions_are_not_built_by_hand_from_a_measurement():
    """``Measurement.ground_motion`` is the one way (a filtered ground is built where it is filtered)."""
    root = Path(__file__).resolve().parents[1]
    by_hand = re.compile(r"GroundMotion\(dt=\w+\.dt, acc=np\.asarray\(\w+\.ground_acc\)")
    files = sorted([*(root / "hlaid").rglob("*.py"), *(root / "scripts").glob("*.py")])
    found = [f"{p.relative_to(root)}:{n}" for p in files
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if by_hand.search(line)]
    assert found == [], f"use Measurement.ground_motion: {found}"
