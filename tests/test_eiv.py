"""The replay refinement's errors-in-variables weighting (``refine.ground_noise: whiten``):
the linear ground transfer against the simulator, the whitening against the inverse
covariance computed directly, the option's validation and its optimum on noise-free data."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.errors import InputError
from hlaid.identify import RefineConfig, refine_replay
from hlaid.identify.eiv import ground_transfer, lowpass_gain, whiten
from hlaid.motions import GroundMotion
from hlaid.signal import lowpass
from hlaid.simulate import simulate_response
from hlaid.synthetic import simulate_measurement


@pytest.mark.parametrize("pdelta", [False, True])
def test_ground_transfer_is_the_linear_buildings(table1, pdelta):
    """h(w) times the ground's spectrum gives the simulated absolute floor accelerations of a
    building that stays elastic (dy far above its drift), P-Delta with or without."""
    b = table1.replace(dy=table1.dy * 1e4, delta_eta=table1.delta_eta * 0.0, height=np.full(3, 3000.0), pdelta=pdelta)
    dt, n = 0.005, 8000
    g = np.random.default_rng(1).standard_normal(n) * 100.0
    g[:500] = g[-1500:] = 0.0  # quiet ends: the response dies out before the (circular) end
    g = lowpass(g, dt, 20.0)
    acc = simulate_response(b, GroundMotion(dt=dt, acc=g), substeps=4, outputs="acc").acc[0]
    pred = np.fft.irfft(ground_transfer(b, np.fft.rfftfreq(n, dt)) * np.fft.rfft(g)[:, None], n=n, axis=0)
    assert np.all(np.std(acc - pred, axis=0) < 0.01 * np.std(acc, axis=0))
    if pdelta:  # the geometric stiffness softens the building: a visibly different transfer
        h0 = ground_transfer(b.replace(pdelta=False), np.array([1.0, 2.0]))
        assert not np.allclose(h0, ground_transfer(b, np.array([1.0, 2.0])), rtol=1e-3)


def test_ground_transfer_limits(table1):
    """The floors follow the ground at w -> 0 and decouple from it far above the modes."""
    h = ground_transfer(table1, np.array([1e-6, 500.0]))
    np.testing.assert_allclose(h[0], 1.0, atol=1e-8)
    assert np.all(np.abs(h[1]) < 0.2)


def test_lowpass_gain_is_the_filters(table1):
    """The gain of :func:`hlaid.signal.lowpass` (forward-backward) at the rfft frequencies."""
    dt, n = 0.005, 4096
    x = np.zeros(n)
    x[n // 2] = 1.0
    measured = np.abs(np.fft.rfft(lowpass(x, dt, 20.0)))
    np.testing.assert_allclose(lowpass_gain(n, dt, 20.0), measured, atol=1e-6)


@pytest.mark.parametrize("n", [400, 401])
def test_whiten_gives_the_inverse_covariance_quadratic_form(n):
    """|whiten(r)|^2 = sum_w r(w)^H Sigma(w)^-1 r(w) (Parseval weights), Sigma = diag(s^2) + a a^H
    with a = s v, solved directly per frequency; and the identity without ground noise."""
    rng = np.random.default_rng(3)
    nf = 3
    res = rng.standard_normal((n, nf))
    m = n // 2 + 1
    v = rng.standard_normal((m, nf)) + 1j * rng.standard_normal((m, nf))
    v[0] = v[0].real  # the DC (and an even length's Nyquist) bins of a real signal are real
    if n % 2 == 0:
        v[-1] = v[-1].real
    s = np.array([0.5, 1.0, 2.0])
    R = np.fft.rfft(res, axis=0)
    Sigma = np.eye(nf)[None] * s**2 + (s * v)[:, :, None] * np.conj(s * v)[:, None, :]
    q = np.real(np.einsum("ki,ki->k", np.conj(R), np.linalg.solve(Sigma, R[..., None])[..., 0]))
    w = np.full(m, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    expected = np.sum(w * q) / n * np.mean(s) ** 2
    assert np.sum(whiten(res, v, s) ** 2) == pytest.approx(expected, rel=1e-10)
    np.testing.assert_allclose(whiten(res, np.zeros((m, nf)), np.ones(nf)), res, atol=1e-12)


def test_ground_noise_setting_is_checked(table1):
    with pytest.raises(ValueError, match="ground_noise"):
        RefineConfig(ground_noise="model")
    meas = simulate_measurement(table1, window(paper_record("elcentro-1940-ns"), 4.0), noise_rms=0.0)
    with pytest.raises(InputError, match="ground_noise"):
        refine_replay(table1, meas, ground_noise="model")


def test_whitened_refinement_recovers_noise_free_parameters(table1):
    """Noise-free, the whitened criterion has its optimum at the truth too."""
    meas = simulate_measurement(table1, window(paper_record("kocaeli-1999-dzc180"), 14.0, before_peak=4.0),
                                noise_rms=0.0)
    start = table1.replace(k0=table1.k0 * 1.03, alpha=table1.alpha + 0.02, p=table1.p * 0.9,
                           dy=table1.dy * 1.06, delta_eta=table1.delta_eta * 1.1)
    r = refine_replay(start, meas, ground_noise="whiten")
    assert r.cost_final < 1e-3 * r.cost_initial
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_allclose(getattr(r.building, name), getattr(table1, name), rtol=0.01, err_msg=name)
