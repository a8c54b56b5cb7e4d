"""The ground tangent of a nonlinear replay (:mod:`hlaid.simulate.tangent`) and the
errors-in-variables whitening built on it (``refine.method: eiv``): the tangent against the
simulator itself and against finite differences of replays (the reference below), the whitening
against the inverse covariance computed densely, the limit on its size, and the refinement's
use of it."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import torch
from conftest import paper_record, window

from hlaid.errors import InputError, TangentTooLargeError, UnstableTangentError
from hlaid.identify import refine_replay
from hlaid.identify.eiv import TangentWhitener, ground_memory
from hlaid.model import BoucWenBuilding, BuildingTensors, Damping
from hlaid.motions import GroundMotion
from hlaid.signal import lowpass
from hlaid.simulate import simulate_response
from hlaid.simulate.tangent import GroundTangent, ground_tangent, step_jacobians
from hlaid.synthetic import simulate_measurement


@pytest.fixture(scope="module")
def yielding(table1):
    """Table 1 under 4 s of El Centro around its peak (every story yields) and its tangent."""
    gm = window(paper_record("elcentro-1940-ns"), 4.0, before_peak=1.0)
    imp = np.zeros(41)
    imp[20] = 1.0
    shape = lowpass(imp, gm.dt, 20.0)[10:31]
    return gm, shape, ground_tangent(table1, gm, lags=gm.acc.size, shape=shape)  # no truncation


@pytest.mark.parametrize("amplitude, tol", [(1e-3, 0.01), (0.1, 0.05)])
def test_tangent_predicts_the_nonlinear_response(table1, yielding, amplitude, tol):
    """The floors' change under a random ground perturbation, re-simulated with the full
    nonlinear building, is the tangent's prediction: within 1 % for a small one, 5 % for a
    10 % noise (the linear initial-stiffness transfer misses it by more than 100 %)."""
    gm, shape, gt = yielding
    peak = np.abs(simulate_response(table1, gm, outputs="full").drift[0]).max(axis=0)
    assert np.all(peak > 2.0 * table1.dy)  # the transfer really changes along the record
    rng = np.random.default_rng(3)
    u = rng.standard_normal(gm.acc.size) * amplitude * np.sqrt(np.mean(gm.acc**2))
    dg = np.convolve(u, shape, mode="same")
    base = simulate_response(table1, gm, outputs="acc").acc[0]
    moved = simulate_response(table1, GroundMotion(dt=gm.dt, acc=gm.acc + dg), outputs="acc").acc[0]
    act, pred = moved - base, gt.apply(u)
    err = np.sqrt(np.mean((pred - act) ** 2, axis=0) / np.mean(act**2, axis=0))
    assert np.all(err < tol), err
    shifted = np.roll(pred, 1, axis=0)  # one sample off is clearly worse: the alignment is tested
    assert np.all(np.sqrt(np.mean((shifted - act) ** 2, axis=0) / np.mean(act**2, axis=0)) > 3 * err)


def difference_tangent(building, motion, *, lags: int, shape: np.ndarray, substeps: int = 4,
                       rel_step: float = 1e-4, chunk: int = 512) -> GroundTangent:
    """The reference of :func:`ground_tangent` (stride 1, no low-pass): every column a central
    finite difference of two replays restarted from the trajectory's own state just before the
    perturbed sample (``2 x lags x substeps`` times dearer than the tangent-linear model)."""
    g = np.asarray(motion.acc, dtype=float)
    T, n, half = g.size, building.n_stories, shape.size // 2
    base = simulate_response(building, motion, substeps=substeps)
    work = base.energy[0] / ((1.0 - np.asarray(building.alpha)) * np.asarray(building.k0))
    states = np.concatenate([base.disp[0], base.vel[0], base.z[0], work], axis=1)  # states[0] is rest
    width = int(lags) + half
    out = np.zeros((T, width, n))
    eps = rel_step * float(np.sqrt(np.mean(g**2)) or 1.0)
    seg_len = width + half + 2
    padded = np.concatenate([g, np.zeros(seg_len + 1)])
    for c0 in range(0, T, chunk):
        taus = np.arange(c0, min(T, c0 + chunk))
        motions, y0, offs = [], np.empty((2 * taus.size, 4 * n)), []
        for i, tau in enumerate(taus):
            s0 = max(tau - half - 1, 0)  # restart from the state at sample s0 (rest at 0)
            seg = padded[s0:s0 + seg_len]
            lo = max(tau - half, 0)  # the shape's first sample inside the record
            for sign, row in ((1.0, 2 * i), (-1.0, 2 * i + 1)):
                sg = seg.copy()
                sg[lo - s0:tau + half + 1 - s0] += sign * eps * shape[lo - (tau - half):]
                motions.append(GroundMotion(dt=motion.dt, acc=sg))
                y0[row] = states[s0]
            offs.append(tau - half - s0)  # segment index of lag 0 (1, or <= 0 at the record's start)
        acc = simulate_response([building], motions, substeps=substeps, outputs="acc", y0=y0).acc
        diff = (acc[0::2] - acc[1::2]) / (2.0 * eps)
        for i, (tau, off) in enumerate(zip(taus, offs)):
            j0 = max(-off, 0)
            stop = min(width, T - (tau - half))  # lags past the record's end stay zero
            if stop > j0:
                out[c0 + i, j0:stop] = diff[i, off + j0:off + stop]
    return GroundTangent(response=out, lead=half, dt=float(motion.dt))


def test_linear_tangent_is_the_difference_tangent(table1, yielding):
    """The tangent-linear model and the replays' finite differences agree."""
    gm, shape, gt = yielding
    ref = difference_tangent(table1, gm, lags=gm.acc.size, shape=shape)
    assert ref.lead == gt.lead and ref.response.shape == gt.response.shape
    err = np.sqrt(np.sum((gt.response - ref.response) ** 2) / np.sum(ref.response**2))
    assert err < 1e-6, err


