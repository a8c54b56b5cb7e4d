"""The linear peer of the validation study (``hlaid.studies.validation.linear_peer``).

- Against an independent reference: a *linear* Table 1 building simulated by hlaid's own
  integrator; mdof's peer identified on one record predicts another record of it with
  R > 0.999 per floor and peak drifts within 1 % from one event and through decimation (R > 0.99,
  5 % from two joined events); a building 30 % stiffer is told apart
  (R < 0.5, peak drifts 30 % too large).
- The grid search chooses by the self-fit and reports the oracle apart.
- Without mdof: the settings refuse bad values, several events are joined so that each weighs
  alike and no model memory spans two of them, and decimation keeps the compared band.

mdof is an optional study dependency that CI does not install (its own dependencies bring
a 36 MB OpenSees build, pandas, plotly): its tests are skipped without it, in CI too.
"""

from __future__ import annotations

import dataclasses
import importlib.util

import numpy as np
import pytest
from conftest import paper_record, requires, window

from hlaid.errors import InputError
from hlaid.hla import HLAConfig
from hlaid.measurement import Measurement
from hlaid.studies.validation.linear_peer import (
    GAP_S,
    LinearPeer,
    PeerSettings,
    compare_peer,
    joined_record,
    max_decimation,
    peer_cases,
)
from hlaid.synthetic import simulate_measurement

needs_mdof = requires(importlib.util.find_spec("mdof") is not None, "mdof not installed (pip install 'hlaid[peer]')")
BAND = (0.3, 20.0)
HLA = HLAConfig()
HLA_BAND = dataclasses.replace(HLA, preprocess=dataclasses.replace(HLA.preprocess, band_hz=BAND))


def _linear(building, **changes):
    return building.replace(alpha=np.ones(building.n_stories), **changes)


def _event(building, record: str, seconds: float = 30.0) -> Measurement:
    """Noise-free floor accelerations and displacements relative to the ground at 100 Hz."""
    m = simulate_measurement(building, window(paper_record(record), seconds), rate_hz=100.0, noise_rms=0.0)
    assert m.truth is not None
    return dataclasses.replace(m, floor_disp=m.truth.disp)


@pytest.fixture(scope="module")
def events(table1):
    lin = _linear(table1)
    return {name: _event(lin, name) for name in ("elcentro-1940-ns", "kocaeli-1999-dzc180", "northridge-1994-mul009")}


def test_settings_refuse_bad_values():
    with pytest.raises(InputError, match="n4sid.*okid-era, srim"):
        PeerSettings(method="n4sid")
    for bad in ({"order": 0}, {"horizon": 1}, {"decimation": 1.5}, {"rcond": 1.0}):
        with pytest.raises(InputError, match=next(iter(bad))):
            PeerSettings(**bad)


