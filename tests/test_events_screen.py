"""Judged from the one joint fit: the stories' laws (a screen of the nested candidates), the
prefix clones of the start rule (a Newton step), and the update's check that refits only where
the earlier events no longer replay well."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.clone import Clone
from hlaid.events.update import update_clone
from hlaid.identify.auto import resolve_settings
from hlaid.identify.config import IdentifyConfig
from hlaid.joint.fit import joint_fit, map_refine, posterior_uncertainty
from hlaid.joint.laws import candidates, choose_laws, default_laws, with_laws
from hlaid.joint.priors import get_prior
from hlaid.joint.screen import data_jacobian, prefix_point, screen_laws
from hlaid.model import Building
from hlaid.record import EventRecord
from hlaid.synthetic import simulate_events

STORY = {"weight_kN": 171.85, "k0": 1.94e4, "alpha": 0.15, "p": 2.0, "dy": 7.0, "delta_eta": 1.0}


def _one_story(elastic: bool) -> Building:
    s = dict(STORY, dy=200.0, delta_eta=1e-8) if elastic else dict(STORY)
    return Building.from_stories([s], name="one", pdelta=False)


def _setup(building: Building, scales=(0.6,), seed: int = 2):
    motions = [window(paper_record(name), 8.0).scaled(f)
               for name, f in zip(("elcentro-1940-ns", "kocaeli-1999-dzc180"), scales)]
    meas, _ = simulate_events(building, motions, noise_rms=0.05, seed=seed)
    cfg = IdentifyConfig(system="steel-moment-frame", refine=dataclasses.replace(
        IdentifyConfig().refine, method="least_squares", max_iterations=15))
    return meas, resolve_settings(meas, cfg).config


@pytest.mark.slow
@pytest.mark.parametrize("elastic", [True, False], ids=["elastic", "degrading"])
def test_laws_judged_from_the_one_fit_agree_with_their_full_fits(elastic):
    """A story that stays elastic (dy far beyond its drift) and one that yields and degrades,
    under the same record: the laws chosen from the screen of the system's fit are those chosen
    from a full fit under every candidate, and the true one."""
    b = _one_story(elastic)
    meas, cfg = _setup(b)
    system = get_prior("steel-moment-frame")
    default = default_laws(system, 1)
    start = with_laws(b.replace(alpha=np.array([0.1]), p=np.array([2.0]), dy=np.array([5.0]),
                                delta_eta=np.array([0.1])), default, system)
    fit = joint_fit(start, meas, system, cfg, laws=default, k0_ref=b.k0)
    others = [laws for laws in candidates(1) if laws != default]
    screened = screen_laws(fit, others, system, b.k0)
    assert set(screened) == set(others)
    full = {laws: joint_fit(with_laws(fit.building, laws, system), meas, system, cfg, laws=laws, k0_ref=b.k0)
            for laws in others}

    def chosen(tried):
        n_eff = np.mean([fit.n_eff] + [f.n_eff for f in tried.values()], axis=0)
        return choose_laws([(default, fit.log_evidence(n_eff))]
                           + [(laws, f.log_evidence(n_eff)) for laws, f in tried.items()], default)[0]

    truth = ("elastic",) if elastic else ("degrading",)
    assert chosen(screened) == chosen(full) == truth


def test_the_screen_and_the_newton_step_start_from_the_fits_own_jacobian():
    """The data rows of the fit's Jacobian, unweighted, are the replay's derivatives (a finite
    difference of the residuals agrees); the system's own law screened again is the fit itself
    (no step moves it); the prefix of every event is the fit's optimum."""
    b = _one_story(False)
    meas, cfg = _setup(b, scales=(0.6,))
    system = get_prior("steel-moment-frame")
    fit = map_refine(b, meas, system=system, damping=True, ground_noise="ignore", max_iterations=15,
                     laws=default_laws(system, 1), rounds=1)
    Jd = data_jacobian(fit)
    assert Jd is not None and Jd.shape == (fit.series.n_residuals, fit.result.x.size)
    x = np.asarray(fit.result.x)
    j = fit.vector.slots.index(("k0", 0))
    h = 1e-5
    parts0, _, _ = fit.series.run([fit.vector.building_at(x)])
    parts1, _, _ = fit.series.run([fit.vector.building_at(x + h * (np.arange(x.size) == j))])
    fd = (parts1[0][0] - parts0[0][0]) / h
    assert np.corrcoef(fd, Jd[:, j])[0, 1] > 0.99
    np.testing.assert_allclose(np.linalg.norm(Jd[:, j]), np.linalg.norm(fd), rtol=0.05)
    same = screen_laws(fit, [default_laws(system, 1)], system, b.k0)[default_laws(system, 1)]
    np.testing.assert_allclose(same.squares, fit.squares, rtol=1e-3)
    whole = prefix_point(fit, 1, ["e1"])
    assert whole is not None and whole.building is not None and whole.step_sd < 0.01
    np.testing.assert_allclose(whole.building.k0, fit.building.k0, rtol=1e-4)


@pytest.mark.slow
def test_an_update_is_refitted_only_where_the_earlier_events_no_longer_replay_well():
    """An update with a second record of the same building keeps the update (the check passes,
    nothing refitted); a second record of a building 40 % softer, with the clone's posterior
    widened, moves k0 far: the first record no longer replays as the posterior said, and the
    events are refitted jointly."""
    b = _one_story(False)
    meas, cfg = _setup(b, scales=(0.4, 0.4), seed=4)
    system = get_prior("steel-moment-frame")
    first = map_refine(b, meas[:1], system=system, damping=False, ground_noise="ignore", max_iterations=10)
    clone = Clone(building=first.building, uncertainty=posterior_uncertainty(first), state=first.states[-1],
                  system="steel-moment-frame", events=(EventRecord(name=meas[0].name),))
    kept = update_clone(clone, meas[1], cfg, earlier=meas[:1]).clone.update_check
    assert kept is not None and kept.events == 1 and not kept.refit and not kept.refitted
    soft = b.replace(k0=0.6 * b.k0)
    (other,), _ = simulate_events(soft, [window(paper_record("kocaeli-1999-dzc180"), 8.0).scaled(0.4)],
                                  noise_rms=0.05, seed=9)
    moved = update_clone(clone, dataclasses.replace(other, name="softer"), cfg, earlier=meas[:1], widen=30.0)
    check = moved.clone.update_check
    assert check is not None and check.refit and check.refitted
    assert check.misfit_change is not None and check.gaussian is not None and check.limit is not None
    assert check.misfit_change > check.gaussian + check.limit


def test_an_entry_held_at_its_bound_leaves_the_evidence_finite():
    """A zero column of the posterior Jacobian (an entry at a bound of its transform, such as a
    damping ratio at its cap) is held there: the log-determinants are those of the other entries,
    not NaN from a singular matrix."""
    from hlaid.joint.fit import _logdet, log_dets

    rng = np.random.default_rng(0)
    J, Jp = rng.normal(size=(30, 3)), np.eye(3)
    held = np.hstack([J, np.zeros((30, 1))])
    held_p = np.hstack([np.vstack([Jp, np.zeros((1, 3))]), np.zeros((4, 1))])
    assert np.isnan(_logdet(held.T @ held))
    d = log_dets(held, held_p)
    assert d["log_det_hessian"] == pytest.approx(_logdet(J.T @ J)) and d["log_det_prior"] == pytest.approx(0.0)
