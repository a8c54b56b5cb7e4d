"""hlaid.signal against scipy: the filters are forward-backward Butterworth designs, the Nyquist
rule is 0.45 x the sample rate, the double integration recovers a sine's displacement."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate
from scipy import signal as ss

from hlaid import signal as hs
from hlaid.measurement import Measurement, measured_ground

DT = 0.01
RNG = np.random.default_rng(0)
X = RNG.standard_normal((3000, 2))


def test_nyquist_rule():
    assert hs.max_corner(0.01) == pytest.approx(45.0)
    assert hs.cap_corner(20.0, 0.01) == 20.0
    assert hs.cap_corner(80.0, 0.01) == hs.max_corner(0.01)
    assert hs.max_corner(0.005) == 0.45 / 0.005  # the very number call sites used to write


@pytest.mark.parametrize("band", [(0.2, 20.0), (1.0, 40.0)])
def test_bandpass_is_sosfiltfilt_of_a_butterworth_band(band):
    sos = ss.butter(4, band, btype="bandpass", fs=1.0 / DT, output="sos")
    np.testing.assert_allclose(hs.bandpass(X, DT, band), ss.sosfiltfilt(sos, X, axis=0), rtol=0, atol=1e-10)


def test_lowpass_and_a_zero_low_corner_are_the_same_filter():
    sos = ss.butter(4, 10.0, btype="lowpass", fs=1.0 / DT, output="sos")
    ref = ss.sosfiltfilt(sos, X, axis=0)
    np.testing.assert_allclose(hs.lowpass(X, DT, 10.0), ref, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(hs.lowpass(X, DT, 10.0), hs.bandpass(X, DT, (0.0, 10.0)))


def test_axis_argument_filters_along_time_of_a_batch():
    batch = np.moveaxis(X, 0, 1)[None]  # (1, channel, time)
    np.testing.assert_allclose(hs.bandpass(batch, DT, (0.2, 20.0), axis=2)[0].T, hs.bandpass(X, DT, (0.2, 20.0)),
                               rtol=0, atol=1e-12)


def test_highpass_removes_only_the_mean_when_its_corner_is_zero():
    np.testing.assert_allclose(hs.highpass(X + 5.0, DT, (0.0, 20.0)), X - X.mean(axis=0), atol=1e-12)
    sos = ss.butter(4, 0.5, btype="highpass", fs=1.0 / DT, output="sos")
    np.testing.assert_allclose(hs.highpass(X, DT, (0.5, 20.0)), ss.sosfiltfilt(sos, X, axis=0), rtol=0, atol=1e-10)
    assert hs.butter_sos((0.0, 20.0), DT, kind="highpass") is None


def test_a_corner_above_the_design_guard_is_designed_at_the_guard():
    guard = hs.DESIGN_GUARD * 0.5 / DT
    np.testing.assert_array_equal(hs.butter_sos((0.0, 1000.0), DT), hs.butter_sos((0.0, guard), DT))


def test_integrate_twice_recovers_a_displacement_pulse():
    t = np.arange(6000) * DT
    w = 2 * np.pi * 1.5
    disp_true = np.sin(w * t) * np.exp(-(((t - 30.0) / 8.0) ** 2))  # starts and ends at rest
    acc = np.gradient(np.gradient(disp_true, DT), DT)[:, None]
    vel, disp = hs.integrate_twice(acc, DT, (0.2, 20.0))
    assert np.max(np.abs(disp[:, 0] - disp_true)) < 0.02
    assert np.max(np.abs(vel[:, 0] - np.gradient(disp_true, DT))) < 0.02 * w
    trap = integrate.cumulative_trapezoid(acc, dx=DT, axis=0, initial=0.0)
    np.testing.assert_array_equal(vel, hs.highpass(trap, DT, (0.2, 20.0)))


def test_measured_ground_is_the_low_passed_ground():
    g = np.sin(np.arange(2000) * 0.05) * 1000.0 + RNG.standard_normal(2000) * 50.0
    meas = Measurement(dt=DT, ground_acc=g, floor_acc=g[:, None])
    gm = measured_ground(meas, 20.0)
    assert gm.dt == DT and gm.name == "measured"
    np.testing.assert_array_equal(gm.acc, hs.lowpass(g, DT, 20.0))
