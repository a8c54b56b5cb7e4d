"""Two questions at a recorded event, two names: the clone replaying the event's own motion
(P(collapse | this motion), its residual drift beside the measured) and the fragility at the
event's intensity (another record of it); a run of several events of one building."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.ida.basis import DecisionBasis, decision_basis
from hlaid.ida.config import IDAConfig
from hlaid.ida.ownevent import (
    AT_INTENSITY,
    OWN_MOTION,
    OwnMotionCheck,
    check_of_demands,
    fragility_at_im,
    measured_drift_ratios,
)
from hlaid.loss.ownmotion import own_motion_check
from hlaid.motions import GroundMotion, load_builtin
from hlaid.synthetic import simulate_measurement


@pytest.fixture(scope="module")
def recorded(table1):
    """Table 1 (3 m stories) under 10 s of El Centro at 0.62 g: its measurement."""
    b = table1.replace(height=np.full(3, 3000.0))
    quake = load_builtin("elcentro-1940-ns").scaled_to_pga(0.62)
    quake = GroundMotion(dt=quake.dt, acc=quake.acc[: int(10 / quake.dt)], name="elcentro")
    meas = simulate_measurement(b, quake, rate_hz=100.0, noise_rms=0.0, seed=0)
    return b, dataclasses.replace(meas, floor_disp=np.asarray(meas.truth.disp))  # as a record with displacements


def test_the_two_figures_have_two_names():
    assert "own motion" in OWN_MOTION and "another record" in AT_INTENSITY
    assert fragility_at_im(1.0, 1.0, 0.4) == pytest.approx(0.5) and fragility_at_im(None, 1.0, 0.4) is None
    c = OwnMotionCheck(name="s4", in_clone=False, p_collapse=0.0, n_runs=1, peak=(0.05, 0.06, 0.04),
                       residual=(0.004, 0.001, 0.0), measured_peak=(0.049, 0.06, 0.056),
                       measured_residual=(0.0028, 0.0013, 0.0004), heights_assumed=True)
    assert c.text().startswith("s4: P(collapse | the event's own motion)") and "assumed story heights" in c.text()
    assert c.residual_error == pytest.approx((0.0012, -0.0003, -0.0004)) and c.residual_met is True
    d = c.to_dict()
    assert d["p_collapse_own_motion"] == 0.0 and "p_collapse" not in d
    b = DecisionBasis(own_motion=(c,))
    assert DecisionBasis.from_dict(b.to_dict()).own_motion == (c,)
    far = OwnMotionCheck(name="s4", in_clone=False, p_collapse=0.2, residual=(0.02,), measured_residual=(0.002,))
    flags = DecisionBasis(own_motion=(far,)).flags()
    assert any("collapses in 20% of its replays of s4's own motion" in f for f in flags)
    assert any("residual drift ratio +1.80% off the measured" in f for f in flags)


def test_the_replay_of_its_own_building_meets_the_measured_residual(recorded):
    """The clone that IS the building replays the record: it survives, its peak and residual drift
    ratios are the record's (the measured residual: the last second's mean less the first's)."""
    b, meas = recorded
    clone = Clone(building=b)
    measured = measured_drift_ratios(meas, b.height)
    c = own_motion_check(clone, "elcentro", meas.ground_motion(), measured=measured,
                         ida_config=IDAConfig(collapse="none"))
    assert c.p_collapse == 0.0 and c.n_runs == 1
    np.testing.assert_allclose(c.peak, measured[0], rtol=0.05)
    assert c.residual_met is True


def test_check_of_demands_reads_the_ensemble_fraction():
    class D:  # demands of 4 members, one collapsed
        n_realizations = 4
        collapsed = np.array([False, True, False, False])
        pid = np.full((4, 2), 0.02)
        rid = np.array([[0.001, 0.0], [np.nan, np.nan], [0.003, 0.0], [0.002, 0.0]])
    c = check_of_demands("e", None, D(), measured=(np.array([0.02, 0.02]), np.array([0.002, 0.0])))
    assert c.p_collapse == 0.25 and c.n_runs == 4 and c.residual_median == pytest.approx((0.002, 0.0))


def test_a_basis_carries_both_questions(recorded):
    b, _ = recorded
    c = OwnMotionCheck(name="e", in_clone=True, p_collapse=0.0)
    basis = decision_basis(Clone(building=b), own_motion=(c,))
    assert any(line.strip().startswith("e: P(collapse | the event's own motion)") for line in basis.lines())
    assert basis.to_dict()["own_motion"][0]["p_collapse_own_motion"] == 0.0


