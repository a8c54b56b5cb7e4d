"""The batch simulator against independent references, and its physical invariants.

- alpha = 1 (linear): exact piecewise-linear-input solution by ``scipy.signal.lsim``;
- nonlinear Table 1: ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-10) on the model written
  again in numpy (``reference_systems``);
- RK4 convergence order, the compiled kernel against the torch module;
- invariants: |z| <= dy, unloading slope = ke (eq 11), energy balance;
- docs/DESIGN.md's sanity figures (loose regression), batching, layouts and errors.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import RECORDS, random_building, rel_err, story_drift, window
from reference_systems import ShearBuildingRef, energy_terms

from hlaid.errors import InputError
from hlaid.model import Building, Damping
from hlaid.motions import GroundMotion
from hlaid.simulate import HISTORY_FIELDS, simulate_response


def _ref(b: Building) -> ShearBuildingRef:
    return ShearBuildingRef(b.mass, b.k0, b.alpha, b.p, b.dy, b.delta_eta, ratio=b.damping.ratio,
                            kg=b.geometric_stiffness())


def _with_pdelta(b: Building) -> Building:
    return b.replace(height=np.full(b.n_stories, 3000.0), pdelta=True)


# ---------------------------------------------------------------------- linear: exact reference
@pytest.mark.parametrize("pdelta", [False, True])
def test_linear_matches_lsim(table1, records, pdelta):
    """alpha = 1: the response equals the exact solution for piecewise-linear ground motion."""
    b = table1.replace(alpha=np.ones(3))
    b = _with_pdelta(b) if pdelta else b
    errs = []
    for gm in records.values():
        r = simulate_response(b, gm, substeps=4)
        errs.append(rel_err(r.disp[0], _ref(b).linear_response(gm.acc, gm.dt)))
    assert max(errs) <= 1e-6, errs  # measured about 3e-8 (mean) / 5e-8 (worst)


@pytest.mark.parametrize("n", [1, 2, 5, 10, 20])
def test_linear_any_number_of_stories(n):
    rng = np.random.default_rng(n)
    b = random_building(rng, n, alpha=np.ones(n), k0=rng.uniform(2e4, 5e4, n), mass=rng.uniform(20, 50, n))
    gm = GroundMotion(dt=0.01, acc=2000.0 * np.sin(2 * np.pi * 1.3 * np.arange(800) * 0.01) * rng.normal(1, 0.3, 800))
    r = simulate_response(b, gm, substeps=8)
    assert r.disp.shape == (1, 800, n)
    assert rel_err(r.disp[0], _ref(b).linear_response(gm.acc, gm.dt)) <= 1e-6


def test_rk4_fourth_order(table1, records):
    """Error against the exact linear solution falls as h^4 (coarse 50 Hz input, 2-32 sub-steps)."""
    b = table1.replace(alpha=np.ones(3))
    src = records["elcentro-1940-ns"]
    gm = GroundMotion(dt=0.02, acc=src.acc[::4][:600])
    exact = _ref(b).linear_response(gm.acc, gm.dt)
    subs = np.array([2, 4, 8, 16, 32])
    errs = [np.abs(simulate_response(b, gm, substeps=int(s)).disp[0] - exact).max() for s in subs]
    slope = np.polyfit(np.log(gm.dt / subs), np.log(errs), 1)[0]
    assert slope == pytest.approx(4.0, abs=0.15), (slope, errs)  # measured 4.00


# ---------------------------------------------------------------------- nonlinear: solve_ivp
def test_table1_matches_solve_ivp(table1, records):
    """Table 1 at 0.62 g: 10 s around the peak of three real records vs DOP853 at rtol 1e-10."""
    ref = _ref(table1)
    peak_errs, hist_errs = [], []
    for gm in records.values():
        w = window(gm, 10.0)
        states = ref.solve(w.acc, w.dt, rtol=1e-10, atol=1e-10)
        x_ref = story_drift(states[:, :3])
        r = simulate_response(table1, w, substeps=4)
        assert (np.abs(x_ref).max(axis=0) > 3.0 * table1.dy).all()  # well into the nonlinear range
        peak_errs.append(np.abs(r.peak_drift[0] / np.abs(x_ref).max(axis=0) - 1.0).max())
        hist_errs.append(rel_err(r.drift[0], x_ref))
        np.testing.assert_allclose(r.z[0], states[:, 6:9], atol=1e-3 * table1.dy.min())
        # floor accelerations are absolute: relative acceleration + ground acceleration
        acc_ref = np.stack([ref.rhs(y, a)[3:6] + a for y, a in zip(states, w.acc)])
        assert rel_err(r.acc[0], acc_ref) <= 1e-4
    assert max(peak_errs) <= 1e-3, peak_errs  # measured <= 1e-5
    assert max(hist_errs) <= 1e-4, hist_errs  # measured about 1e-5


# ---------------------------------------------------------------------- compiled kernel vs torch module
def test_numba_matches_torch_module():
    """100 random buildings x 2 real records (8 s at 100 Hz): numba kernel == torch module.

    Half of the buildings carry P-Delta; damping models are drawn from every kind."""
    from conftest import paper_record

    from hlaid.model import DAMPING_KINDS, Damping
    rng = np.random.default_rng(2024)
    buildings = []
    for k in range(100):
        extra = {"height": rng.uniform(2500, 4000, 3), "pdelta": True} if k % 2 else {}
        damping = Damping(kind=str(rng.choice(sorted(DAMPING_KINDS))), ratio=float(rng.uniform(0.0, 0.1)))
        buildings.append(random_building(rng, 3, damping=damping, **extra))
    assert sum(b.pdelta_active for b in buildings) == 50
    motions = [window(paper_record(name).resampled(100.0), 8.0) for name in RECORDS[:2]]
    a = simulate_response(buildings, motions, substeps=4, backend="numba")
    b = simulate_response(buildings, motions, substeps=4, backend="torch")
    assert (a.status == 0).all() and (b.status == 0).all()
    worst = 0.0
    for name in HISTORY_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        scale = np.abs(y).max(axis=1)  # per element and story
        worst = max(worst, float((np.abs(x - y).max(axis=1) / np.maximum(scale, 1e-300)).max()))
    assert worst <= 1e-8, worst  # measured about 1e-13
    np.testing.assert_allclose(a.peak_drift, b.peak_drift, rtol=1e-8)
    np.testing.assert_allclose(a.peak_acc, b.peak_acc, rtol=1e-8)


# ---------------------------------------------------------------------- invariants
def _reversal_slopes(r, b: Building, i: int):
    """Secant slope df/dx over the first sample after every drift-velocity reversal of story i
    on the unloading branch (dx*z < 0), with the eq-11 prediction at the same time."""
    x, f, z, eta = r.drift[0, :, i], r.force[0, :, i], r.z[0, :, i], r.eta[0, :, i]
    xd = story_drift(r.vel[0])[:, i]
    s = np.sign(xd)
    k = np.nonzero(s[1:] != s[:-1])[0] + 1  # first sample in the new direction
    k = k[k + 1 < len(x)]
    c = k + 1
    ok = (s[k] == s[c]) & (xd[k] * z[k] < 0) & (xd[c] * z[c] < 0) & (z[k] * z[c] > 0) & \
         (np.abs(x[c] - x[k]) > 1e-3 * b.dy[i])
    k, c = k[ok], c[ok]
    slope = (f[c] - f[k]) / (x[c] - x[k])
    eta_mid = 0.5 * (eta[k] + eta[c])
    ke = b.alpha[i] * b.k0[i] + (1.0 - b.alpha[i]) * b.k0[i] / eta_mid  # eq 11, written out
    return slope, ke


def test_unloading_slope_is_ke(table1, records):
    """Right after each reversal the story unloads along ke = alpha k0 + (1-alpha) k0 / eta (eq 11)."""
    worst, count = 0.0, 0
    for gm in records.values():
        r = simulate_response(table1, gm, substeps=4)
        for i in range(3):
            slope, ke = _reversal_slopes(r, table1, i)
            assert len(slope) >= 50
            count += len(slope)
            worst = max(worst, np.abs(slope / ke - 1.0).max())
            # degradation shows: ke has dropped well below k0 by the end of the record
            assert ke.min() < 0.8 * table1.k0[i]
    assert worst <= 1e-4, worst  # measured about 1e-5 over ~1200 reversals
    assert count > 600


def test_loading_branch_is_softer_than_unloading(table1, records):
    """Near yield (|z| > 0.9 dy, loading) the tangent is far below ke: the law does switch branch."""
    r = simulate_response(table1, records["elcentro-1940-ns"], substeps=4)
    x, f, z = r.drift[0], r.force[0], r.z[0]
    xd = story_drift(r.vel[0])
    for i in range(3):
        m = (xd[:-1, i] * z[:-1, i] > 0) & (xd[1:, i] * z[1:, i] > 0) & (np.abs(z[:-1, i]) > 0.9 * table1.dy[i])
        j = np.nonzero(m)[0]
        tangent = (f[j + 1, i] - f[j, i]) / (x[j + 1, i] - x[j, i])
        ke_min = table1.elastic_stiffness(r.eta[0, -1])[i]
        assert len(j) > 50 and tangent.max() < 0.8 * ke_min


def test_z_never_exceeds_dy(table1, records):
    rng = np.random.default_rng(7)
    buildings = [table1] + [random_building(rng, 3) for _ in range(20)]
    motions = [window(gm, 12.0) for gm in records.values()]
    r = simulate_response(buildings, motions, [0.5, 1.0, 2.0], substeps=4)
    assert (r.status == 0).all()
    dy = np.stack([b.dy for b in buildings])[r.building_index]
    ratio = np.nanmax(np.abs(r.z), axis=1) / dy
    assert ratio.max() <= 1.0 + 1e-6, ratio.max()
    assert ratio.max() > 0.99  # the bound is reached, not trivially satisfied


@pytest.mark.parametrize("pdelta", [False, True])
def test_energy_balance(table1, records, pdelta):
    """input = kinetic + damping + elastic + hysteretic (+ P-Delta potential), at every time."""
    b = _with_pdelta(table1) if pdelta else table1
    for gm in records.values():
        r = simulate_response(b, gm, substeps=4)
        E = energy_terms(dt=gm.dt, mass=b.mass, C=b.damping_matrix(), alpha=b.alpha, k0=b.k0,
                         kg=b.geometric_stiffness(), ag=gm.acc, drift=r.drift[0], vel=r.vel[0], z=r.z[0])
        out = E["kinetic"] + E["damping"] + E["elastic"] + E["hysteretic"] + E["pdelta"]
        err = np.abs(E["input"] - out).max() / np.abs(E["input"]).max()
        assert err <= 0.01, err  # measured about 3e-4 (trapezoid rule at 200 Hz)
        assert E["hysteretic"][-1] > 0.3 * E["input"][-1]  # a strongly nonlinear case
        # the simulator's own hysteretic work (a state) agrees with the trapezoid of z dx
        np.testing.assert_allclose(r.energy[0].sum(axis=1), E["hysteretic"], rtol=0,
                                   atol=1e-3 * E["hysteretic"][-1])


# ---------------------------------------------------------------------- docs/DESIGN.md sanity figures
@pytest.mark.parametrize("record,drift,ke", [
    ("elcentro-1940-ns", (37, 31, 14), (0.60, 0.57, 0.56)),
    ("kocaeli-1999-dzc180", (33, 31, 14), (0.67, 0.66, 0.69)),
])
def test_design_sanity_figures(table1, records, record, drift, ke):
    r = simulate_response(table1, records[record], substeps=4)
    np.testing.assert_allclose(r.peak_drift[0], drift, rtol=0.05)
    final_eta = r.eta[0, r.n_time[0] - 1]
    np.testing.assert_allclose(table1.elastic_stiffness(final_eta) / table1.k0, ke, atol=0.015)


# ---------------------------------------------------------------------- stories, batching, layouts
@pytest.mark.parametrize("n", [1, 2, 4, 9, 20])
def test_any_number_of_stories_runs(n, records):
    rng = np.random.default_rng(100 + n)
    buildings = [random_building(rng, n) for _ in range(3)]
    gm = window(records["kocaeli-1999-dzc180"], 4.0)
    r = simulate_response(buildings, gm, substeps=4)
    assert (r.status == 0).all()
    for name in HISTORY_FIELDS:
        assert getattr(r, name).shape == (3, gm.npts, n)
    assert r.peak_drift.shape == (3, n) and r.final_state.shape == (3, 4 * n)
    np.testing.assert_allclose(r.drift, story_drift(r.disp))
    np.testing.assert_allclose(r.peak_drift, np.abs(r.drift).max(axis=1))
    assert (r.peak_drift > 0).all()


def test_product_and_zip_layouts(table1, records):
    rng = np.random.default_rng(3)
    buildings = [table1, random_building(rng, 3)]
    motions = [window(records[name], 3.0) for name in RECORDS[:2]]
    scales = np.array([[0.5, 1.0, 1.5], [0.2, 0.4, 0.6]])  # one row per motion
    r = simulate_response(buildings, motions, scales, outputs="peaks")
    assert r.batch_size == 12 and r.disp is None
    for bi in range(2):
        for mi in range(2):
            for si in range(3):
                k = (bi * 2 + mi) * 3 + si
                assert (r.building_index[k], r.motion_index[k], r.scale[k]) == (bi, mi, scales[mi, si])
                one = simulate_response(buildings[bi], motions[mi].scaled(scales[mi, si]), outputs="peaks")
                np.testing.assert_allclose(r.peak_drift[k], one.peak_drift[0], rtol=1e-12)
    z = simulate_response(buildings, motions[0], [0.5, 1.0], pairing="zip")
    assert list(z.building_index) == [0, 1] and list(z.scale) == [0.5, 1.0]
    np.testing.assert_allclose(z.peak_drift[1], r.peak_drift[(1 * 2 + 0) * 3 + 1], rtol=1e-12)


def test_peaks_output_equals_full_output(table1, records):
    ms = [window(records[n], 4.0) for n in RECORDS]
    full = simulate_response(table1, ms)
    peaks = simulate_response(table1, ms, outputs="peaks")
    for name in ("peak_drift", "peak_acc", "residual_drift", "final_state", "status", "n_time"):
        np.testing.assert_array_equal(getattr(full, name), getattr(peaks, name))
    np.testing.assert_allclose(full.peak_acc, np.abs(full.acc).max(axis=1))


def test_damping_band_gives_the_full_product(records, monkeypatch):
    """The kernel sums the damping force over C's band only (a shear building's C is
    tridiagonal): bit for bit the full product's response, and the band is found right."""
    from hlaid.simulate import _kernel

    C = np.zeros((3, 5, 5))
    C[0] = np.diag(np.ones(5))
    C[1] = np.diag(np.ones(5)) + np.diag(np.ones(4), 1)
    C[2, 0, 4] = 2.0
    np.testing.assert_array_equal(_kernel.damping_bandwidth(C), [0, 1, 4])
    rng = np.random.default_rng(3)
    bs = [random_building(rng, 6) for _ in range(3)]
    bs.append(bs[0].replace(damping=Damping(kind="mass", ratio=0.05)))
    gm = window(records["elcentro-1940-ns"], 4.0).scaled_to_pga(0.8)
    band = simulate_response(bs, gm, outputs="acc")
    monkeypatch.setattr(_kernel, "damping_bandwidth", lambda C: np.full(len(C), C.shape[-1] - 1, dtype=np.int64))
    full = simulate_response(bs, gm, outputs="acc")
    assert np.array_equal(band.acc, full.acc) and np.isfinite(band.acc).all()


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_acc_output_equals_full_output(table1, records, backend):
    """outputs="acc" (what replays read; written by the compiled kernel itself) holds the
    same accelerations as the full run, NaN after each element's end, and nothing else."""
    a = window(records["elcentro-1940-ns"], 3.0)
    b = window(records["kocaeli-1999-dzc180"].resampled(100.0), 5.0)
    buildings = [table1, table1.replace(k0=0.8 * table1.k0)]
    full = simulate_response(buildings, [a, b], backend=backend)
    acc = simulate_response(buildings, [a, b], backend=backend, outputs="acc")
    np.testing.assert_allclose(acc.acc, full.acc, rtol=0, atol=1e-9 * np.nanmax(np.abs(full.acc)))
    assert np.array_equal(np.isnan(acc.acc), np.isnan(full.acc)) and np.isnan(acc.acc).any()
    assert acc.disp is None and acc.drift is None and acc.force is None
    for name in ("residual_drift", "final_state", "status", "n_time"):
        np.testing.assert_array_equal(getattr(full, name), getattr(acc, name))


