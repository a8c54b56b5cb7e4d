"""Intensity measures: hlaid's batched response spectrum against scipy's exact linear solver.

``scipy.signal.lsim`` with ``interp=True`` integrates a linear system exactly for an input that
is linear between samples (first-order hold) -- the same assumption as the Nigam-Jennings
recursion, written independently -- so the two must agree to round-off.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from hlaid.errors import InputError
from hlaid.ida import INTENSITY_MEASURES, intensity, response_spectrum
from hlaid.model import Building
from hlaid.motions import GroundMotion, load_builtin

G = 9806.65


def _lsim_psa(gm: GroundMotion, T: float, xi: float, refine: int = 1) -> float:
    """Exact response at the samples refined ``refine`` times (the input interpolated linearly)."""
    w = 2 * np.pi / T
    sys = signal.lti([[0.0, 1.0], [-w * w, -2 * xi * w]], [[0.0], [-1.0]], [[1.0, 0.0]], [[0.0]])
    t = np.arange((gm.npts - 1) * refine + 1) * gm.dt / refine
    _, y, _ = signal.lsim(sys, np.interp(t, gm.time, gm.acc), t, interp=True)
    return w * w * np.abs(y).max()


@pytest.fixture(scope="module")
def motions():
    # different dt (0.01, 0.005, 0.02) and lengths, batched together
    return [load_builtin(n) for n in ("elcentro-1940-ns", "kocaeli-1999-dzc180", "landers-1992-yer270")]


@pytest.mark.parametrize("xi", [0.0, 0.05, 1.5])
def test_spectrum_matches_scipy_exact_solution(motions, xi):
    """At the record's samples: equal to round-off."""
    periods = [0.05, 0.5, 3.0]
    S = response_spectrum(motions, periods, damping=xi, points_per_period=None)
    assert S.shape == (3, 3)
    ref = np.array([[_lsim_psa(gm, T, xi) for T in periods] for gm in motions])
    assert np.max(np.abs(S / ref - 1)) < 1e-8


def test_spectrum_finds_the_peak_between_samples(motions):
    """Default: the true peak of the continuous response (lsim on a 50x finer grid), within
    the 0.05 % bound; the peak at the samples alone can be well below it at short periods."""
    gm, T = motions[2], 0.1  # dt = 0.02 s = T / 5
    ref = _lsim_psa(gm, T, 0.05, refine=50)
    assert response_spectrum(gm, [T])[0, 0] == pytest.approx(ref, rel=5e-4)
    assert response_spectrum(gm, [T], points_per_period=None)[0, 0] < (1 - 1e-3) * ref


def test_batch_equals_one_by_one_and_period_zero_is_pga(motions):
    periods = [0.0, 0.3, 1.2]
    S = response_spectrum(motions, periods)
    for i, gm in enumerate(motions):
        assert np.array_equal(S[i], response_spectrum(gm, periods)[0])
        assert S[i, 0] == gm.pga


def test_intensity_measures(motions):
    b = Building(mass=[10.0, 8.0], k0=[4000.0, 3000.0], alpha=[0.1, 0.1], p=[2.0, 2.0], dy=[10.0, 8.0],
                 delta_eta=[0.0, 0.0])
    T1 = b.periods()[0]
    sa = intensity(motions, "sa_t1", building=b)
    assert np.allclose(sa, response_spectrum(motions, [T1])[:, 0] / G, rtol=1e-14)
    assert np.allclose(intensity(motions, "pga"), [m.pga_g for m in motions])
    # an IM is proportional to the scale factor (so one multiplication reaches a level)
    assert np.allclose(intensity([m.scaled(2.5) for m in motions], "sa_t1", building=b), 2.5 * sa, rtol=1e-12)
    assert np.allclose(intensity(motions, "sa_t1", period=T1), sa, rtol=1e-14)
    assert set(INTENSITY_MEASURES) >= {"sa_t1", "pga"}


def test_intensity_errors(motions):
    with pytest.raises(InputError, match="unknown intensity measure 'sa'; expected one of pga, sa_t1"):
        intensity(motions, "sa")
    with pytest.raises(InputError, match="needs a building"):
        intensity(motions, "sa_t1")
    with pytest.raises(InputError, match="periods must be non-negative"):
        response_spectrum(motions, [-1.0])
