"""Decisions consistent with what the building did: the events a clone was identified from were
survived (the ensemble conditioned on them, the collapse law made consistent with the drifts
survived), every ensemble draw inside the model's bounds, and nothing not computed reported as 0."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import DATA, REPO, requires
from test_loss import needs_pelicun

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.events.evidence import event_motions, replay_events, survivors
from hlaid.events.identify import event_record
from hlaid.ida.assessment import member_preparer
from hlaid.ida.config import IDAConfig
from hlaid.ida.prepare import prepare_building
from hlaid.io import read
from hlaid.model import COLLAPSE_MODELS
from hlaid.model.capacity import capacity_posterior
from hlaid.model.collapse import accommodate
from hlaid.model.schema import STORY_BOUNDS
from hlaid.model.uncertainty import BOUNDS, ParameterUncertainty
from hlaid.motions import GroundMotion, load_builtin
from hlaid.synthetic import simulate_measurement
from hlaid.uncertainty.ensemble import clone_ensemble

STEEL = DATA / "structural_response" / "shake_table_3story_steel_mrf_fixedbase"


# ---------------------------------------------------------------------------- bounds
def test_the_uncertainty_bounds_are_the_buildings():
    for name in ("k0", "p", "dy", "delta_eta"):
        assert BOUNDS[name] == (STORY_BOUNDS[name].lo, STORY_BOUNDS[name].upper())
    assert BOUNDS["alpha"] == (0.0, 0.95)


def _wide_clone(building, sd=60.0):
    """A clone whose log-parameter standard deviations are absurd (exp(60) ~ 1e26): its draws
    would leave every bound unclipped."""
    slots = tuple((n, i) for i in range(building.n_stories) for n in ("k0", "alpha", "p", "dy", "delta_eta"))
    tr = tuple({"alpha": "logit", "p": "log1"}.get(n, "log") for n, _ in slots)
    unc = ParameterUncertainty(slots=slots, transform=tr, centre=np.zeros(len(slots)),
                               covariance=sd**2 * np.eye(len(slots)))
    return Clone(building=building, uncertainty=unc)


def test_every_draw_is_a_building_a_clone_file_may_hold(table1):
    """Draws of an absurdly wide posterior stay inside the bounds (before, a draw of delta_eta =
    1.3e8 made Building refuse the member and the command blame the clone file)."""
    c = _wide_clone(table1)
    members = clone_ensemble(c, 200, seed=3)
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        lo, hi = BOUNDS[name]
        v = np.array([getattr(b, name) for b in members])
        assert v.min() >= lo and v.max() <= hi, name
        assert v.max() == hi or name == "alpha"  # the clipping is exercised: some draws hit the upper bound
    lo, hi = np.array(list(c.uncertainty.interval(0.9).values())).T
    names = [n for n, _ in c.uncertainty.slots]
    assert all(BOUNDS[n][0] <= a <= b <= BOUNDS[n][1] for n, a, b in zip(names, lo, hi))


# ---------------------------------------------------------------------------- the collapse law
def test_a_capping_below_the_survived_drift_is_moved_to_it():
    law = COLLAPSE_MODELS["steel-mrf"]
    dy, h = np.array([10.0, 20.0, 5.0]), np.array([1000.0, 1000.0, 2000.0])
    survived = np.array([30.0, 60.0, 40.0])  # story 2: 6 % of its height, beyond 2 % + 2.5 %
    new, notes = accommodate(law, dy=dy, height=h, survived=survived)
    assert new.theta_p == pytest.approx(0.04)  # (60 - 20) / 1000
    assert new.theta_u - new.theta_p == pytest.approx(law.theta_u - law.theta_p)
    assert (new.theta_pc, new.kappa) == (law.theta_pc, law.kappa)
    cap = dy + new.theta_p * h
    assert np.all(cap >= survived - 1e-9) and cap[1] == pytest.approx(survived[1])
    assert len(notes) == 1 and "story 2" in notes[0] and "60.0 mm" in notes[0] and "1000 mm" in notes[0]
    same, none = accommodate(law, dy=dy, height=h, survived=np.array([10.0, 20.0, 5.0]))
    assert same is law and none == []
    wide, notes = accommodate(law, dy=np.array([70.0, 10.0, 10.0]), height=np.full(3, 1000.0))  # dy/h = 7 %
    assert wide.theta_u > 0.07 + wide.theta_p and "theta_u raised" in notes[0]
    with pytest.raises(InputError, match="beyond its height 1000 mm"):
        accommodate(law, dy=dy, height=np.full(3, 1000.0), survived=np.array([10.0, 1200.0, 5.0]))


def test_prepare_building_conditions_the_law_on_the_measured_drifts(table1):
    b = table1.replace(height=np.full(3, 3000.0))
    c = Clone(building=b, system="steel-moment-frame",
              events=({"name": "big one", "peak_drift": [150.0, 30.0, 20.0]},))  # 5 % in story 1
    prepared, notes = prepare_building(c)
    t = (150.0 - table1.dy[0]) / 3000.0
    assert prepared.collapse.theta_p > t  # never capping below a drift the story came through
    assert prepared.collapse.theta_p == pytest.approx(capacity_posterior(
        COLLAPSE_MODELS["steel-mrf"], dy=table1.dy, height=b.height, survived=[150.0, 30.0, 20.0]).quantile(0.5))
    assert any("without losing strength" in n for n in notes)
    plain, _ = prepare_building(dataclasses.replace(c, events=()))
    assert plain.collapse.theta_p == COLLAPSE_MODELS["steel-mrf"].theta_p
    # the clone's replay (its carried state) is no evidence: only the measured drifts are
    from hlaid.model.state import BuildingState
    z = np.zeros(3)
    replayed = dataclasses.replace(c, events=({"name": "small", "peak_drift": [1.0, 1.0, 1.0]},),
                                   state=BuildingState(drift=z, z=z, work=z, peak_positive=np.array([300.0, 1, 1]),
                                                       peak_negative=z))
    assert prepare_building(replayed)[0].collapse.theta_p == COLLAPSE_MODELS["steel-mrf"].theta_p
    # an ensemble member of large dy (dy/h + theta_p beyond theta_u) is prepared, not refused
    big = table1.replace(height=np.full(3, 100.0), dy=np.array([7.0, 9.0, 3.0]))
    member, notes = prepare_building(big, collapse="steel-mrf")
    assert member.collapse.theta_u > 0.09 + 0.025 and any("theta_u raised" in n for n in notes)


def test_a_clone_that_stayed_elastic_keeps_the_literature_law_and_its_fragility(table1):
    """No story beyond its yield drift in any event: the evidence says nothing, the building the IDA
    runs is the one without events, bit for bit, so its fragility is unchanged."""
    from hlaid.ida import run_ida

    b = table1.replace(height=np.full(3, 3000.0))
    elastic = Clone(building=b, system="steel-moment-frame",
                    events=({"name": "small", "peak_drift": (0.5 * np.asarray(table1.dy)).tolist()},))
    bare = dataclasses.replace(elastic, events=())
    pe, notes = prepare_building(elastic)
    pb, _ = prepare_building(bare)
    assert pe.collapse == pb.collapse == COLLAPSE_MODELS["steel-mrf"]
    assert not any("without losing strength" in n for n in notes)
    cfg = IDAConfig(levels=[1.0, 2.0, 4.0, 8.0], refine=False, bootstrap=0)
    recs = [load_builtin("elcentro-1940-ns"), load_builtin("kocaeli-1999-dzc180")]
    fe, fb = (run_ida(c, recs, cfg).summary(n_boot=0)["collapse_fragility"] for c in (elastic, bare))
    assert fe == fb


def test_the_capacity_posterior_is_the_truncated_lognormal():
    """Against scipy's truncated normal of ln theta_p: median, 90 % interval, the prior
    probability of surviving; no evidence (no story beyond yield) leaves the law unchanged."""
    from scipy import stats

    law = COLLAPSE_MODELS["steel-mrf"]
    dy, h = np.array([10.0, 20.0, 5.0]), np.array([1000.0, 1000.0, 2000.0])
    for survived in ([30.0, 60.0, 40.0], [12.0, 30.0, 9.0], [10.0, 95.0, 5.0]):
        post = capacity_posterior(law, dy=dy, height=h, survived=survived)
        t = float(np.max((np.array(survived) - dy) / h))
        a = (np.log(t) - np.log(law.theta_p)) / law.beta_p
        ref = stats.truncnorm(a, np.inf, loc=np.log(law.theta_p), scale=law.beta_p)
        assert post.threshold == pytest.approx(t)
        assert post.quantile(0.5) == pytest.approx(np.exp(ref.median()), rel=1e-9)
        assert post.interval(0.9) == pytest.approx(tuple(np.exp(ref.interval(0.9))), rel=1e-9)
        assert post.p_consistent == pytest.approx(stats.norm.sf(a), rel=1e-9)
        new = post.conditioned()
        assert new.theta_p > t and new.theta_u - new.theta_p == pytest.approx(law.theta_u - law.theta_p)
        again = capacity_posterior(new, dy=dy, height=h, survived=survived).conditioned()
        assert again.theta_p == new.theta_p  # conditioned once: the law in force is a point value
    far = capacity_posterior(law, dy=dy, height=h, survived=[10.0, 500.0, 5.0])  # 48 % plastic drift
    assert not far.consistent and "not assessed" in far.note()
    elastic = capacity_posterior(law, dy=dy, height=h, survived=[9.0, 15.0, 5.0])
    assert not elastic.informative and elastic.conditioned() is law
    with pytest.raises(InputError, match="beyond its height 1000 mm"):
        capacity_posterior(law, dy=dy, height=np.full(3, 1000.0), survived=[10.0, 1200.0, 5.0])


# ---------------------------------------------------------------------------- survival as evidence
@pytest.fixture(scope="module")
def event(table1, tmp_path_factory):
    """Table 1 (3 m stories) under El Centro at 0.62 g, saved and read back like a real record."""
    b = table1.replace(height=np.full(3, 3000.0))
    quake = load_builtin("elcentro-1940-ns").scaled_to_pga(0.62)
    quake = GroundMotion(dt=quake.dt, acc=quake.acc[: int(15 / quake.dt)], name="elcentro")
    meas = simulate_measurement(b, quake, rate_hz=100.0, noise_rms=0.02, seed=0)
    path = tmp_path_factory.mktemp("event") / "event.npz"
    meas.save(path)
    return b, read(path, "measurement"), path


def _clone_of(b, meas, sd=0.25):
    slots = tuple((n, i) for i in range(3) for n in ("k0", "dy"))
    centre = np.log([getattr(b, n)[i] for n, i in slots])
    unc = ParameterUncertainty(slots=slots, transform=("log",) * len(slots), centre=centre,
                               covariance=sd**2 * np.eye(len(slots)))
    return Clone(building=b, uncertainty=unc, events=(event_record(meas),))


def test_members_that_collapse_under_the_event_are_rejected(event):
    """With a drift limit just above the nominal clone's own peak, a wide posterior puts part of
    its draws beyond it under the event the building survived: those are rejected, every member
    kept survives the event, and the first draws are the plain ensemble's."""
    b, meas, _ = event
    c = _clone_of(b, meas)
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc), name="own")
    peak = replay_events([b], [own], drift_limit=1.0).peak[0]
    limit = float(np.max(peak / 3000.0)) * 1.15
    surv = survivors(c, 12, seed=4, motions=[own], drift_limit=limit)
    assert surv.nominal_survives is True and surv.events == (meas.name,)
    assert surv.n_rejected > 0 and len(surv.members) == 12 and surv.n_drawn == 12 + surv.n_rejected
    again = replay_events(list(surv.members), [own], drift_limit=limit)
    assert not again.collapsed.any()
    plain = clone_ensemble(c, surv.n_drawn, seed=4)
    bad = replay_events(plain, [own], drift_limit=limit).collapsed
    assert int(bad.sum()) == surv.n_rejected  # the same stream, each draw judged once
    kept = [m for m, x in zip(plain, bad) if not x]
    np.testing.assert_allclose([m.k0 for m in surv.members], [m.k0 for m in kept])
    assert any("rejected" in n for n in surv.notes) and surv.to_dict()["n_rejected"] == surv.n_rejected


