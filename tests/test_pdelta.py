"""P-Delta in the shear building: the geometric stiffness -P_i/h_i against closed forms.

* an elastic SDOF with P-Delta oscillates at sqrt((k - P/h)/m), a 3-story one in the modes of
  (K0 - Kg, M), in both the compiled kernel and the torch module;
* a static push with alpha = 0 loses stability: tangent -P/h, zero force at k0 dy / (P/h);
* a yielded SDOF whose P/h exceeds alpha*k0 has a tipping point
  x_crit = (1-alpha) k0 dy / (P/h - alpha k0): released from rest inside it, it comes back;
  just outside, it runs away to collapse;
* the IDA default turns P-Delta on when heights are known.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from hlaid.model import Building, Damping
from hlaid.motions import GroundMotion
from hlaid.simulate import simulate_response

G = 9806.65


def _still(seconds: float, dt: float = 0.002) -> GroundMotion:
    return GroundMotion(dt=dt, acc=np.zeros(round(seconds / dt) + 1), name="still")


def _sdof(**kw) -> Building:
    d = {"mass": [2.0], "k0": [800.0], "alpha": [1.0], "p": [2.0], "dy": [50.0], "delta_eta": [0.0],
         "height": [3000.0], "gravity_load": [2.0 * G * 60.0], "damping": Damping(kind="none"), "pdelta": True}
    d.update(kw)
    return Building(**d)


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_elastic_sdof_oscillates_at_reduced_frequency(backend):
    b = _sdof()
    kg = b.geometric_stiffness()[0]
    assert kg == pytest.approx(2.0 * G * 60.0 / 3000.0)
    assert 0.3 < kg / 800.0 < 0.5  # a large effect, so a missing P-Delta cannot pass
    u0 = 10.0
    gm = _still(1.5, dt=0.005)  # about 3.4 periods
    r = simulate_response(b, gm, substeps=4, y0=[u0, 0.0, u0, 0.0], backend=backend)
    w = np.sqrt((800.0 - kg) / 2.0)
    exact = u0 * np.cos(w * gm.time)
    assert np.max(np.abs(r.disp[0, :, 0] - exact)) < 1e-6 * u0
    # the same building without P-Delta follows sqrt(k/m): the test sees the difference
    r0 = simulate_response(b.replace(pdelta=False), gm, substeps=4, y0=[u0, 0.0, u0, 0.0], backend=backend)
    assert np.max(np.abs(r0.disp[0, :, 0] - exact)) > 0.5 * u0


def test_three_story_modes_of_reduced_stiffness():
    m = np.array([20.0, 18.0, 10.0])
    k = np.array([9000.0, 7000.0, 4000.0])
    h = np.array([3500.0, 3000.0, 3000.0])
    W = m * G * 8.0  # heavy gravity loads (8x the seismic weight): a strong P-Delta effect
    b = Building(mass=m, k0=k, alpha=[1.0] * 3, p=[2.0] * 3, dy=[40.0] * 3, delta_eta=[0.0] * 3, height=h,
                 gravity_load=W, damping=Damping(kind="none"), pdelta=True)
    P = np.cumsum(W[::-1])[::-1]
    assert np.allclose(b.geometric_stiffness(), P / h)
    ks = k - P / h
    K = np.diag(ks + np.append(ks[1:], 0.0)) - np.diag(ks[1:], 1) - np.diag(ks[1:], -1)
    lam, phi = linalg.eigh(K, np.diag(m))
    mode = phi[:, 0] / np.abs(phi[:, 0]).max() * 20.0
    x0 = np.diff(np.concatenate([[0.0], mode]))
    gm = _still(4.0)
    r = simulate_response(b, gm, substeps=4, y0=np.concatenate([mode, np.zeros(3), x0, np.zeros(3)]))
    exact = np.cos(np.sqrt(lam[0]) * gm.time)[:, None] * mode
    assert np.max(np.abs(r.disp[0] - exact)) < 1e-6 * 20.0
    # K0 alone would give a different frequency
    w0 = np.sqrt(linalg.eigh(np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1),
                             np.diag(m), eigvals_only=True)[0])
    assert abs(w0 / np.sqrt(lam[0]) - 1) > 0.04


def test_static_push_loses_stability_at_k0_dy_over_p_h():
    """Quasi-static push (dz/dx of the model's own law) with alpha = 0: beyond yield the tangent
    stiffness of the story force minus P-Delta tends to -P/h, and the force crosses zero at
    x = k0 dy / (P/h): the story can no longer carry its gravity load laterally."""
    from scipy.integrate import solve_ivp

    from hlaid.model import equations as eq
    k0, dy, p, kg_target = 1000.0, 20.0, 4.0, 50.0
    b = _sdof(k0=[k0], alpha=[0.0], p=[p], dy=[dy], gravity_load=[kg_target * 3000.0])
    kg = b.geometric_stiffness()[0]
    x = np.linspace(0.0, 1200.0, 6001)
    z = solve_ivp(lambda _, zz: eq.hysteretic_rate(1.0, zz, dy, p, 1.0), (0, x[-1]), [0.0], t_eval=x,
                  rtol=1e-11, atol=1e-12).y[0]
    f = eq.spring_force(x, z, 0.0, k0) - kg * x
    tangent = np.gradient(f, x)
    assert tangent[0] == pytest.approx(k0 - kg, rel=1e-3)
    assert tangent[-1] == pytest.approx(-kg, rel=1e-3)  # negative: unstable beyond the peak
    x_zero = x[np.flatnonzero(f < 0)[0]]
    assert x_zero == pytest.approx(k0 * dy / kg, rel=2e-3)


@pytest.mark.parametrize("side, collapses", [(0.90, False), (1.02, True)])
def test_dynamic_tipping_point_of_a_yielded_story(side, collapses):
    """Released from rest in the yielded state at x0 (no ground motion): a story whose P/h
    exceeds alpha*k0 comes back from inside x_crit = (1-alpha) k0 dy / (P/h - alpha k0) and runs
    away to collapse from outside it (p = 30: a nearly bilinear knee, so the reload after the
    first swing is elastic and the static threshold holds dynamically)."""
    alpha, k0, dy, m, h = 0.02, 1000.0, 20.0, 5.0, 3000.0
    kg = 3.0 * alpha * k0  # P/h = 60 N/mm > alpha k0 = 20 N/mm: negative post-yield stiffness
    b = _sdof(mass=[m], k0=[k0], alpha=[alpha], p=[30.0], dy=[dy], gravity_load=[kg * h],
              damping=Damping(kind="rayleigh", ratio=0.05))
    x_crit = (1 - alpha) * k0 * dy / (kg - alpha * k0)  # 490 mm
    x0 = side * x_crit
    r = simulate_response(b, _still(20.0), substeps=8, y0=[x0, 0.0, dy, 0.0], stop_drift=3 * x_crit, outputs="peaks")
    if collapses:
        assert r.status[0] == 1  # ran away to the drift limit
    else:
        assert r.status[0] == 0
        assert r.peak_drift[0, 0] <= x0 * (1 + 1e-9)
        assert abs(r.residual_drift[0, 0]) < x0


def test_stable_when_post_yield_stiffness_exceeds_pdelta():
    """With alpha*k0 > P/h the same push from far beyond yield returns (no tipping point)."""
    b = _sdof(mass=[5.0], k0=[1000.0], alpha=[0.1], p=[2.0], dy=[20.0], gravity_load=[60.0 * 3000.0],
              damping=Damping(kind="rayleigh", ratio=0.05))
    r = simulate_response(b, _still(20.0), y0=[2000.0, 0.0, 20.0, 0.0], stop_drift=6000.0, outputs="peaks")
    assert r.status[0] == 0 and abs(r.residual_drift[0, 0]) < 2000.0


def test_ida_turns_pdelta_on_when_heights_are_known():
    from hlaid.ida import prepare_building
    b = _sdof(pdelta=False)
    on, notes = prepare_building(b)
    assert on.pdelta_active and np.allclose(on.geometric_stiffness(), b.replace(pdelta=True).geometric_stiffness())
    assert any("pdelta: false" in n for n in notes)
    off, _ = prepare_building(b, pdelta=False)
    assert not off.pdelta_active and np.all(off.geometric_stiffness() == 0)