def test_records_of_different_length_and_rate(table1, records):
    a = window(records["elcentro-1940-ns"], 3.0)                # 200 Hz, 601 samples
    b = window(records["kocaeli-1999-dzc180"].resampled(100.0), 5.0)  # 100 Hz, 501 samples
    r = simulate_response(table1, [a, b])
    assert list(r.n_time) == [601, 501] and list(r.dt) == [a.dt, b.dt]
    assert np.isnan(r.disp[1, 501:]).all() and np.isfinite(r.disp[1, :501]).all()
    np.testing.assert_array_equal(r.disp[1, :501], simulate_response(table1, b).disp[0])
    with pytest.raises(ValueError, match="different dt"):
        r.time  # noqa: B018


def test_initial_state_continues_a_run(table1, records):
    gm = window(records["elcentro-1940-ns"], 6.0)
    k = 500
    whole = simulate_response(table1, gm)
    first = simulate_response(table1, GroundMotion(dt=gm.dt, acc=gm.acc[:k + 1]))
    second = simulate_response(table1, GroundMotion(dt=gm.dt, acc=gm.acc[k:]), y0=first.final_state)
    np.testing.assert_allclose(second.disp[0], whole.disp[0, k:], rtol=0, atol=1e-12 * np.abs(whole.disp).max())
    np.testing.assert_allclose(second.eta[0], whole.eta[0, k:], rtol=1e-12)