def test_a_run_of_several_events_decides_at_the_last_or_a_named_one():
    from hlaid.run.config import MeasurementSource

    m = MeasurementSource(file=["runs/s1.tsv.gz", "runs/s2.tsv.gz", "runs/s3.tsv.gz"])
    assert m.files == ["runs/s1.tsv.gz", "runs/s2.tsv.gz", "runs/s3.tsv.gz"]
    assert MeasurementSource(file=m.file, decide_at="s2").files == ["runs/s1.tsv.gz", "runs/s2.tsv.gz"]
    assert MeasurementSource(file="one.npz").files == ["one.npz"]
    with pytest.raises(InputError, match="decide_at names no file"):
        MeasurementSource(file=m.file, decide_at="s9")
    with pytest.raises(InputError, match="measurement.file"):
        MeasurementSource(file=[])


def test_survived_is_measured_and_extrapolation_is_beyond_the_fitted_range(table1):
    """The drift the building survived is the measured one (the capacity's evidence); a demand is
    extrapolated only beyond the range the clone was fitted on (the records or its replay of them,
    whichever is larger): the clone's replay of its own record is no extrapolation."""
    from hlaid.model.state import BuildingState

    b = table1.replace(height=np.full(3, 1000.0))
    z = np.zeros(3)
    state = BuildingState(drift=z, z=z, work=z, peak_positive=np.array([60.0, 10.0, 10.0]), peak_negative=z)
    c = Clone(building=b, events=({"name": "e", "peak_drift": [50.0, 10.0, 10.0]},), state=state)
    basis = decision_basis(c, demand_ratio=0.062)  # beyond 1.1 x the 5 % measured, within 1.1 x the 6 % replayed
    assert basis.survived_ratio == pytest.approx(0.05) and basis.fitted_ratio == pytest.approx(0.06)
    assert basis.extrapolated is False
    assert decision_basis(c, demand_ratio=0.067).extrapolated is True
    assert "largest drift survived (measured): 50.0, 10.0, 10.0 mm" in "\n".join(basis.lines())


def test_a_fleet_with_history_clones_each_building_from_its_events_so_far(table1, tmp_path):
    """``history: true``: a building's unit at its event k reads events 1..k (the clone of them,
    as identify takes several records); its digest covers the earlier events' files."""
    from hlaid.fleet import load_fleet_config, make_jobs
    from hlaid.fleet.task import load_unit_measurements

    for k, pga in enumerate((0.1, 0.2, 0.3)):
        q = load_builtin("elcentro-1940-ns").scaled_to_pga(pga)
        q = GroundMotion(dt=q.dt, acc=q.acc[: int(4 / q.dt)], name=f"e{k + 1}")
        simulate_measurement(table1, q, rate_hz=100.0, noise_rms=0.0, seed=k).save(tmp_path / f"e{k + 1}.npz")
    text = ("records: builtin-suite\nHISTORYbuildings:\n  - name: B1\n    measurements:\n"
            + "".join(f"      ev{k}: {{file: e{k}.npz}}\n" for k in (1, 2, 3)))
    (tmp_path / "a.yaml").write_text(text.replace("HISTORY", ""))
    (tmp_path / "h.yaml").write_text(text.replace("HISTORY", "history: true\n"))
    alone = make_jobs(load_fleet_config(tmp_path / "a.yaml"), tmp_path, "sha", "fake")
    jobs = make_jobs(load_fleet_config(tmp_path / "h.yaml"), tmp_path, "sha", "fake")
    assert [len(j.earlier) for j in alone] == [0, 0, 0] and [len(j.earlier) for j in jobs] == [0, 1, 2]
    series = load_unit_measurements(jobs[2])
    assert [m.name for m in series] == ["B1@ev1", "B1@ev2", "B1@ev3"]
    assert jobs[0].digest == alone[0].digest != jobs[1].digest
    (tmp_path / "e1.npz").write_bytes((tmp_path / "e1.npz").read_bytes()[:-64])
    again = make_jobs(load_fleet_config(tmp_path / "h.yaml"), tmp_path, "sha", "fake")
    assert again[2].digest != jobs[2].digest  # an earlier event's file changed
