"""The band a record holds, the clone judged in it, and a second Rayleigh ratio for the higher
modes: the band chooser against records of known content and noise floor, the two-ratio damping
against the modal solution, and the record of a clone's full replay of its own events."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import paper_record, window
from scipy import signal as ss
from scipy.integrate import solve_ivp

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.events.predict import predict_event
from hlaid.events.replay import own_replay, summary_line
from hlaid.identify.auto import BROAD_BAND_HZ, records_band
from hlaid.model import Damping
from hlaid.motions import GroundMotion
from hlaid.record import EventRecord
from hlaid.signal import content_corner
from hlaid.simulate import simulate_response
from hlaid.synthetic import simulate_measurement


def _band_limited(fc: float, noise_db: float, fs: float = 200.0, seconds: float = 120.0, seed: int = 0):
    """White noise low-passed at ``fc`` (order 12, so it falls 72 dB an octave) plus white sensor
    noise whose spectral level is ``noise_db`` below the content's."""
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    x = ss.sosfilt(ss.butter(12, fc / (0.5 * fs), output="sos"), rng.standard_normal(n))
    return x + 10 ** (noise_db / 20.0) * rng.standard_normal(n), 1.0 / fs


@pytest.mark.parametrize("fc", [5.0, 12.0, 30.0])
def test_the_corner_follows_the_content_above_the_noise_floor(fc):
    """Content low-passed at fc over a noise floor 30 dB below it: the corner is where the content
    falls to 10 dB above the floor, (10^2)^(1/24) fc = 1.21 fc by the filter's slope."""
    x, dt = _band_limited(fc, -30.0)
    assert content_corner(x, dt) == pytest.approx(1.21 * fc, rel=0.08)


def test_a_higher_noise_floor_lowers_the_corner_and_a_clean_record_stops_at_its_dynamic_range():
    fc = 10.0
    noisy, dt = _band_limited(fc, -15.0)
    clean, _ = _band_limited(fc, -200.0)
    # 10 dB above a floor 15 dB down: (10^0.5)^(1/24) fc; no floor: 40 dB below the peak, (10^4)^(1/24) fc
    assert content_corner(noisy, dt) == pytest.approx(10 ** (0.5 / 24) * fc, rel=0.05)
    assert content_corner(clean, dt) == pytest.approx(10 ** (4 / 24) * fc, rel=0.08)
    assert content_corner(noisy, dt) < content_corner(clean, dt)


def test_a_spectral_line_or_pure_noise_holds_no_band():
    x, dt = _band_limited(5.0, -40.0)
    t = np.arange(x.size) * dt
    hum = x + 0.05 * np.sin(2 * np.pi * 60.0 * t)  # mains hum: one line far above the floor
    assert content_corner(hum, dt) == pytest.approx(content_corner(x, dt), rel=0.02)
    white = np.random.default_rng(1).standard_normal(20_000)
    assert content_corner(white, dt) == 0.0
    assert content_corner(np.zeros(1000), dt) == 0.0


def test_records_band_of_simulated_events(table1):
    """A record of the paper's building (200 Hz, sensor noise 2 % of each channel's RMS) holds
    its three modes (1.3-5.2 Hz): its band reaches above the third; its low corner is 0.1 Hz, or
    two periods of a shorter record (15 s: 0.14 Hz)."""
    meas = simulate_measurement(table1, window(paper_record("elcentro-1940-ns"), 15.0), noise_rms=0.02, seed=3)
    lo, hi = records_band(meas)
    f3 = 1.0 / table1.periods()[-1]
    assert lo == 0.14 and f3 < hi <= 0.45 * 200.0
    assert records_band(dataclasses.replace(meas, floor_acc=np.tile(meas.floor_acc, (3, 1)),
                                            ground_acc=np.tile(meas.ground_acc, 3)))[0] == BROAD_BAND_HZ[0]
    quiet = dataclasses.replace(meas, floor_acc=np.random.default_rng(0).standard_normal(meas.floor_acc.shape))
    assert records_band(quiet) == BROAD_BAND_HZ  # nothing above the noise: the broad band