def test_free_vibration_decays(table1, records):
    gm = window(records["elcentro-1940-ns"], 5.0)
    r = simulate_response(table1, gm, free_vibration=10.0)
    assert r.n_time[0] == gm.npts + 2000
    tail = np.abs(r.vel[0, -200:]).max()
    assert tail < 1e-3 * np.abs(r.vel[0]).max()  # 5% damping, 10 s ~ 26 periods
    # after shaking the building sways about a residual (permanent) drift, which stays put
    np.testing.assert_allclose(r.residual_drift[0], r.drift[0, -1])


def test_stop_drift_and_collapse(table1, records):
    """A heavily P-Delta-loaded, non-hardening building runs away and stops at the drift limit."""
    weak = table1.replace(alpha=np.zeros(3), height=np.full(3, 3000.0), pdelta=True,
                          gravity_load=np.full(3, 2.0e7))  # P/h far above the post-yield stiffness
    gm = window(records["kocaeli-1999-dzc180"], 6.0)
    r = simulate_response([table1, weak], gm, stop_drift=300.0)
    assert list(r.status) == [0, 1]
    assert r.n_time[0] == gm.npts and r.n_time[1] < gm.npts
    assert r.peak_drift[1].max() > 300.0 and np.isnan(r.disp[1, r.n_time[1]:]).all()
    per_story = simulate_response(table1, gm, stop_drift=np.array([1.0, 1e9, 1e9]), outputs="peaks")
    assert per_story.status[0] == 1 and per_story.n_time[0] < gm.npts


