"""What a decision rests on: every command that turns a clone into a decision prints and stores
P(collapse) at the clone's recorded events and the flags of what the figure rests on (assumed
heights, extrapolation, survival contradicted, the clone's own replay error), each defined once
(:mod:`hlaid.ida.basis`)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from hlaid.cli import main
from hlaid.clone import Clone
from hlaid.events.identify import event_record
from hlaid.ida.basis import (
    EXTRAPOLATION_MARGIN,
    REPLAY_MISS_FLAG,
    AtEvent,
    DecisionBasis,
    decision_basis,
    p_collapse,
)
from hlaid.io import read
from hlaid.motions import GroundMotion, load_builtin
from hlaid.record import OwnReplay
from hlaid.synthetic import simulate_measurement

RECS = ["builtin:elcentro-1940-ns", "builtin:kocaeli-1999-dzc180"]


@pytest.fixture(scope="module")
def event(table1, tmp_path_factory):
    """Table 1 (3 m stories) under 10 s of El Centro at 0.62 g, saved and read back like a record;
    the clone of it (its own building) with the event recorded."""
    b = table1.replace(height=np.full(3, 3000.0))
    quake = load_builtin("elcentro-1940-ns").scaled_to_pga(0.62)
    quake = GroundMotion(dt=quake.dt, acc=quake.acc[: int(10 / quake.dt)], name="elcentro")
    meas = simulate_measurement(b, quake, rate_hz=100.0, noise_rms=0.02, seed=0)
    folder = tmp_path_factory.mktemp("event")
    path = folder / "event.npz"
    meas.save(path)
    meas = read(path, "measurement")
    u = np.asarray(meas.truth.disp, dtype=float)  # the drift the building went through (a simulation's truth)
    peak = np.max(np.abs(np.diff(np.concatenate([np.zeros((u.shape[0], 1)), u], axis=1), axis=1)), axis=0)
    clone = Clone(building=b, events=(dataclasses.replace(event_record(meas), peak_drift=tuple(peak.tolist())),))
    clone_path = folder / "clone.json"
    clone.save(clone_path)
    return clone, meas, clone_path


# ---------------------------------------------------------------------------- one definition each
def test_p_collapse_is_the_lognormal_fragility():
    assert p_collapse(1.0, 1.0, 0.4) == pytest.approx(0.5)
    from scipy.stats import norm

    assert p_collapse(2.0, 1.0, 0.4) == pytest.approx(norm.cdf(np.log(2.0) / 0.4), rel=1e-12)
    assert p_collapse(0.5, 1.2, 0.3) == pytest.approx(norm.cdf(np.log(0.5 / 1.2) / 0.3), rel=1e-12)
    assert p_collapse(0.0, 1.0, 0.4) == 0.0
    assert p_collapse(1.0, None, 0.4) is None


def test_survival_contradicted_at_half_and_said_with_what_to_do():
    b = DecisionBasis(events=(AtEvent("s4", 1.2, 0.574), AtEvent("s3", 0.8, 0.43)))
    assert [e.name for e in b.contradicted] == ["s4"]
    flags = b.flags()
    assert len(flags) == 1 and "P(collapse) 57% for another record of s4's intensity" in flags[0]
    assert "building survived" in flags[0]
    assert "check the story heights" in flags[0]
    assert b.to_dict()["survival_contradicted"] == ["s4"]


def test_extrapolation_keeps_the_margin(event):
    clone, _, _ = event
    worst = float(np.max(clone.survived_drift(measured_only=True) / 3000.0))
    inside = decision_basis(clone, demand_ratio=worst * 1.02)  # the clone's own event, 2 % above: not flagged
    assert inside.extrapolated is False and not inside.flags()
    beyond = decision_basis(clone, demand_ratio=worst * (EXTRAPOLATION_MARGIN + 0.05))
    assert beyond.extrapolated is True and "demands extrapolated" in beyond.flags()[0]
    assert beyond.to_dict()["survived_drift_ratio"] == pytest.approx(worst)


def test_the_replay_error_is_flagged_or_not_assessed(event):
    clone, _, _ = event
    b = decision_basis(clone)
    assert b.replay_miss is None and b.replay_flagged is None
    assert any("replay of its own events: not assessed" in line for line in b.lines())
    e = dataclasses.replace(clone.events[0], replay=OwnReplay((0.3, 10.0), (0.05, -0.22, 0.1), (0.9, 0.9, 0.9)))
    bad = decision_basis(dataclasses.replace(clone, events=(e,)))
    assert bad.replay_flagged is True and abs(bad.replay_miss[0]) > REPLAY_MISS_FLAG
    assert any("story 2's peak drift by -22%" in f and "identify again" in f for f in bad.flags())
    again = DecisionBasis.from_dict(json.loads(json.dumps(bad.to_dict())))
    assert again.flags() == bad.flags() and again.lines() == bad.lines()


def test_assumed_heights_are_flagged(event):
    clone, _, _ = event
    b = decision_basis(clone, heights=[3000.0] * 3, heights_assumed=True)
    assert any("story heights 3000, 3000, 3000 mm assumed" in f for f in b.flags())
    assert not any("assumed" in f for f in decision_basis(clone).flags())


# ---------------------------------------------------------------------------- the commands
def _basis_lines(err: str) -> list[str]:
    lines = err.splitlines()
    i = next(k for k, line in enumerate(lines) if line.endswith("what the decision rests on:"))
    return lines[i:i + 5]


@pytest.fixture(scope="module")
def ida_run(event, tmp_path_factory):
    """``hlaid ida`` of the event's clone (3 % drift limit, 2 built-in records): its folder and stderr."""
    import contextlib
    import io

    _, _, path = event
    out = tmp_path_factory.mktemp("ida") / "ida"
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rc = main(["ida", str(path), "--records", *RECS, "--levels", "1:6:1", "--drift-limit", "0.03",
                   "--no-refine", "--bootstrap", "0", "--no-plots", "-o", str(out)])
    assert rc == 0
    return out, err.getvalue()