def test_coarse_tangent_is_the_fine_one_sampled(table1, yielding):
    """``stride`` and ``lowpass_hz``: the fine tangent's columns at every third sample, low-passed
    along the lags and sampled there; and white ground noise of std ``s`` per fine sample carries
    to the floors what ``sqrt(3) s`` per coarse perturbation carries (power below 20 Hz)."""
    gm, shape, gt = yielding
    co = ground_tangent(table1, gm, lags=gm.acc.size // 3, shape=shape, stride=3, lowpass_hz=20.0)
    want = lowpass(gt.response[::3], gm.dt, 20.0, axis=1)
    shift = 3 * co.lead - gt.lead  # the shape is padded to a lead that is a multiple of the stride
    assert co.dt == 3 * gm.dt and 0 <= shift < 3
    lags = np.arange(20, 200)  # coarse lag i is fine lag 3 i - shift (away from the filter's edges)
    np.testing.assert_allclose(co.response[:, lags], want[:, 3 * lags - shift], atol=1e-6 * np.abs(want).max())
    rng = np.random.default_rng(1)
    fine = np.array([lowpass(gt.apply(rng.standard_normal(gm.acc.size)), gm.dt, 20.0)[::3] for _ in range(40)])
    coarse = np.array([co.apply(np.sqrt(3.0) * rng.standard_normal(co.n_time)) for _ in range(40)])
    f = np.fft.rfftfreq(co.n_time, co.dt)
    band = f < 15.0
    pf = np.mean(np.abs(np.fft.rfft(fine, axis=1)) ** 2, axis=(0, 2))[band]
    pc = np.mean(np.abs(np.fft.rfft(coarse, axis=1)) ** 2, axis=(0, 2))[band]
    assert 0.85 < pc.sum() / pf.sum() < 1.15


def test_step_jacobians_are_the_modules_derivatives(table1, yielding):
    """The compiled step's central differences against forward-mode derivatives of the torch
    module's RK4 sample (the same scheme, differentiated exactly)."""
    gm, _, _ = yielding
    full = simulate_response(table1, gm, outputs="full", substeps=2)
    work = full.energy[0] / ((1.0 - table1.alpha) * table1.k0)
    states = np.concatenate([full.disp[0], full.vel[0], full.z[0], work], axis=1)[::7]
    g = gm.acc[::7]  # any pairs of samples will do
    A, b0, b1 = step_jacobians(table1, states, g, gm.dt, substeps=2, chunk=50)
    m, S = A.shape[0], states.shape[1]
    model = BoucWenBuilding(BuildingTensors.stack([table1]).index(np.zeros(m, dtype=np.int64)))
    y, g0, g1 = (torch.as_tensor(np.ascontiguousarray(a)) for a in (states[:-1], g[:-1], g[1:]))

    def step(y, a0, a1):
        return model.rk4_sample(y, a0, a1, gm.dt, 2)

    for j in range(S + 2):
        ty, t0, t1 = torch.zeros_like(y), torch.zeros_like(g0), torch.zeros_like(g1)
        (ty[:, j] if j < S else t0 if j == S else t1).fill_(1.0)
        with torch.no_grad():
            d = torch.func.jvp(step, (y, g0, g1), (ty, t0, t1))[1].numpy()
        got = A[:, :, j] if j < S else (b0 if j == S else b1)
        np.testing.assert_allclose(got, d, rtol=1e-5, atol=1e-6 * np.abs(d).max())


def test_tangent_adjoint(yielding):
    gm, _, gt = yielding
    rng = np.random.default_rng(0)
    x, y = rng.standard_normal(gt.n_time), rng.standard_normal((gt.n_time, 3))
    assert np.isclose(np.sum(gt.apply(x) * y), np.sum(x * gt.adjoint(y)), rtol=1e-12)


@pytest.mark.parametrize("T, W, lead", [(230, 40, 3), (80, 40, 0), (41, 40, 5), (400, 7, 2)])
def test_whitener_is_the_inverse_covariance(T, W, lead):
    """``|rho|^2 = c^2 r^T (diag(s_f^2) + s_g^2 G G^T)^-1 r`` with G built densely, for any
    block layout (a short last block, a lead, lags past the record's ends)."""
    rng = np.random.default_rng(T)
    n = 3
    R = rng.standard_normal((T, W, n)) * np.exp(-np.arange(W) / 10.0)[None, :, None]
    sf, sg = np.array([0.5, 1.0, 2.0]), 0.7
    wt = TangentWhitener(GroundTangent(response=R, lead=lead, dt=0.01), sf, sg)
    G = np.zeros((T, n, T))
    for tau in range(T):
        for j in range(W):
            if 0 <= tau - lead + j < T:
                G[tau - lead + j, :, tau] = R[tau, j]
    G = G.reshape(T * n, T)
    S = np.diag(np.tile(sf**2, T)) + sg**2 * G @ G.T
    r = rng.standard_normal((2, T, n))
    rho = wt(r)
    assert rho.shape == (2, T, n + 1)
    for k in range(2):
        want = np.mean(sf) ** 2 * r[k].ravel() @ np.linalg.solve(S, r[k].ravel())
        assert np.isclose(np.sum(rho[k] ** 2), want, rtol=1e-10)
        np.testing.assert_allclose(wt(r[k]), rho[k], atol=1e-12)
    # the whitener's block form of the operator is GroundTangent's apply / adjoint, scaled by D^(1/2)
    gt = GroundTangent(response=R, lead=lead, dt=0.01)
    d, x = rng.standard_normal(T), rng.standard_normal((T, n))
    np.testing.assert_allclose(wt._apply(d[:, None])[:, :, 0], gt.apply(d) / sf, atol=1e-12)
    np.testing.assert_allclose(wt._adjoint(x[:, :, None])[:, 0], gt.adjoint(x / sf), atol=1e-12)


def test_tangent_size_is_bounded(table1, monkeypatch):
    gm = GroundMotion(dt=0.005, acc=np.ones(2000))
    tangent = importlib.import_module("hlaid.simulate.tangent")
    monkeypatch.setattr(tangent, "simulate_response", None)  # both refusals come before anything is simulated
    # one copy: 2000 x 1000 x 3 doubles (45.8 MiB) and 2000 step Jacobians of 12 x 14 (2.6 MiB)
    with pytest.raises(TangentTooLargeError, match="would take 48 MiB, more than the 40 MiB"):
        ground_tangent(table1, gm, lags=1000, max_mb=40)
    monkeypatch.setenv("HLAID_MAX_TANGENT_MB", "1")
    with pytest.raises(InputError, match="HLAID_MAX_TANGENT_MB"):
        ground_tangent(table1, gm, lags=1000, max_mb=60)


def test_ground_memory_is_four_decay_times_of_the_first_mode(table1):
    t1 = float(table1.periods()[0])
    assert ground_memory(table1) == pytest.approx(4 * t1 / (2 * np.pi * 0.05))
    assert 4.5 < ground_memory(table1) < 5.0  # Table 1: T1 0.38 s at 5 %
    assert ground_memory(table1.replace(damping=Damping(kind="none"))) == 10.0  # undamped: the upper limit
    assert ground_memory(table1.replace(damping=Damping(ratio=0.9))) == 2.0


def test_unstable_tangent_is_refused(table1, yielding, monkeypatch):
    """A tangent that grows without bound is refused with its own error, by the tangent and by
    the whitener (finite but overflowing), rather than as NaNs deep inside the fit."""
    gm, shape, gt = yielding
    with pytest.raises(UnstableTangentError, match="without bound"):
        TangentWhitener(GroundTangent(response=gt.response * 1e200, lead=gt.lead, dt=gt.dt), np.ones(3), 1.0)
    tangent = importlib.import_module("hlaid.simulate.tangent")

    def blown(A, b0, b1, cmap, k, half, taus, out):
        out[:] = np.inf

    monkeypatch.setattr(tangent, "_propagate", blown)
    with pytest.raises(UnstableTangentError, match="without bound"):
        ground_tangent(table1, gm, lags=50, shape=shape)


def test_tangent_refinement_stays_at_the_truth_without_noise(table1):
    """Noise-free, the truth is the optimum of the whitened criterion too; the residuals gain the
    ground correction's column."""
    gm = window(paper_record("kobe-1995-nis000"), 6.0)
    meas = simulate_measurement(table1, gm, noise_rms=0.0, seed=0)
    start = table1.replace(dy=table1.dy * 1.03, alpha=table1.alpha * 0.97)
    rr = refine_replay(start, meas, ground_noise="tangent", ground_memory_s=2.0, jac_substeps=2)
    stride = 3  # residuals low-passed at 20 Hz, compared at 66.7 Hz of the 200 Hz record
    assert rr.channels == 4 and rr.residuals.size == len(range(0, meas.floor_acc.shape[0], stride)) * 4
    for k in ("dy", "alpha", "p", "delta_eta", "k0"):
        np.testing.assert_allclose(getattr(rr.building, k), getattr(table1, k), rtol=2e-3)


# ------------------------------------------------------------------ forward-mode sensitivities
def _one_at_a_time(b, h_rel=1e-4):
    """``b`` and one building per parameter with that parameter moved by ``h_rel`` (damping last)."""
    trial, steps = [b], []
    for i in range(b.n_stories):
        for k in ("k0", "alpha", "p", "dy", "delta_eta"):
            v = np.array(getattr(b, k), float)
            h = h_rel * max(abs(v[i]), 1e-3)
            v[i] += h
            trial.append(b.replace(**{k: v}))
            steps.append(h)
    trial.append(b.replace(damping=Damping(kind=b.damping.kind, ratio=b.damping.ratio * (1 + h_rel),
                                           modes=b.damping.modes)))
    steps.append(b.damping.ratio * h_rel)
    return trial, np.array(steps)


@pytest.mark.parametrize("substeps", [1, 2])
def test_linearised_batch_is_the_replays_derivative(table1, substeps):
    """Within ``linearised``, a batch is the first building's replay plus every other's tangent-linear
    response: its difference quotients are the forward differences of full replays to their O(h)
    (parameters, the damping ratio through the damping matrix, an initial state), the first
    element's replay that of the compiled simulator, and the final states likewise."""
    from hlaid.simulate.sensitivity import linearised

    gm = window(paper_record("elcentro-1940-ns"), 6.0, before_peak=2.0).scaled_to_pga(0.62)
    trial, h = _one_at_a_time(table1)
    y0 = np.zeros((len(trial), 12))
    y0[:, 2] = 0.5  # a state carried from an earlier event ...
    y0[1, 5] += 1e-3  # ... and one element moved in it as well
    full = simulate_response(trial, gm, substeps=substeps, outputs="acc", y0=y0)
    with linearised():
        lin = simulate_response(trial, gm, substeps=substeps, outputs="acc", y0=y0)
    assert np.all(full.status == 0) and np.all(lin.status == 0)
    assert np.allclose(lin.acc[0], full.acc[0], rtol=0, atol=1e-9 * np.abs(full.acc[0]).max())
    dfull = (full.acc[1:] - full.acc[:1]) / h[:, None, None]
    dlin = (lin.acc[1:] - lin.acc[:1]) / h[:, None, None]
    rel = np.linalg.norm((dfull - dlin).reshape(len(h), -1), axis=1) / np.linalg.norm(dfull.reshape(len(h), -1), axis=1)
    assert rel.max() < 5e-3, rel
    assert np.median(rel) < 5e-4, rel
    fs = (full.final_state[1:] - full.final_state[:1]) / h[:, None]
    fl = (lin.final_state[1:] - lin.final_state[:1]) / h[:, None]
    assert np.all(np.linalg.norm(fs - fl, axis=1) <= 5e-3 * np.linalg.norm(fs, axis=1))
    assert np.allclose(lin.peak_drift, full.peak_drift, rtol=1e-4)
    # outside the context, or a batch it does not cover (two motions), the replays are full ones
    plain = simulate_response(trial, gm, substeps=substeps, outputs="acc", y0=y0)
    assert np.array_equal(plain.acc, full.acc)
    with linearised():
        two = simulate_response(trial[:3], [gm, gm], substeps=substeps, outputs="acc", pairing="product")
    ref = simulate_response(trial[:3], [gm, gm], substeps=substeps, outputs="acc", pairing="product")
    assert np.array_equal(two.acc, ref.acc)


def test_linearised_batch_replays_in_full_where_a_sample_is_refined(table1):
    """A yield displacement far below a sample's drift increment makes the replay refine its sub-steps:
    the linearised batch is then the full replays, bit for bit."""
    from hlaid.simulate.sensitivity import linearised

    gm = window(paper_record("elcentro-1940-ns"), 4.0, before_peak=1.0).scaled_to_pga(0.62)
    small = table1.replace(dy=np.full(3, 0.02))
    trial = [small, small.replace(k0=small.k0 * 1.0001), small.replace(p=small.p * 1.0001)]
    full = simulate_response(trial, gm, substeps=1, outputs="acc")
    with linearised():
        lin = simulate_response(trial, gm, substeps=1, outputs="acc")
    assert np.array_equal(lin.acc, full.acc, equal_nan=True) and np.array_equal(lin.status, full.status)


def test_refinement_jacobians_tangent_and_difference_reach_the_same_optimum(table1):
    """The replay fit with the tangent's Jacobians and with forward differences of full replays: the same
    optimum (the residuals define it; within 1e-3, the search's tolerance along the flattest direction),
    the same cost, and Jacobians at the optimum within 1e-2."""
    gm = window(paper_record("kobe-1995-nis000"), 8.0, before_peak=2.0)
    meas = simulate_measurement(table1, gm.scaled_to_pga(0.5), noise_rms=0.05, seed=3)
    start = table1.replace(k0=table1.k0 * 1.03, alpha=table1.alpha + 0.02, p=table1.p * 0.95, dy=table1.dy * 1.05,
                           delta_eta=table1.delta_eta * 1.1)
    a = refine_replay(start, meas, jac_substeps=2, jacobian="tangent")
    b = refine_replay(start, meas, jac_substeps=2, jacobian="difference")
    assert a.cost_final == pytest.approx(b.cost_final, rel=1e-6)
    np.testing.assert_allclose(a.x, b.x, rtol=1e-3)
    assert np.linalg.norm(a.jacobian - b.jacobian) <= 1e-2 * np.linalg.norm(b.jacobian)
    with pytest.raises(InputError, match="jacobian = 'adjoint'"):
        refine_replay(start, meas, jacobian="adjoint")