def _modal_ratios(b) -> np.ndarray:
    """Each mode's damping ratio of the building's C: phi' C phi / (2 w phi' M phi)."""
    M, K, C = np.diag(b.mass), b.stiffness_matrix(), b.damping_matrix()
    lam, phi = np.linalg.eig(np.linalg.solve(M, K))
    order = np.argsort(lam)
    w, phi = np.sqrt(lam[order]), phi[:, order]
    return np.array([phi[:, k] @ C @ phi[:, k] / (2 * w[k] * phi[:, k] @ M @ phi[:, k]) for k in range(len(w))])


def test_two_rayleigh_ratios_damp_their_modes(table1):
    b = table1.replace(damping=Damping(ratio=0.02, modes=(1, 3), ratio2=0.08))
    z = _modal_ratios(b)
    np.testing.assert_allclose(z[[0, 2]], [0.02, 0.08], rtol=1e-9)
    assert 0.02 < z[1] < 0.08  # Rayleigh: between them in between
    same = _modal_ratios(table1.replace(damping=Damping(ratio=0.05, modes=(1, 2), ratio2=0.05)))
    np.testing.assert_allclose(same, _modal_ratios(table1), rtol=1e-12)  # ratio2 = ratio: plain Rayleigh
    assert Damping(ratio=0.05).to_dict() == {"kind": "rayleigh", "ratio": 0.05, "modes": [1, 2]}  # files unchanged
    assert Damping(**Damping(ratio=0.02, ratio2=0.07).to_dict()).ratio2 == 0.07
    with pytest.raises(InputError, match="ratio2"):
        Damping(kind="stiffness", ratio=0.05, ratio2=0.1)


def test_the_replay_of_two_ratio_damping_is_the_modal_solution(table1):
    """Free vibration of an elastic clone (dy far above its drift) from its third mode's shape:
    the simulator against scipy's solution of M x'' + C x' + K x = 0 with C from the two
    ratios (solved here, not by hlaid), and the third mode decays at 8 %."""
    b = table1.replace(dy=np.full(3, 1e5), alpha=np.full(3, 0.5), delta_eta=np.zeros(3),
                       damping=Damping(ratio=0.02, modes=(1, 3), ratio2=0.08))
    M, K = np.diag(b.mass), b.stiffness_matrix()
    lam, phi = np.linalg.eig(np.linalg.solve(M, K))
    w = np.sqrt(np.sort(lam))
    shape = phi[:, np.argmax(lam)] / np.max(np.abs(phi[:, np.argmax(lam)]))
    A = np.array([[1 / (2 * w[0]), w[0] / 2], [1 / (2 * w[2]), w[2] / 2]])
    a0, a1 = np.linalg.solve(A, [0.02, 0.08])
    C = a0 * M + a1 * K
    dt, n = 0.002, 1000
    quiet = GroundMotion(dt=dt, acc=np.zeros(n))
    u0 = 10.0 * shape
    y0 = np.concatenate([u0, np.zeros(3), np.diff(u0, prepend=0.0), np.zeros(3)])  # z = drift: elastic
    sim = simulate_response(b, quiet, y0=y0[None], substeps=4)
    t = np.arange(n) * dt
    ref = solve_ivp(lambda _, s: np.concatenate([s[3:], -np.linalg.solve(M, C @ s[3:] + K @ s[:3])]),
                    (0, t[-1]), np.concatenate([u0, np.zeros(3)]), t_eval=t, rtol=1e-10, atol=1e-10)
    got = np.asarray(sim.disp)[0, :n]
    np.testing.assert_allclose(got, ref.y[:3].T, atol=1e-3 * 10.0)
    env = np.abs(got @ (M @ shape)) / (shape @ M @ shape)
    peaks = ss.find_peaks(env)[0]
    zeta = np.log(env[peaks[0]] / env[peaks[4]]) / (4 * 2 * np.pi / np.sqrt(1 - 0.08**2)) * 2
    assert zeta == pytest.approx(0.08, rel=0.05)


