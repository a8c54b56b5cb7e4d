"""Replay with torchdiffeq against the batch simulator, and its gradients.

torchdiffeq's ``rk4`` is the 3/8-rule variant, a different fourth-order method from the
simulator's classical RK4, so the two agree to truncation error, not to the bit.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import rel_err, window

from hlaid.errors import InputError
from hlaid.model import BuildingTensors
from hlaid.motions import GroundMotion
from hlaid.simulate import SOLVERS, integrate_module, replay, replay_module, simulate_response


@pytest.fixture(scope="module")
def strong_window(records):
    """3 s of El Centro at 0.62 g, 200 Hz, from 1 s before the peak: the strongly nonlinear part."""
    return window(records["elcentro-1940-ns"], 3.0, before_peak=1.0)


def test_rk4_replay_matches_simulator(table1, strong_window):
    """Fixed-step rk4 at the same step (dt/8) as the simulator."""
    r = replay(table1, strong_window, method="rk4", substeps=8)
    s = simulate_response(table1, strong_window, substeps=8)
    assert r.drift.shape == s.drift.shape == (1, strong_window.npts, 3)
    assert (r.peak_drift[0] > 3 * table1.dy).all()  # well into the nonlinear range
    err = rel_err(r.drift, s.drift)
    # measured about 3e-6 (1e-6 to 3.5e-6 over three records). At substeps=4 both methods are
    # 1e-5 from the converged answer and differ by up to 1.4e-5: the sign switches of the
    # hysteretic law make the convergence slower than h^4.
    assert err <= 1e-5, err
    np.testing.assert_allclose(r.eta, s.eta, rtol=1e-6)


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_dopri5_replay_with_sample_step_points(table1, strong_window):
    """Adaptive dopri5, told the record's sample times as step points, at a tight tolerance."""
    r = replay(table1, strong_window, method="dopri5", rtol=1e-9, atol=1e-8)
    s = simulate_response(table1, strong_window, substeps=16)  # the simulator near its converged answer
    err = rel_err(r.drift, s.drift)
    assert err <= 1e-5, err  # measured about 1e-6


def test_replay_batch_and_scale(table1, strong_window):
    """Several buildings in one replay; ``scale`` multiplies the motion."""
    soft = table1.replace(k0=table1.k0 * 0.7)
    short = GroundMotion(dt=strong_window.dt, acc=strong_window.acc[:201])
    r = replay([table1, soft], short, method="rk4", substeps=4, scale=0.5)
    s = simulate_response([table1, soft], short, 0.5, substeps=4)
    assert r.batch_size == 2 and list(r.scale) == [0.5, 0.5]
    assert rel_err(r.drift, s.drift) <= 1e-5


def test_replay_gradients_match_finite_differences(table1, strong_window):
    """Replay is differentiable in the parameters (what gradient-based identification needs)."""
    gm = GroundMotion(dt=strong_window.dt, acc=strong_window.acc[200:321])  # 0.6 s from the peak
    P = BuildingTensors.stack([table1])

    def loss(**changes):
        params = BuildingTensors(**{**vars(P), **changes})
        states = integrate_module(replay_module(params, gm), gm, method="rk4", substeps=2)
        u = states[..., :3]
        x = u - torch.nn.functional.pad(u, (1, 0))[..., :-1]
        return (x**2).sum()

    leaves = {name: getattr(P, name).clone().requires_grad_(True) for name in ("k0", "dy", "delta_eta")}
    loss(**leaves).backward()
    for name, i in (("k0", 0), ("k0", 2), ("dy", 1), ("delta_eta", 2)):
        base = getattr(P, name)
        h = 1e-6 * float(base[0, i])
        up, dn = base.clone(), base.clone()
        up[0, i] += h
        dn[0, i] -= h
        with torch.no_grad():
            fd = float(loss(**{name: up}) - loss(**{name: dn})) / (2 * h)
        assert fd != 0.0
        assert float(leaves[name].grad[0, i]) == pytest.approx(fd, rel=1e-4), (name, i)


def test_replay_errors(table1, strong_window):
    with pytest.raises(InputError, match="unknown replay method 'rk5'"):
        replay(table1, strong_window, method="rk5")
    assert "rk4" in SOLVERS and "dopri5" in SOLVERS