def test_joined_events_weigh_alike_and_never_touch():
    """An event and the same event 10 times stronger become the same block; the zeros between
    them outlast the model's memory."""
    rng = np.random.default_rng(1)
    u = rng.standard_normal(3000)
    y = np.stack([np.convolve(u, rng.standard_normal(20))[:3000] for _ in range(2)], axis=1)
    dt, horizon, dec = 0.01, 400, 2
    uj, yj = joined_record([(u, y), (10 * u, 10 * y)], dt, horizon, dec)
    gap = uj.size - 2 * u.size
    assert gap >= max(GAP_S / dt, 2 * horizon * dec)
    np.testing.assert_allclose(uj[:3000], uj[-3000:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(yj[:3000], yj[-3000:], rtol=1e-12, atol=1e-12)
    assert np.all(uj[3000:3000 + gap] == 0) and np.all(yj[3000:3000 + gap] == 0)
    assert np.sqrt(np.mean(uj[1000:2000] ** 2)) == pytest.approx(1.0, rel=0.1)  # unit RMS input, taper aside
    same_u, same_y = joined_record([(u, y)], dt, horizon, dec)
    assert same_u is u and same_y is y


@pytest.mark.parametrize(("dt", "band", "expected"), [(1 / 256, (0.3, 2.5), 46), (0.02, (1.0, 20.0), 1),
                                                      (0.02, (1.0, 50.0), 1)])
def test_max_decimation_keeps_the_band(dt, band, expected):
    d = max_decimation(dt, band)
    assert d == expected
    if d > 1:
        assert 0.45 / (dt * d) >= band[1] > 0.45 / (dt * (d + 1))


def test_unfitted_peer_refuses_to_predict(events):
    with pytest.raises(InputError, match="not fitted"):
        LinearPeer(PeerSettings()).predict(events["elcentro-1940-ns"])


@needs_mdof
@pytest.mark.parametrize("settings", [PeerSettings(method="srim", order=6, horizon=30),
                                      PeerSettings(method="okid-era", order=6, horizon=100, rcond=1e-6),
                                      PeerSettings(method="srim", order=6, horizon=30, decimation=2)],
                         ids=["srim", "okid-era", "srim-decimated"])
def test_peer_of_a_linear_building_predicts_another_record(events, settings):
    peer = LinearPeer(settings, hla_config=HLA).fit([events["elcentro-1940-ns"]])
    p = compare_peer(peer, events["kocaeli-1999-dzc180"], HLA, BAND)
    assert np.all(p.r > 0.999), p.r
    assert np.all(np.abs(p.peak_drift_error) < 0.01), p.peak_drift_error


@needs_mdof
def test_peer_from_joined_events_predicts_a_third(events):
    peer = LinearPeer(PeerSettings(method="srim", order=6, horizon=30), hla_config=HLA)
    peer.fit([events["elcentro-1940-ns"], events["northridge-1994-mul009"]])
    p = compare_peer(peer, events["kocaeli-1999-dzc180"], HLA, BAND)
    assert np.all(p.r > 0.99), p.r
    assert np.all(np.abs(p.peak_drift_error) < 0.05), p.peak_drift_error


@needs_mdof
def test_peer_of_another_building_is_told_apart(table1, events):
    stiff = _event(_linear(table1, k0=1.3 * table1.k0), "kocaeli-1999-dzc180")
    peer = LinearPeer(PeerSettings(method="srim", order=6, horizon=30), hla_config=HLA)
    p = compare_peer(peer.fit([events["elcentro-1940-ns"]]), stiff, HLA, BAND)
    assert np.all(p.r < 0.5) and np.all(p.peak_drift_error > 0.3), (p.r, p.peak_drift_error)


@needs_mdof
def test_grid_chooses_by_self_fit_and_reports_the_oracle(events):
    """One mode (order 2) cannot replay a 3-story building as well as three (order 6): the
    self-fit picks order 6, which is also the oracle on the prediction."""
    grid = [PeerSettings(method="srim", order=2, horizon=30), PeerSettings(method="srim", order=6, horizon=30)]
    train = [("a", events["elcentro-1940-ns"])]
    (case,) = peer_cases("t1", train, [("b", events["kocaeli-1999-dzc180"])], grid, HLA_BAND)
    assert case.chosen.order == 6 and case.oracle.order == 6
    assert case.self_r > 0.99 and case.prediction.r_mean == case.oracle_prediction.r_mean > 0.99
    assert case.n_grid == 2 and case.n_failed == 0 and case.identified_on == ("a",)


@needs_mdof
def test_events_of_different_rates_are_refused(events):
    other = dataclasses.replace(events["kocaeli-1999-dzc180"], dt=0.02)
    with pytest.raises(InputError, match="events differ"):
        LinearPeer(PeerSettings(method="srim", order=6, horizon=30)).fit([events["elcentro-1940-ns"], other])


def test_script_refuses_unknown_structures():
    import sys

    from conftest import REPO

    sys.path.insert(0, str(REPO / "scripts"))
    try:
        import study_linear_peer
    finally:
        sys.path.pop(0)
    assert study_linear_peer.main(["--structures", "nowhere", "--out", "/nonexistent/never"]) == 2