def test_the_events_are_read_back_only_when_unchanged(event, tmp_path):
    b, meas, path = event
    c = _clone_of(b, meas)
    em = event_motions(c)
    assert em.missing == () and em.motions[0] is not None
    np.testing.assert_array_equal(em.motions[0].acc, meas.ground_acc)
    copy = tmp_path / "event.npz"
    simulate_measurement(b, load_builtin("elcentro-1940-ns").scaled_to_pga(0.3), rate_hz=100.0, seed=1).save(copy)
    moved = dataclasses.replace(c, events=(dataclasses.replace(c.events[0], source=str(copy)),))
    em = event_motions(moved)
    assert em.motions == (None,) and "changed since the clone was identified" in em.missing[0]
    em = event_motions(moved, [GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc))])  # passed in: matched
    assert em.missing == () and em.motions[0] is not None
    surv = survivors(dataclasses.replace(c, events=({"name": "lost", "source": str(tmp_path / "gone.npz")},)), 3)
    assert surv.nominal_survives is None and len(surv.members) == 3 and "not found" in surv.unchecked[0]


def test_a_survived_drift_at_the_drift_limit_is_refused(event):
    b, meas, _ = event
    c = dataclasses.replace(_clone_of(b, meas),
                            events=(dataclasses.replace(event_record(meas), peak_drift=(400.0, 20.0, 10.0)),))
    prep = member_preparer(IDAConfig(collapse="none"))
    with pytest.raises(InputError, match=r"survived drifts of 400\.0, 20\.0, 10\.0 mm .*13\.3% of its height 3000 mm"):
        survivors(c, 2, prepare=prep, drift_limit=0.10)


