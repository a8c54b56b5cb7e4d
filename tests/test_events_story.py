"""What the next event's clone is judged on and what it chooses: story drifts in the prediction,
the prequential start rule, the stories' laws, and numerical stages that fall back with a note."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.clone import Clone
from hlaid.events.prequential import MARGIN, start_rule
from hlaid.events.start import resolve_start
from hlaid.hla.auto import DRIFT_AGREEMENT
from hlaid.hla.preprocess import drift_agreement, first_mode
from hlaid.joint.laws import (
    ELASTIC_CY,
    NO_DEGRADATION,
    candidates,
    choose_laws,
    default_laws,
    law_mask,
    with_laws,
)
from hlaid.joint.priors import get_prior, weight_above
from hlaid.joint.vector import PriorVector, SystemPrior, from_units, to_units
from hlaid.model.schema import STORY_BOUNDS
from hlaid.model.state import BuildingState
from hlaid.record import EventRecord, LawChoice, Prequential, StartRule, StartScore
from hlaid.simulate import simulate_response
from hlaid.synthetic import simulate_events


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    return float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b)))


# ----------------------------------------------------------------------------- the start rule
def _events(*pairs) -> list[EventRecord]:
    out = [EventRecord(name="e1")]
    for k, (c, r) in enumerate(pairs):
        out.append(EventRecord(name=f"e{k + 2}", prequential=Prequential(
            clone_of=("e1",), carried=StartScore(c), undamaged=StartScore(r))))
    return out


def test_the_start_rule_carries_only_what_predicted_better_than_rest():
    assert start_rule(_events()).choice == "undamaged"  # nothing predicted yet
    r = start_rule(_events((0.95, 0.90), (0.97, 0.95)))  # carried better by 0.035 on the mean
    assert r.choice == "carried" and r.n == 2 and r.carried_minus_undamaged == pytest.approx(0.035)
    r = start_rule(_events((0.95, 0.90), (0.90, 0.94)))  # +0.005: within the margin
    assert r.choice == "undamaged" and r.carried_minus_undamaged == pytest.approx(0.005) and MARGIN == 0.01
    assert start_rule(_events((0.80, 0.93))).choice == "undamaged"
    broken = [EventRecord.from_dict(e.to_dict()) for e in _events((0.95, 0.90))]
    broken[1] = EventRecord.from_dict({"name": "e2", "prequential": {"carried": {"r": 0.95}, "undamaged": {"r": None}}})
    assert start_rule(broken).n == 0  # a record that cannot be read counts as none


def test_auto_start_follows_the_clones_rule(table1):
    state = BuildingState.at_rest(3)
    for choice, expect in (("carried", "carried"), ("undamaged", "undamaged")):
        c = Clone(building=table1, state=state, start_rule=StartRule(choice, "because"))
        s = resolve_start(c, "auto")
        assert s.name == expect and "because" in s.reason
        assert resolve_start(c, "carried").name == "carried"  # asked for: as asked
    assert resolve_start(Clone(building=table1, state=state), "auto").name == "carried"  # a clone before the rule


# ----------------------------------------------------------------------------- laws
def test_laws_fix_the_entries_they_hold(table1):
    steel = get_prior("steel-moment-frame")
    assert default_laws(steel, 3) == ("degrading",) * 3
    assert candidates(3)[:3] == [("elastic",) * 3, ("nondegrading",) * 3, ("degrading",) * 3]
    assert len(candidates(3)) == 9 and ("nondegrading", "elastic", "elastic") in candidates(3)
    laws = ("nondegrading", "elastic", "degrading")
    assert law_mask(laws).sum() == 4 + 1 + 5
    b = with_laws(table1, laws, steel)
    w = weight_above(table1)
    assert b.delta_eta[0] == NO_DEGRADATION and b.delta_eta[1] == NO_DEGRADATION
    assert b.delta_eta[2] == table1.delta_eta[2] and b.dy[2] == table1.dy[2]
    assert b.dy[1] == pytest.approx(ELASTIC_CY * w[1] / table1.k0[1])
    assert b.alpha[1] == pytest.approx(steel.alpha.median) and b.p[1] == pytest.approx(steel.p.median)
    v = PriorVector(b, damping=True, laws=laws)
    assert len(v.slots) == 10 + 1 and ("cy", 1) not in v.slots and ("delta_eta", 0) not in v.slots
    x = v.x0.copy()
    x[v.slots.index(("k0", 1))] += np.log(2.0)  # the elastic story twice as stiff
    moved = v.building_at(x)
    assert moved.k0[1] == pytest.approx(2 * b.k0[1])
    assert moved.dy[1] == pytest.approx(b.dy[1] / 2)  # Cy held: dy = Cy W / k0
    np.testing.assert_allclose(moved.delta_eta, b.delta_eta)
    np.testing.assert_allclose(v.of(moved), x)
    prior = SystemPrior(steel, v, b.k0)
    full = SystemPrior(steel, PriorVector(b, damping=True), b.k0)
    assert prior.residuals(v.x0).size < full.residuals(PriorVector(b, damping=True).x0).size
    assert Clone(building=b, laws=LawChoice(chosen=laws)).story_laws() == laws
    assert Clone(building=b).story_laws() is None
    assert Clone(building=b, laws=LawChoice(chosen=laws[:2])).story_laws() is None  # not one per story


def test_the_systems_law_stays_unless_another_is_clearly_better():
    d = ("degrading",) * 3
    e = ("elastic",) * 3
    assert choose_laws([(d, -100.0), (e, -99.0)], d)[0] == d  # +1: a tie
    assert choose_laws([(d, -100.0), (e, -97.0)], d)[0] == e  # +3
    assert choose_laws([(d, float("nan")), (e, -97.0)], d)[0] == e
    assert choose_laws([(d, float("nan"))], d)[0] == d


def test_prior_units_are_clipped_to_the_models_bounds(table1):
    u, lz = to_units(table1)
    u[1, 3] += 40.0  # Cy so large that dy = Cy W / k0 leaves the model's range
    u[2, 4] += 60.0
    b = from_units(table1, u, lz)
    assert b.dy[1] == pytest.approx(STORY_BOUNDS["dy"].upper())
    assert b.delta_eta[2] == pytest.approx(STORY_BOUNDS["delta_eta"].upper())
    np.testing.assert_allclose(b.k0, table1.k0)


# ----------------------------------------------------------------------------- which displacement, which band
def test_measured_drifts_are_used_only_where_they_resolve_the_story(table1):
    gm = window(paper_record("elcentro-1940-ns"), 12.0).scaled(0.3)
    (m,), _ = simulate_events(table1, [gm], noise_rms=0.0, seed=0)
    truth = np.asarray(m.truth.disp) if m.truth is not None else None
    assert truth is not None
    band = (0.5, 15.0)
    clean = drift_agreement(truth, m.floor_acc, m.ground_acc, m.dt, band)
    assert np.all(clean > DRIFT_AGREEMENT + 0.1)
    rng = np.random.default_rng(0)
    # sensors whose noise scales with each floor's whole motion, here 5 x the smallest story drift
    noisy = truth + rng.standard_normal(truth.shape) * 5 * np.std(np.diff(truth, axis=1, prepend=0.0), axis=0).min()
    assert drift_agreement(noisy, m.floor_acc, m.ground_acc, m.dt, band).min() < DRIFT_AGREEMENT


def test_an_isolation_mode_below_the_acceleration_peak_sets_the_first_mode():
    dt, t = 0.01, np.arange(0, 60, 0.01)
    rng = np.random.default_rng(1)
    ground = rng.standard_normal(t.size)
    roof = ground + 3 * np.sin(2 * np.pi * 3.0 * t)  # relative acceleration peaks at 3 Hz
    assert first_mode(ground, roof, dt) == pytest.approx(3.0, abs=0.1)
    disp = 50 * np.sin(2 * np.pi * 0.4 * t) + np.sin(2 * np.pi * 3.0 * t)  # displacement at 0.4 Hz
    assert first_mode(ground, roof, dt, disp) == pytest.approx(0.4, abs=0.1)
    assert first_mode(ground, roof, dt, np.sin(2 * np.pi * 2.5 * t)) == pytest.approx(3.0, abs=0.1)


# ----------------------------------------------------------------------------- end to end
def test_identify_falls_back_chooses_and_predict_reports_story_drifts(table1, tmp_path, capsys, monkeypatch):
    """Two events through the command line with the errors-in-variables whitening failing
    numerically: the clone is made (exit 0) with the fallback said, the start rule and the laws
    recorded; the prediction's per-story drift R and peak-drift errors are those of its own
    displacements."""
    import scipy.linalg

    from hlaid.cli.app import main

    def not_pd(*a, **k):
        raise np.linalg.LinAlgError("19-th leading minor not positive definite")
    monkeypatch.setattr(scipy.linalg, "cholesky_banded", not_pd)
    pieces = [window(paper_record(n), 6.0).scaled(f) for n, f in (("elcentro-1940-ns", 0.4),
                                                                   ("kocaeli-1999-dzc180", 0.6),
                                                                   ("northridge-1994-mul009", 0.7))]
    meas, _ = simulate_events(table1, pieces, noise_rms=0.02, seed=3)
    files = [str(m.save(tmp_path / f"e{k + 1}.npz")) for k, m in enumerate(meas)]
    cfg = tmp_path / "id.yaml"
    cfg.write_text("system: steel-moment-frame\nrefine: {method: eiv, max_iterations: 6}\n")
    c12, pred = tmp_path / "c12.json", tmp_path / "pred"
    assert main(["identify", *files[:2], "-o", str(c12), "--config", str(cfg), "--no-cache", "-q"]) == 0
    c = Clone.load(c12)
    d = c.diagnostics  # the reader's account of the fit
    assert all(e["errors_in_variables"]["fitted_by"] == "least squares" for e in d["joint"]["events"])
    h = c.events[1].prequential
    assert h is not None and h.carried is not None and h.undamaged is not None
    assert h.clone_of == ("e1",) and 0.5 < h.undamaged.r <= 1.0
    rule = c.start_rule
    assert rule is not None and rule.n == 1
    assert rule.carried_minus_undamaged == pytest.approx(h.carried.r - h.undamaged.r)
    assert rule.choice == ("carried" if rule.carried_minus_undamaged > MARGIN else "undamaged")
    laws = c.laws
    assert laws is not None and laws.chosen is not None and len(laws.chosen) == 3 and len(laws.candidates) >= 2
    assert main(["predict", str(c12), files[2], "-o", str(pred), "-q"]) == 0
    p = json.loads((pred / "prediction.json").read_text())
    assert p["start"] == rule.choice
    with np.load(pred / "prediction.npz") as z:
        t, dm, dp = z["time"], z["disp_measured"], z["disp_predicted"]
    assert dm.shape == dp.shape == (t.size, 3)
    xm, xp = np.diff(dm, axis=1, prepend=0.0), np.diff(dp, axis=1, prepend=0.0)
    by_hand = np.max(np.abs(xp), axis=0) / np.max(np.abs(xm), axis=0) - 1.0
    np.testing.assert_allclose(p["peak_drift_error"], by_hand, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(p["drift_r"], [_corr(xp[:, i], xm[:, i]) for i in range(3)], atol=1e-9)
    np.testing.assert_allclose(p["r"], [_corr(dp[:, i], dm[:, i]) for i in range(3)], atol=1e-9)
    assert p["peak_drift_error_mean_abs"] == pytest.approx(np.mean(np.abs(by_hand)))
    assert p["peak_drift_error_worst"] == pytest.approx(by_hand[np.argmax(np.abs(by_hand))])
    assert p["roof_error"] == pytest.approx(np.max(np.abs(dp[:, -1])) / np.max(np.abs(dm[:, -1])) - 1.0)
    assert p["drift_r_mean"] == pytest.approx(np.mean(p["drift_r"])) and min(p["drift_r"]) > 0.8
    capsys.readouterr()


def test_the_simulated_response_is_what_the_tests_above_assume(table1):
    """A guard on the helper above: a replay from rest of the true building correlates 1 with itself."""
    gm = window(paper_record("elcentro-1940-ns"), 4.0)
    r = simulate_response(table1, gm, outputs="full")
    d = np.asarray(r.disp)[0]
    assert _corr(d[:, 0], d[:, 0]) == pytest.approx(1.0)


def test_the_check_of_an_update_flags_one_that_forgot_the_earlier_events(table1):
    """The earlier event's misfit change against the Gaussian's prediction: an update that moved
    the parameters within the posterior is kept; one that moved a well-determined parameter far
    (the earlier event's misfit grows by much more than a wide posterior predicts) is refitted."""
    from hlaid.events.guard import EXCESS_MIN, check_update, load_earlier
    from hlaid.joint.vector import GaussianPrior

    gm = window(paper_record("elcentro-1940-ns"), 6.0).scaled(0.5)
    (m,), _ = simulate_events(table1, [gm], noise_rms=0.02, seed=5)
    v = PriorVector(table1, damping=False)
    band = (0.1, 20.0)
    same = check_update(table1, table1, [m], GaussianPrior(v.x0, np.eye(v.x0.size)), v, band_hz=band)
    assert same.misfit_change == pytest.approx(0.0, abs=1e-9) and same.gaussian == pytest.approx(0.0)
    assert not same.refit and same.limit == EXCESS_MIN
    x = v.x0.copy()
    x[v.slots.index(("k0", 0))] += np.log(1.3)  # story 1 30 % stiffer: the record says otherwise
    moved = v.building_at(x)
    wide = check_update(table1, moved, [m], GaussianPrior(v.x0, 100.0 * np.eye(v.x0.size)), v, band_hz=band)
    assert wide.gaussian is not None and wide.misfit_change is not None
    assert wide.gaussian < 0.01 and wide.misfit_change > EXCESS_MIN and wide.refit
    # the same move, where the posterior said k0 was that uncertain: kept
    cov = 1e-6 * np.eye(v.x0.size)
    cov[v.slots.index(("k0", 0)), v.slots.index(("k0", 0))] = (np.log(1.3) / 100.0) ** 2
    tight = check_update(table1, moved, [m], GaussianPrior(v.x0, cov), v, band_hz=band)
    assert tight.gaussian == pytest.approx(0.5 * 100.0**2, rel=1e-6) and not tight.refit
    events = [EventRecord(name="e1", source=None, ground_sha256="0" * 64)]
    found, missing = load_earlier(events)
    assert found == [] and "not there" in missing[0]
    found, missing = load_earlier(events, [m])
    assert found == [] and "SHA-256" in missing[0]
