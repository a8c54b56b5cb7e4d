"""The linear floor coupling and per-mode damping: against independent references (scipy's
eigensolver, scipy's ODE solver), the shear chain unchanged at zero coupling, one model in the
compiled simulator, the torch module and the tangent."""

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.model import Building, Damping
from hlaid.model.coupling import Coupling
from hlaid.model.modes import clone_modes
from hlaid.motions import GroundMotion
from hlaid.simulate import simulate_response

KF = (400.0, 250.0)


def _frame(alpha=1.0, coupling=KF, damping=None, dy=5.0):
    return Building(mass=[1.2, 1.0, 0.8], k0=[2500.0, 1800.0, 1200.0], alpha=[alpha] * 3, p=[2.0] * 3,
                    dy=[dy] * 3, delta_eta=[0.0] * 3, coupling=None if coupling is None else Coupling(coupling),
                    damping=damping or Damping(kind="modal", ratio=0.02, ratio2=0.03, higher=(0.04,)))


def _stiffness_by_hand(b):
    """Shear chain plus flexural terms, assembled from the strain energy by finite differences."""
    n = b.n_stories

    def energy(u):
        x = np.diff(np.concatenate([[0.0], u]))
        full = np.concatenate([[0.0], u])
        curv = full[:-2] - 2 * full[1:-1] + full[2:]
        return 0.5 * np.sum(b.k0 * x**2) + 0.5 * np.sum(np.asarray(KF) * curv**2)

    K = np.zeros((n, n))
    e = np.eye(n)
    for i in range(n):
        for j in range(n):
            K[i, j] = (energy(e[i] + e[j]) - energy(e[i]) - energy(e[j])) / 1.0  # a quadratic form: exact
    return K


def test_linear_modes_match_scipy_eigh_and_the_modal_damping_ratios():
    b = _frame()
    K = _stiffness_by_hand(b)
    np.testing.assert_allclose(b.linear_stiffness(), K, rtol=1e-12, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(b.coupling_matrix()) >= -1e-9)
    lam = scipy.linalg.eigh(K, np.diag(b.mass), eigvals_only=True)
    modes = clone_modes(b)
    np.testing.assert_allclose([m.frequency_hz for m in modes], np.sqrt(lam) / (2 * np.pi), rtol=1e-10)
    np.testing.assert_allclose(1 / b.periods(), np.sqrt(lam) / (2 * np.pi), rtol=1e-10)
    np.testing.assert_allclose([m.damping_ratio for m in modes], [0.02, 0.03, 0.04], rtol=1e-10)


def _pulse(dt=0.005, T=3.0):
    t = np.arange(0.0, T, dt)
    ag = 2000.0 * np.sin(2 * np.pi * 2.5 * t) * np.exp(-t)
    return GroundMotion(acc=ag, dt=dt, name="pulse")


def test_linear_response_matches_solve_ivp():
    b = _frame()
    gm = _pulse()
    res = simulate_response(b, gm, substeps=4, outputs="full")
    M, K, C = np.diag(b.mass), b.linear_stiffness(), b.damping_matrix()
    t = np.arange(gm.acc.size) * gm.dt

    def rhs(tt, y):
        ag = np.interp(tt, t, gm.acc)
        u, v = y[:3], y[3:]
        return np.concatenate([v, np.linalg.solve(M, -K @ u - C @ v) - ag])

    sol = scipy.integrate.solve_ivp(rhs, (0, t[-1]), np.zeros(6), t_eval=t, rtol=1e-10, atol=1e-10, method="DOP853",
                                    max_step=gm.dt)
    u = res.disp[0]
    scale = np.max(np.abs(sol.y[:3]))
    assert np.max(np.abs(u - sol.y[:3].T)) < 1e-6 * scale


def test_zero_coupling_is_the_shear_chain_bit_for_bit():
    from hlaid.model import BuildingTensors
    from hlaid.simulate import _kernel

    b = _frame(alpha=0.1, coupling=None, damping=Damping(ratio=0.03))
    assert _frame(alpha=0.1, coupling=(0.0, 0.0), damping=Damping(ratio=0.03)).coupling is None
    P = BuildingTensors.stack([b]).numpy()
    gm = _pulse()
    ag = gm.acc[None].copy()
    outs = []
    for bwc in (-1, 2):  # no coupling, and a zero coupling's arithmetic done in full
        acc = np.empty((1, ag.shape[1], 3))
        args = dict(final=np.zeros((1, 12)), n_done=np.zeros(1, np.int64), status=np.zeros(1, np.int64))
        _kernel.integrate(ag, np.array([gm.dt]), np.array([ag.shape[1]]), np.zeros(1, np.int64),
                          np.zeros(1, np.int64), np.full(1, 3.0), 2, P["mass"], P["k0"], P["alpha"], P["p"], P["dy"],
                          P["delta_eta"], P["kg"], P["damping"], _kernel.damping_bandwidth(P["damping"]),
                          np.zeros((1, 3, 3)), np.array([bwc]), P["collapse"], np.zeros((1, 12)),
                          np.full((1, 3), np.inf), False, np.empty((0, 0, 0)), True, acc, np.zeros((1, 3)),
                          np.zeros((1, 3)), args["final"], args["n_done"], args["status"])
        outs.append(acc)
    np.testing.assert_array_equal(outs[0], outs[1])
    np.testing.assert_array_equal(simulate_response(b, gm, scales=3.0, substeps=2, outputs="acc").acc, outs[0])


def test_torch_module_and_kernel_agree_with_coupling():
    b = _frame(alpha=0.1, dy=2.0)
    gm = _pulse(T=1.5)
    a = simulate_response(b, gm, scales=2.0, outputs="full")
    t = simulate_response(b, gm, scales=2.0, outputs="full", backend="torch")
    np.testing.assert_allclose(a.acc, t.acc, rtol=1e-8, atol=1e-8 * np.max(np.abs(a.acc)))


def test_tangent_follows_a_change_of_coupling():
    from hlaid.simulate import sensitivity

    b = _frame(alpha=0.1, dy=2.0)
    h = 1e-4
    bs = [b, b.replace(coupling=Coupling((KF[0] * (1 + h), KF[1])))]
    gm = _pulse(T=1.5)
    full = simulate_response(bs, gm, scales=2.0, outputs="acc").acc
    with sensitivity.linearised():
        lin = simulate_response(bs, gm, scales=2.0, outputs="acc").acc
    d_full, d_lin = full[1] - full[0], lin[1] - lin[0]
    assert np.max(np.abs(d_lin - d_full)) < 1e-3 * np.max(np.abs(d_full))


def test_files_keep_the_coupling_and_refuse_a_bad_one():
    b = _frame()
    back = Clone.from_dict(Clone(building=b).to_dict()).building
    np.testing.assert_array_equal(back.coupling_matrix(), b.coupling_matrix())
    assert back.damping == b.damping
    assert Building.from_dict(b.to_dict()).coupling == b.coupling
    d = Clone(building=b).to_dict()
    d["coupling"] = {"flexural": [1.0]}
    with pytest.raises(InputError, match="coupling.flexural has 1 terms"):
        Clone.from_dict(d, source="c.json")
    d["coupling"] = {"flexural": [-1.0, 0.0]}
    with pytest.raises(InputError, match="coupling.flexural"):
        Clone.from_dict(d, source="c.json")


def test_opensees_export_refuses_a_coupled_clone():
    from hlaid.opensees.script import model_data

    with pytest.raises(InputError, match="coupling"):
        model_data(_frame())