def test_the_assessment_reports_each_event_and_the_survival(event):
    from hlaid.ida import assess

    b, meas, _ = event
    c = dataclasses.replace(_clone_of(b, meas, sd=0.05), system="steel-moment-frame")
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc), name="own")
    recs = [load_builtin(n) for n in ("kobe-1995-nis000", "northridge-1994-mul009", "elcentro-1940-ns")]
    a = assess(c, recs, n_ensemble=3, ida_config=IDAConfig(n_levels=4, max_hunt=8, max_fill=3, tolerance=0.1),
               own_motion=own, seed=0, n_boot=3)
    assert [e["name"] for e in a.events] == [meas.name] and a.events[0]["im"] == pytest.approx(a.own_im)
    assert a.events[0]["p_collapse"] == pytest.approx(a.p_collapse)
    assert a.survival["nominal_survives"] is True and a.survival["n_members"] == 3 == a.n_ensemble


# ---------------------------------------------------------------------------- not assessed is not 0
@needs_pelicun
def test_losses_without_a_collapse_fragility_do_not_report_zero(event, tmp_path):
    from hlaid.loss import LossConfig, clone_demands
    from hlaid.loss.assess import loss_of_demand_file

    b, meas, _ = event
    d = clone_demands(Clone(building=b), GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc)))
    csv = d.write_csv(tmp_path / "demands.csv")
    s = loss_of_demand_file(csv, LossConfig(floor_area_m2=500.0), tmp_path / "loss")
    assert s["p_collapse"] is None and s["p_replacement"] is None and "not assessed" in s["notes"][0]
    s = loss_of_demand_file(csv, LossConfig(floor_area_m2=500.0), tmp_path / "loss2", collapse=(3.0, 0.4))
    assert s["p_collapse"] is not None and 0.0 <= s["p_collapse"] < 0.5


