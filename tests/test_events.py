"""Clones carried through a building's successive events: the state, the joint fit over several
records, sequential updating and the prediction of the next event, each against an independent
reference or the truth of simulated data."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import paper_record, window
from reference_systems import ShearBuildingRef

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.events.identify import identify_clone
from hlaid.events.predict import predict_event
from hlaid.events.start import resolve_start
from hlaid.events.update import update_clone
from hlaid.identify import IdentifyConfig
from hlaid.joint.fit import map_refine, posterior_uncertainty
from hlaid.joint.priors import PRIORS, get_prior
from hlaid.joint.series import effective_samples
from hlaid.joint.vector import PriorVector, from_units, prior_of_clone, to_units
from hlaid.measurement import check_series
from hlaid.model.state import BuildingState, settle_time
from hlaid.record import FitReplay
from hlaid.simulate import simulate_response
from hlaid.synthetic import simulate_events, simulate_measurement

PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")


@pytest.fixture(scope="module")
def pieces():
    """Three short pieces of real records at growing intensity (the second and third start in
    the state the earlier ones left)."""
    return [window(paper_record(name), 8.0).scaled(f) for name, f in
            (("elcentro-1940-ns", 0.5), ("kocaeli-1999-dzc180", 0.8), ("northridge-1994-mul009", 1.0))]


def _ref(b) -> ShearBuildingRef:
    return ShearBuildingRef(mass=b.mass, k0=b.k0, alpha=b.alpha, p=b.p, dy=b.dy, delta_eta=b.delta_eta,
                             ratio=b.damping.ratio)


def test_state_of_a_vector_and_back(table1):
    y = np.array([1.0, 3.0, 4.5, 9.0, -2.0, 0.5, 0.3, -0.2, 0.1, 120.0, 80.0, 10.0])
    st = BuildingState.from_vector(y, peaks=(np.array([5.0, 6, 7]), np.array([4.0, 3, 2])), events=("a",))
    np.testing.assert_allclose(st.drift, [1.0, 2.0, 1.5])
    v = st.vector()
    np.testing.assert_allclose(v[:3], y[:3])
    np.testing.assert_allclose(v[3:6], 0.0)  # at rest
    np.testing.assert_allclose(v[6:], y[6:])
    np.testing.assert_allclose(st.vector(collapse=True)[12:], [5, 6, 7, 4, 3, 2])
    # eta and ke by the paper's eq 7-8 and 11, written out here
    eps = (1 - table1.alpha) * (table1.k0 / table1.mass) * st.work * 1e-6
    eta = 1 + table1.delta_eta * eps
    np.testing.assert_allclose(st.eta(table1), eta, rtol=1e-12)
    np.testing.assert_allclose(st.elastic_stiffness(table1), table1.alpha * table1.k0
                               + (1 - table1.alpha) * table1.k0 / eta, rtol=1e-12)
    assert BuildingState.from_dict(st.to_dict()).to_dict() == st.to_dict()
    with pytest.raises(InputError, match="state.z"):
        BuildingState(drift=np.zeros(3), z=np.zeros(2), work=np.zeros(3), peak_positive=np.zeros(3),
                      peak_negative=np.zeros(3))


def test_the_state_carried_into_the_next_event_is_the_reference_solvers(table1, pieces):
    """The second event of :func:`simulate_events` starts from the state the first left: solving
    it with scipy's DOP853 (tests/reference_systems.py, the story law written again) from that
    state gives the same drift, hysteretic displacement and degradation (to 2e-4 of their range: the
    simulator's RK4 against DOP853 at 1e-9)."""
    meas, states = simulate_events(table1, pieces[:2], noise_rms=0.0)
    assert states[0].work.max() > 0 and np.abs(states[0].drift).max() > 0.05  # it yielded and moved
    ref = _ref(table1).solve(pieces[1].acc, pieces[1].dt, y0=states[0].vector(), rtol=1e-9, atol=1e-9)
    n = table1.n_stories
    truth = meas[1].truth
    drift = ref[:, :n] - np.pad(ref[:, :n], ((0, 0), (1, 0)))[:, :-1]
    np.testing.assert_allclose(truth.drift, drift, atol=2e-4 * np.ptp(drift))
    np.testing.assert_allclose(truth.z, ref[:, 2 * n:3 * n], atol=2e-4 * np.ptp(ref[:, 2 * n:3 * n]))
    eta_ref = 1 + table1.delta_eta * (1 - table1.alpha) * (table1.k0 / table1.mass) * ref[:, 3 * n:] * 1e-6
    np.testing.assert_allclose(truth.eta, eta_ref, rtol=1e-5)
    assert np.all(truth.eta[0] > 1.0)  # it starts degraded


def test_effective_samples():
    rng = np.random.default_rng(0)
    white = rng.standard_normal((4000, 2))
    assert 0.8 * white.size < effective_samples(white) <= white.size
    t = np.arange(4000) * 0.01
    tone = np.sin(2 * np.pi * 1.3 * t)[:, None] * np.ones((1, 3)) + 1e-3 * rng.standard_normal((4000, 3))
    assert effective_samples(tone) < 20  # one sinusoid in three channels: a handful, not 12000


def test_prior_units_round_trip(table1):
    u, lz = to_units(table1)
    back = from_units(table1, u, lz)
    for name in PARAMS:
        np.testing.assert_allclose(getattr(back, name), getattr(table1, name), rtol=1e-10, err_msg=name)
    assert back.damping.ratio == pytest.approx(table1.damping.ratio)
    with pytest.raises(InputError, match="'rc-frame', 'steel-moment-frame', 'generic'"):
        get_prior("masonry")
    for prior in PRIORS.values():  # every system names its sources
        assert prior.sources and 0 < prior.alpha.median < 0.95 and prior.p.median > 1


def test_joint_fit_recovers_the_truth_from_two_events(table1, pieces):
    """Noise-free, two events with the state carried: one set of parameters from 5-15 % off
    comes back to the truth within 1 %, and the state it leaves matches the true one."""
    meas, states = simulate_events(table1, pieces[:2], noise_rms=0.0)
    start = table1.replace(k0=table1.k0 * 1.05, alpha=table1.alpha * 1.1, p=table1.p * 0.9, dy=table1.dy * 1.1,
                           delta_eta=table1.delta_eta * 0.85)
    fit = map_refine(start, meas, system=PRIORS["generic"], damping=False, ground_noise="ignore")
    for name in PARAMS:
        np.testing.assert_allclose(getattr(fit.building, name), getattr(table1, name), rtol=0.01, err_msg=name)
    np.testing.assert_allclose(fit.states[-1].work, states[-1].work, rtol=0.02)
    assert np.all(fit.informed() > 0.9)  # the data, not the prior, set every parameter


def test_joint_posterior_as_the_clones_uncertainty(table1, pieces):
    """The Laplace posterior maps exactly onto the clone's parameters (dy through Cy), and back
    onto the prior of an update."""
    meas, _ = simulate_events(table1, pieces[:1], noise_rms=0.05, seed=3)
    fit = map_refine(table1, meas, system=PRIORS["steel-moment-frame"], damping=True, ground_noise="ignore",
                     max_iterations=8)
    unc = posterior_uncertainty(fit)
    vals = unc.values(unc.centre)
    b = fit.building
    for (name, i), v in zip(unc.slots, vals):
        expect = b.damping.ratio if name == "damping" else getattr(b, name)[i]
        assert v == pytest.approx(expect, rel=1e-9), (name, i)
    prior = prior_of_clone(unc, b, PriorVector(b, damping=True), PRIORS["generic"])
    np.testing.assert_allclose(prior.mean, fit.result.x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(prior.chol @ prior.chol.T, fit.covariance, rtol=1e-6, atol=1e-12)


def test_update_agrees_with_the_joint_fit(table1, pieces):
    """One event then an update with the second agrees with the joint fit of both (10 % noise):
    the 15 parameters' differences inside their joint 90 % interval (Bonferroni: each within
    ``2.71 sqrt(s_joint^2 + s_update^2)`` in the posterior's transformed units), the median well
    inside one standard deviation."""
    cfg = IdentifyConfig(system="generic", refine=dataclasses.replace(IdentifyConfig().refine,
                                                                      method="least_squares", max_iterations=15))
    meas, _ = simulate_events(table1, pieces[:2], noise_rms=0.10, seed=7)
    start = table1.replace(alpha=table1.alpha * 1.1, dy=table1.dy * 0.9)
    joint = map_refine(start, meas, system=PRIORS["generic"], damping=False, ground_noise="ignore",
                       max_iterations=15)
    first = map_refine(start, meas[:1], system=PRIORS["generic"], damping=False, ground_noise="ignore",
                       max_iterations=15)
    clone = Clone(building=first.building, uncertainty=posterior_uncertainty(first), state=first.states[-1],
                  system="generic", events=({"name": "one"},))
    upd = update_clone(clone, meas[1], cfg).clone
    uj, uu = posterior_uncertainty(joint), upd.uncertainty
    assert uj.slots == uu.slots and uj.transform == uu.transform
    z = np.abs(uj.centre - uu.centre) / np.sqrt(uj.std**2 + uu.std**2)
    assert np.all(z < 2.71) and np.median(z) < 1.0, dict(zip(uj.names, z.round(2)))
    assert [e.name for e in upd.events] == ["one", meas[1].name]
    assert upd.state is not None and upd.state.events[-1] == meas[1].name
    assert upd.events[-1].start == "carried"  # the damage was carried: the event says so
    assert resolve_start(upd, "auto").state is not None


def test_an_update_finds_a_building_that_recovered(table1, pieces):
    """The second event recorded on a building that recovered in between (simulated from rest):
    the update explains it better undamaged and its clone predicts from rest (start 'auto')."""
    cfg = IdentifyConfig(system="generic", refine=dataclasses.replace(IdentifyConfig().refine,
                                                                      method="least_squares", max_iterations=15))
    first, _ = simulate_events(table1, pieces[2:], noise_rms=0.05, seed=8)
    fit = map_refine(table1, first, system=PRIORS["generic"], damping=False, ground_noise="ignore",
                     max_iterations=15)
    assert np.all(fit.states[-1].eta(fit.building) > 1.15)  # the first event degraded every story
    clone = Clone(building=fit.building, uncertainty=posterior_uncertainty(fit), state=fit.states[-1],
                  system="generic", events=({"name": "one"},))
    second = simulate_measurement(table1, pieces[1], noise_rms=0.05, seed=9)  # from rest: recovered
    upd = update_clone(clone, second, cfg).clone
    assert upd.events[-1].start == "undamaged" and resolve_start(upd, "auto").state is None
    assert resolve_start(upd, "carried").state is not None


def test_an_elastic_record_gives_a_clone_from_the_prior(table1, pieces):
    """A record that leaves the building elastic: stiffness from the data, the loop's shape from
    the structural system, flagged as such (the paper's method alone refuses it)."""
    meas = simulate_measurement(table1, pieces[0].scaled(0.15), noise_rms=0.02, seed=1)
    res = identify_clone(meas, IdentifyConfig(system="steel-moment-frame"), cache_dir="")
    c = res.clone
    np.testing.assert_allclose(c.building.k0, table1.k0, rtol=0.1)
    by = {(f.name, f.story): f for f in c.parameters or ()}
    assert all(by[("alpha", i)].source == "prior" for i in (1, 2, 3))
    assert all(by[("k0", i)].source == "data" for i in (1, 2, 3))
    assert c.system == "steel-moment-frame" and c.state is not None and len(c.events) == 1


def test_clone_files_keep_the_state_and_read_older_versions(table1, tmp_path):
    st = BuildingState(drift=np.array([0.1, -0.2, 0.3]), z=np.array([1.0, 2, 3]), work=np.array([10.0, 20, 30]),
                       peak_positive=np.ones(3), peak_negative=2 * np.ones(3), events=("e1", "e2"))
    c = Clone(building=table1, system="steel-moment-frame", events=({"name": "e1"}, {"name": "e2"}), state=st)
    path = c.save(tmp_path / "c.json")
    back = Clone.load(path)
    assert back.system == "steel-moment-frame" and back.state.to_dict() == st.to_dict()
    np.testing.assert_allclose(resolve_start(back, "carried").vector(), st.vector())
    assert resolve_start(back, "undamaged").vector() is None
    d = c.to_dict()
    for key in ("system", "events", "state", "identification", "settings"):
        d.pop(key)
    old = Clone.from_dict({**d, "version": 2})
    assert old.state is None and resolve_start(old, "auto").vector() is None
    with pytest.raises(InputError, match="start: carried needs a clone that carries"):
        resolve_start(old, "carried")
    with pytest.raises(InputError, match="unknown field 'system'"):
        Clone.from_dict({**c.to_dict(), "version": 2})
    bad = c.to_dict()
    bad["state"]["z"] = [1.0, 2.0]
    with pytest.raises(InputError, match="state.z"):
        Clone.from_dict(bad)


def test_prediction_from_the_carried_state(table1, pieces):
    """The true building, left in its true state, predicts the third event's true response
    (R 1, peak drifts within 1 %: the replay's ground is low-passed at the band's corner);
    started undamaged it does not."""
    meas, states = simulate_events(table1, pieces, noise_rms=0.0)
    c = Clone(building=table1, state=states[1])
    carried = predict_event(c, meas[2], band_hz=(0.2, 15.0))
    undamaged = predict_event(c, meas[2], band_hz=(0.2, 15.0), start="undamaged")
    assert carried.start == "carried" and undamaged.start == "undamaged"
    assert np.all(carried.r_true > 0.99999)
    np.testing.assert_allclose(carried.peak_drift_error, 0.0, atol=0.01)  # the ground low-passed at 15 Hz
    assert np.max(np.abs(undamaged.peak_drift_error)) > 10 * np.max(np.abs(carried.peak_drift_error))
    d = carried.to_dict()
    assert d["r_mean"] == pytest.approx(np.mean(carried.r)) and d["start"] == "carried"


def test_the_predictive_band_holds_the_measurement(table1, pieces):
    """A clone of one noisy event predicts the next with a band (parameter draws and its own
    misfit) that holds most of the measured response, and more than the draws alone."""
    meas, states = simulate_events(table1, pieces[:2], noise_rms=0.05, seed=5)
    fit = map_refine(table1, meas[:1], system=PRIORS["generic"], damping=False, ground_noise="ignore",
                     max_iterations=10)
    own = predict_event(Clone(building=fit.building), meas[0])  # its self-replay, in HLA's band
    c = Clone(building=fit.building, uncertainty=posterior_uncertainty(fit), state=fit.states[-1],
              fit_replays=(FitReplay(name=None, r_measured=tuple(own.r.tolist())),))
    p = predict_event(c, meas[1], n_ensemble=20)
    draws = predict_event(c, meas[1], n_ensemble=20, misfit=0.0)
    assert p.band is not None and draws.band is not None
    assert np.all(p.band.lower <= p.band.upper) and np.all(p.band.coverage >= draws.band.coverage)
    assert np.mean(p.band.coverage) > 0.85, p.band.coverage
    assert np.all(p.band.width < 0.5), p.band.width  # a narrow band, not one that covers anything


def test_events_of_another_building_are_refused(table1, pieces):
    meas, _ = simulate_events(table1, pieces[:2], noise_rms=0.0)
    other = dataclasses.replace(meas[1], floor_acc=meas[1].floor_acc[:, :2], mass=meas[1].mass[:2], truth=None,
                                source="other.npz")
    with pytest.raises(InputError, match="other.npz: 2 floor channels"):
        check_series([meas[0], other])
    heavier = dataclasses.replace(meas[1], mass=meas[1].mass * 2, source="heavy.npz")
    with pytest.raises(InputError, match="heavy.npz: its floor masses differ"):
        check_series([meas[0], heavier])
    early = [dataclasses.replace(meas[0], recorded="2020-05-01T10:00:00Z"),
             dataclasses.replace(meas[1], recorded="2019-01-01T00:00:00Z", source="b.npz")]
    with pytest.raises(InputError, match="b.npz: recorded 2019-01-01T00:00:00Z, not after"):
        check_series(early)
    with pytest.raises(InputError, match="2 floor channels, but the clone has 3 stories"):
        predict_event(Clone(building=table1), other)


def test_simulated_events_carry_their_damage(table1, pieces):
    """The state after each event is the end of one continuous history: replaying the events
    from rest one after the other with the simulator gives the same states."""
    _, states = simulate_events(table1, pieces, noise_rms=0.0)
    assert np.all(np.diff([s.work.sum() for s in states]) > 0)  # damage only accumulates
    y = None
    for gm, st in zip(pieces, states):
        r = simulate_response(table1, gm.resampled(200.0), y0=y, free_vibration=settle_time(table1),
                              outputs="peaks")
        y = np.array(r.final_state[0])
        y[3:6] = 0.0
        np.testing.assert_allclose(y[6:], st.vector()[6:], rtol=1e-9, atol=1e-12)


def test_cli_identify_predict_update(table1, pieces, tmp_path, capsys):
    """The event commands end to end on weak (elastic) events: identify from two, predict the
    third from the carried state, add it with update."""
    import json

    from hlaid.cli.app import main

    meas, _ = simulate_events(table1, [p.scaled(0.15) for p in pieces], noise_rms=0.02, seed=4)
    files = [str(m.save(tmp_path / f"e{k + 1}.npz")) for k, m in enumerate(meas)]
    cfg = tmp_path / "id.yaml"
    cfg.write_text("system: steel-moment-frame\nrefine: {method: least_squares, max_iterations: 10}\n")
    c1, c2, pred = tmp_path / "c12.json", tmp_path / "c123.json", tmp_path / "pred"
    assert main(["identify", *files[:2], "-o", str(c1), "--config", str(cfg), "--no-cache", "-q"]) == 0
    assert main(["predict", str(c1), files[2], "-o", str(pred), "--ensemble", "5", "-q"]) == 0
    p = json.loads((pred / "prediction.json").read_text())
    rule = Clone.load(c1).start_rule  # how the clone of e1 predicted e2 chose the start
    assert rule is not None and rule.n == 1 and p["start"] == rule.choice
    assert len(p["r"]) == 3 and min(p["r"]) > 0.9
    assert 0.0 <= p["coverage_mean"] <= 1.0 and (pred / "prediction.png").is_file()
    assert main(["update", str(c1), files[2], "-o", str(c2), "--config", str(cfg), "-q"]) == 0
    c = Clone.load(c2)
    assert [e.name for e in c.events] == ["e1", "e2", "e3"] and c.state is not None  # named by their files
    assert c.state.events[-1] == "e3"
    capsys.readouterr()