def test_ida_prints_and_stores_p_collapse_at_the_recorded_event(event, ida_run):
    clone, meas, _ = event
    out, err = ida_run
    block = _basis_lines(err)
    assert "P(collapse | another record of the intensity of each event the building survived), the fragility at " \
           f"its IM: {meas.name} at" in block[1]
    s = json.loads((out / "summary.json").read_text())["basis"]
    assert [e["name"] for e in s["events"]] == [meas.name] and s["events"][0]["im"] > 0
    p = s["events"][0]["p_collapse"]
    assert p is not None and f"{p:.1%}" in block[1]
    assert s["survived_drift_mm"] == pytest.approx(clone.survived_drift(measured_only=True).tolist())
    own = s["own_motion"][0]  # the other question: the clone replaying the event's own motion
    assert own["name"] == meas.name and own["in_clone"] is True and own["p_collapse_own_motion"] == 0.0
    assert f"{meas.name}: P(collapse | the event's own motion)" in err
    assert s["replay_miss"] is None and s["heights_assumed"] is False
    assert "the collapse criterion 3% is 2.4 x the drift survived" in err
    assert "with no collapse law (collapse only beyond the 3% drift limit)" in err  # not "with its collapse law"


def test_demands_store_what_they_rest_on_beside_the_csv(event, tmp_path, capsys):
    clone, meas, path = event
    out = tmp_path / "d.csv"
    rc = main(["demands", str(path), "--motion", str(meas.source), "--heights", "3000,3000,3000", "-o", str(out)])
    assert rc == 0
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "d.csv.basis.json").read_text())
    assert s["extrapolated"] is False  # the clone's own event: its demand is the drift it survived
    assert s["heights_assumed"] is True and "story heights 3000, 3000, 3000 mm assumed" in err
    assert "not assessed (demands run no IDA" in err
    # the sidecar is the user's file next time: not replaced without --force
    assert main(["demands", str(path), "--motion", str(meas.source), "-o", str(tmp_path / "e.csv")]) == 0
    (tmp_path / "f.csv.basis.json").write_text("mine")
    assert main(["demands", str(path), "--motion", str(meas.source), "-o", str(tmp_path / "f.csv")]) == 2
    assert (tmp_path / "f.csv.basis.json").read_text() == "mine" and not (tmp_path / "f.csv").exists()