# ---------------------------------------------------------------------------- a real frame
@requires(STEEL.is_dir(), f"steel-frame data not found at {STEEL}", data=True)
@pytest.mark.slow  # one identification of a real record (about 2 minutes on 2 cores)
def test_the_steel_frame_clone_of_s4_is_consistent_with_what_the_frame_did(tmp_path):
    """gm152 s4, the documented settings with the steel-moment-frame system, story heights 1 m:
    every 90 % interval within a factor 100 (the prior's), the nominal clone survives s4 with the
    collapse law in force (its capping moved to the drift the frame survived), and the default
    ensembles of predict and demands run."""
    from hlaid.config import load_config
    from hlaid.events import identify_clone, predict_event
    from hlaid.identify import IdentifyConfig
    from hlaid.loss import clone_demands

    cfg = load_config(str(REPO / "configs" / "identify_steel_frame.yaml"), IdentifyConfig)
    cfg = dataclasses.replace(cfg, training=dataclasses.replace(cfg.training, samples=100))
    meas = read(STEEL / "filtered_fbgm152s4_denoised.tsv.gz", "measurement")
    c = identify_clone(meas, cfg, cache_dir=str(tmp_path / "cache")).clone
    assert c.uncertainty.method == "laplace-posterior"
    for name, (lo, hi) in c.uncertainty.interval(0.9).items():
        assert 0 < lo <= hi <= 100 * lo, name
    b, notes = prepare_building(c, heights=[1000.0] * 3)
    survived = c.survived_drift(measured_only=True)
    assert np.all(b.dy + b.collapse.theta_p * 1000.0 >= survived - 1e-6)
    own = GroundMotion(dt=meas.dt, acc=np.asarray(meas.ground_acc))
    surv = survivors(c, 20, prepare=member_preparer(IDAConfig(heights_mm=[1000.0] * 3,
                                                              collapse=b.collapse.to_dict())), motions=[own])
    assert surv.nominal_survives is True and len(surv.members) == 20
    p = predict_event(c, meas, band_hz=(0.3, 2.5), n_ensemble=20)
    assert p.band is not None and p.band.n_ensemble == 20
    d = clone_demands(c, own, n_ensemble=20, ida_config=IDAConfig(heights_mm=[1000.0] * 3))
    assert d.n_realisations == 20 and not d.collapsed.any()


def test_an_event_file_read_again_is_named_on_one_line(tmp_path):
    """A clone's event whose name and file carry a newline and a terminal escape: the note that
    says why it was not read again shows them escaped, on one line."""
    from hlaid.events.evidence import read_event
    from hlaid.record import EventRecord

    bad = tmp_path / "ev\n\x1b[31m.npz"
    bad.write_bytes(b"x")
    meas, why = read_event(EventRecord(name="e\n\x1b[2J", source=str(bad), sha256="0" * 64))
    assert meas is None and "\n" not in why and "\x1b" not in why
    assert "\\x0a" in why and "changed since the clone was identified" in why