def test_divergence_is_flagged_not_returned_as_numbers(records):
    """A step far beyond RK4's stability limit gives status 2 and NaN histories after it."""
    stiff = Building(mass=[1.0], k0=[1e7], alpha=[1.0], p=[2.0], dy=[5.0], delta_eta=[0.0])
    ok = Building(mass=[10.0], k0=[1e4], alpha=[1.0], p=[2.0], dy=[5.0], delta_eta=[0.0])
    gm = window(records["kocaeli-1999-dzc180"].resampled(100.0), 20.0)
    r = simulate_response([stiff, ok], gm, substeps=1)
    assert list(r.status) == [2, 0]
    assert r.n_time[0] < gm.npts and np.isnan(r.disp[0, r.n_time[0]:]).all()
    assert np.isfinite(r.disp[1]).all()


@pytest.mark.parametrize("kwargs,match", [
    ({"backend": "fortran"}, "unknown backend 'fortran'"),
    ({"outputs": "everything"}, "outputs = 'everything'"),
    ({"substeps": 0}, "substeps = 0"),
    ({"pairing": "cross"}, "unknown pairing 'cross'"),
    ({"scales": [1.0, np.nan]}, "scale factors must be finite"),
    ({"stop_drift": np.ones((2, 2))}, "stop_drift of shape"),
    ({"backend": "torch", "stop_drift": 10.0}, "does not stop at a drift limit"),
    ({"y0": np.zeros(5)}, r"y0 of shape \(5,\); expected \(batch, 4\*story\) = \(1, 12\)"),
])
def test_bad_arguments(table1, records, kwargs, match):
    gm = window(records["elcentro-1940-ns"], 1.0)
    with pytest.raises(InputError, match=match):
        simulate_response(table1, gm, **kwargs)


def test_bad_batches(table1, records):
    gm = window(records["elcentro-1940-ns"], 1.0)
    with pytest.raises(InputError, match="pairing='zip' needs equal lengths"):
        simulate_response([table1, table1], [gm, gm, gm], pairing="zip")
    with pytest.raises(InputError, match="one row per motion"):
        simulate_response(table1, [gm, gm], np.ones((3, 2)))
    with pytest.raises(InputError, match="expected one or more GroundMotion"):
        simulate_response(table1, [])
    with pytest.raises(InputError, match="same number of stories"):
        simulate_response([table1, Building(mass=[1.0], k0=[1.0], alpha=[0.1], p=[2.0], dy=[1.0], delta_eta=[0.0])], gm)