def test_loss_of_a_run_says_when_its_figure_contradicts_the_survival(event):
    """The run's P(collapse) at its events (here 57 % at the recorded one) travels into the losses'
    basis, flagged as in the run."""
    from hlaid.loss.assess import loss_basis

    clone, meas, _ = event
    b = loss_basis(clone, None, (1.0, 0.4), None, [{"name": meas.name, "im": 1.2, "p_collapse": 0.574,
                                                    "source": "IDA of the identified clone"}], False, None)
    assert any(f.startswith(f"the fragility gives P(collapse) 57% for another record of {meas.name}'s intensity "
                            "(1.2 g), an event the building survived")
               for f in b.flags())
    assert b.to_dict()["survival_contradicted"] == [meas.name]


def test_loss_takes_the_clones_own_collapse_fragility(event, ida_run, tmp_path, capsys):
    clone, meas, path = event
    ida, _ = ida_run
    csv = tmp_path / "d.csv"
    assert main(["demands", str(path), "--motion", str(meas.source), "-o", str(csv)]) == 0
    f = json.loads((ida / "summary.json").read_text())["collapse_fragility"]["capacities"]
    from hlaid.cli.loss import ida_fragility

    assert ida_fragility(str(ida), csv) == (pytest.approx(f["median_g"]), pytest.approx(f["beta"]))
    other = tmp_path / "other.csv"
    text = csv.read_text()
    sa = next(c for c in text.splitlines()[0].split(",") if "-SA_" in c)
    other.write_text(text.replace(sa, "1-SA_9.99-0-1"))
    capsys.readouterr()
    out = str(tmp_path / "l")
    assert main(["loss", str(other), "-o", out, "--floor-area", "100", "--collapse-from", str(ida)]) == 2
    err = capsys.readouterr().err
    assert "is not the demand file's (SA_9.99)" in err and not (tmp_path / "l").exists()
    assert main(["loss", str(csv), "-o", str(tmp_path / "l"), "--floor-area", "100", "--collapse-from", str(ida),
                 "--collapse-median", "1.2", "--collapse-beta", "0.4"]) == 2
    assert "not both" in capsys.readouterr().err


def test_the_fleet_keeps_what_each_unit_rests_on(event):
    """A unit's assessment carries the basis (its table the flags, one column): P(collapse) at the
    clone's event, contradicted at 60 %."""
    from hlaid.fleet.assess import assess_clone, flatten
    from hlaid.ida.config import IDAConfig

    clone, meas, _ = event

    def fake(clone, records, *, n_ensemble, ida_config, own_motion, seed):
        return {"n_ensemble": 3, "p_collapse": 0.6, "own_peak_drift": [0.0125, 0.0124, 0.0126],
                "events": [{"name": meas.name, "im": 1.46, "p_collapse": 0.6, "p_collapse_band": [0.4, 0.8]}]}
    a = assess_clone(clone, [], n_ensemble=3, ida_config=IDAConfig(heights_mm=[3000.0] * 3), own_motion=None, seed=0,
                     assess=fake)
    b = a["basis"]
    assert b["survival_contradicted"] == [meas.name] and b["extrapolated"] is False
    assert b["heights_assumed"] is True
    row = flatten(a)
    assert f"P(collapse) 60% for another record of {meas.name}'s intensity" in row["basis_flags"]
    assert "assumed" in row["basis_flags"]
    survived = clone.survived_drift(measured_only=True)
    assert row["basis.survived_drift_ratio"] == pytest.approx(float(np.max(survived / 3000.0)))


def test_predict_and_demands_say_which_drifts_they_compare(event, tmp_path, capsys):
    """The same question, two answers unless each says its band: predict compares band-passed
    drifts (and says the band), demands gives the full replay's (and says so)."""
    clone, meas, path = event
    assert main(["predict", str(path), str(meas.source), "-o", str(tmp_path / "p"), "--start", "undamaged",
                 "--band", "0.3", "10", "--no-plots"]) == 0
    assert "drifts compared in 0.3-10 Hz, hlaid demands gives the full replay's" in capsys.readouterr().err
    assert main(["demands", str(path), "--motion", str(meas.source), "-o", str(tmp_path / "d.csv")]) == 0
    assert "the clones' full replay, unfiltered; hlaid predict compares drifts in a band" in capsys.readouterr().err


def test_a_clone_without_events_says_so(table1):
    b = decision_basis(Clone(building=table1))
    assert "not assessed (the clone records no events it was identified from" in b.lines()[1]
    assert "not recorded with the clone" in b.lines()[2] and b.flags() == []