def test_the_prediction_names_its_bands_and_the_replay_record_round_trips(table1, tmp_path):
    """The clone equal to the building replays its event in the records' band with no error;
    a softer one misses; the record goes into the clone file and comes back."""
    meas = simulate_measurement(table1, window(paper_record("elcentro-1940-ns"), 10.0), noise_rms=0.0, seed=1)
    meas = dataclasses.replace(meas, floor_disp=meas.truth.disp)
    p = predict_event(Clone(building=table1), meas, start="undamaged")
    assert p.band_name == "records" and p.band_hz == records_band(meas)
    assert p.peak_drift_error == pytest.approx(np.zeros(3), abs=0.01) and np.all(p.drift_r > 0.999)
    assert p.residual_drift_error is not None and np.all(np.abs(p.residual_drift_error) < 0.05)
    d = p.to_dict()
    assert d["band"] == "records" and "hla" in d["other_bands"] and d["other_bands"]["hla"]["meaning"]
    exact = own_replay(table1, meas)
    soft = own_replay(table1.replace(k0=table1.k0 * 0.6), meas)
    assert max(abs(v) for v in exact.peak_drift_error) < 0.01
    assert max(abs(v) for v in soft.peak_drift_error) > 0.1
    events = (EventRecord(name="quake", replay=exact), EventRecord(name="other", replay=soft))
    c = Clone(building=table1, events=events)
    c.save(tmp_path / "c.json")
    back = Clone.load(tmp_path / "c.json")
    err = np.asarray(soft.peak_drift_error)
    j = int(np.argmax(np.abs(err)))
    assert back.own_replay_miss() == (pytest.approx(err[j]), j, "other", tuple(soft.band_hz))
    line = summary_line(back.events)
    assert line is not None and "quake" in line and f"{100 * err[j]:+.0f}" in line


def test_measured_drift_ratios_of_floor_displacements():
    """Peak and residual drift ratios of a measurement's floor displacements, story by story."""
    from types import SimpleNamespace

    from hlaid.cli.loss import measured_drift_ratios

    t = np.arange(0, 10, 0.01)
    drift = np.column_stack([10 * np.sin(2 * np.pi * t) + (t > 5) * 3.0, -20 * np.sin(2 * np.pi * t), 0 * t])
    meas = SimpleNamespace(floor_disp=np.cumsum(drift, axis=1), dt=0.01)
    peak, residual = measured_drift_ratios(meas, [1000.0, 2000.0, 1000.0])
    np.testing.assert_allclose(peak, [13.0 / 1000, 20.0 / 2000, 0.0], rtol=1e-3)
    np.testing.assert_allclose(residual, [3.0 / 1000, 0.0, 0.0], atol=1e-5)
    assert measured_drift_ratios(SimpleNamespace(floor_disp=None, dt=0.01), [1000.0] * 3) is None
    assert measured_drift_ratios(meas, None) is None


def test_the_prior_vector_moves_masses_and_a_second_ratio_and_the_clone_keeps_them(table1, tmp_path):
    """With masses and a second Rayleigh ratio in the vector: the building comes back from its
    vector, the total mass is kept, the prior holds the masses equal and the clone file and the
    posterior's slots keep the second ratio."""
    from hlaid.joint.priors import PRIORS
    from hlaid.joint.vector import MASS_BETA, PriorVector, SystemPrior

    b = table1.replace(mass=np.full(3, 1.0 / 3.0), damping=Damping(ratio=0.03, ratio2=0.05))
    v = PriorVector(b, damping=True, masses=True)
    assert [s for s in v.slots if s[0] in ("damping", "damping2", "mass")] == [
        ("damping", -1), ("damping2", -1), ("mass", 0), ("mass", 1)]
    x = v.of(b).copy()
    x[-2:] = np.log([0.5, 0.25])  # m1 / m3, m2 / m3
    x[-3] = np.log(0.08)
    moved = v.building_at(x)
    np.testing.assert_allclose(moved.mass, np.array([0.5, 0.25, 1.0]) / 1.75, rtol=1e-12)
    assert moved.damping.ratio2 == pytest.approx(0.08) and moved.damping.ratio == pytest.approx(0.03)
    np.testing.assert_allclose(v.of(moved), x, atol=1e-9)
    np.testing.assert_allclose(_modal_ratios(moved)[:2], [0.03, 0.08], rtol=1e-9)
    prior = SystemPrior(PRIORS["steel-moment-frame"], v, b.k0)
    np.testing.assert_allclose(prior.residuals(x)[-2:], np.log([0.5, 0.25]) / MASS_BETA)
    assert len(v.clone_slots()[0]) == len(v.slots) - 2  # the masses are no clone slot
    c = Clone(building=moved)
    c.save(tmp_path / "c.json")
    assert Clone.load(tmp_path / "c.json").building.damping == moved.damping
