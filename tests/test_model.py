"""The shear-building model: parameters, validation, matrices, the torch right-hand side.

References: the shear building written again in numpy (``reference_systems.ShearBuildingRef``),
``scipy.linalg.eigh`` for the modes, the Rayleigh definition for the damping ratios.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import random_building
from reference_systems import TABLE1, ShearBuildingRef, table1_masses
from scipy import linalg

from hlaid.errors import InputError
from hlaid.model import STORY_FIELDS, BoucWenBuilding, Building, BuildingTensors, Damping
from hlaid.units import G_MM_S2


def _ref(b: Building, ratio=0.05) -> ShearBuildingRef:
    return ShearBuildingRef(b.mass, b.k0, b.alpha, b.p, b.dy, b.delta_eta, ratio=ratio, kg=b.geometric_stiffness())


# ---------------------------------------------------------------------- construction
def test_table1_from_weights(table1):
    np.testing.assert_allclose(table1.mass, table1_masses(), rtol=1e-15)
    assert table1.mass[0] == pytest.approx(17.524, abs=5e-4)  # docs/DESIGN.md section 2: 171.85 kN -> 17.524 t
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_array_equal(getattr(table1, name), TABLE1[name])
    assert table1.n_stories == 3 and not table1.pdelta_active


def test_to_dict_round_trip():
    b = Building.from_stories([{"mass_t": 10.0, "k0": 2e4, "alpha": 0.1, "p": 2.0, "dy": 5.0, "delta_eta": 0.5,
                                "height_mm": 3200.0, "gravity_kN": 120.0}] * 2,
                              damping=Damping(kind="stiffness", ratio=0.03, modes=(1, 1)), pdelta=True, name="x")
    c = Building.from_dict(b.to_dict())
    for name in STORY_FIELDS + ("height", "gravity_load"):
        np.testing.assert_array_equal(getattr(c, name), getattr(b, name))
    assert (c.damping, c.pdelta, c.name) == (b.damping, b.pdelta, b.name)
    np.testing.assert_allclose(c.gravity_load, 120e3)


def test_arrays_are_frozen(table1):
    with pytest.raises(ValueError):
        table1.k0[0] = 1.0
    with pytest.raises(AttributeError):
        table1.k0 = np.ones(3)  # frozen dataclass


_BAD = [("mass", 0.0, "1e-06 <= mass <= 100000000 [t]"), ("mass", -1.0, "1e-06 <= mass"),
        ("k0", 0.0, "1e-06 <= k0 <= 1000000000000 [N/mm]"), ("alpha", -0.1, "0 <= alpha <= 1"),
        ("alpha", 1.2, "0 <= alpha <= 1"), ("p", 0.9, "1 <= p <= 50"), ("dy", 0.0, "1e-06 <= dy <= 100000 [mm]"),
        ("delta_eta", -0.01, "0 <= delta_eta"), ("k0", np.nan, "1e-06 <= k0"), ("dy", np.inf, "<= dy <="),
        ("dy", 1e-300, "1e-06 <= dy"), ("p", 1e300, "p <= 50")]


@pytest.mark.parametrize("field,value,form", _BAD)
def test_out_of_range_parameter_names_story_and_field(field, value, form):
    good = {"mass": [10.0] * 3, "k0": [2e4] * 3, "alpha": [0.1] * 3, "p": [2.0] * 3, "dy": [5.0] * 3,
            "delta_eta": [0.5] * 3}
    good[field] = [good[field][0], value, good[field][0]]
    with pytest.raises(InputError) as err:
        Building(**good, source="bldg.yaml")
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("bldg.yaml: story 2: ")
    assert f"{field} = " in msg and form in msg


@pytest.mark.parametrize("field,bound,outside", [("alpha", 0.0, -1e-12), ("alpha", 1.0, 1.0 + 1e-12),
                                                  ("p", 1.0, 1.0 - 1e-12), ("delta_eta", 0.0, -1e-12)])
def test_range_bounds_are_inclusive(field, bound, outside):
    """A value on an inclusive bound is kept as given; one a hair beyond it is refused."""
    good = {"mass": [1.0], "k0": [1.0], "alpha": [0.1], "p": [2.0], "dy": [1.0], "delta_eta": [0.5]}
    b = Building(**{**good, field: [bound]})
    assert getattr(b, field)[0] == bound
    with pytest.raises(InputError, match=f"{field} = "):
        Building(**{**good, field: [outside]})


def test_shape_and_story_errors():
    with pytest.raises(InputError, match="k0 has 2 values but the building has 3 stories"):
        Building(mass=[1.0] * 3, k0=[1.0] * 2, alpha=[0.1] * 3, p=[2.0] * 3, dy=[1.0] * 3, delta_eta=[0.0] * 3)
    with pytest.raises(InputError, match="at least one story"):
        Building(mass=[], k0=[], alpha=[], p=[], dy=[], delta_eta=[])
    with pytest.raises(InputError, match="story 1: give exactly one of mass_t or weight_kN"):
        Building.from_stories([{"k0": 1.0, "alpha": 0.1, "p": 2.0, "dy": 1.0, "delta_eta": 0.0}])
    with pytest.raises(InputError, match=r"story 2: missing dy"):
        Building.from_stories([{"mass_t": 1.0, "k0": 1.0, "alpha": 0.1, "p": 2.0, "dy": 1.0, "delta_eta": 0.0},
                               {"mass_t": 1.0, "k0": 1.0, "alpha": 0.1, "p": 2.0, "delta_eta": 0.0}])
    with pytest.raises(InputError, match=r"story 1: unknown field\(s\) \['kO'\]"):
        Building.from_stories([{"mass_t": 1.0, "kO": 1.0, "k0": 1.0, "alpha": 0.1, "p": 2.0, "dy": 1.0,
                                "delta_eta": 0.0}])
    with pytest.raises(InputError, match="pdelta is on but story heights are unknown"):
        Building(mass=[1.0], k0=[1.0], alpha=[0.1], p=[2.0], dy=[1.0], delta_eta=[0.0], pdelta=True)
    with pytest.raises(InputError, match="damping kind 'viscous' is unknown"):
        Damping(kind="viscous")
    with pytest.raises(InputError, match="damping.ratio"):
        Damping(ratio=1.5)
    with pytest.raises(InputError, match=r"damping.modes = \[1, 99\]: a building of 3 stories has modes 1..3"):
        Building(mass=[1.0] * 3, k0=[1.0] * 3, alpha=[0.1] * 3, p=[2.0] * 3, dy=[1.0] * 3, delta_eta=[0.0] * 3,
                 damping=Damping(modes=(1, 99)))
    Building(mass=[1.0], k0=[1.0], alpha=[0.1], p=[2.0], dy=[1.0], delta_eta=[0.0])  # one story: modes (1, 2) as ever


# ---------------------------------------------------------------------- matrices and damping
@pytest.mark.parametrize("n", [1, 2, 3, 7, 20])
def test_periods_and_matrices_against_scipy(n):
    b = random_building(np.random.default_rng(n), n)
    ref = _ref(b)
    np.testing.assert_allclose(b.stiffness_matrix(), ref.K, rtol=1e-14)
    w = np.sqrt(linalg.eigh(ref.K, ref.M, eigvals_only=True))
    np.testing.assert_allclose(b.periods(), 2 * np.pi / w, rtol=1e-10)
    np.testing.assert_allclose(b.damping_matrix(), ref.C, rtol=1e-10, atol=1e-12 * np.abs(ref.C).max())


@pytest.mark.parametrize("kind,ratios", [("rayleigh", {1: 0.05, 2: 0.05}), ("stiffness", {1: 0.05}),
                                         ("mass", {1: 0.05}), ("none", {1: 0.0, 2: 0.0})])
def test_damping_gives_the_modal_ratio(table1, kind, ratios):
    b = table1.replace(damping=Damping(kind=kind, ratio=0.05))
    C, K, M = b.damping_matrix(), b.stiffness_matrix(), np.diag(b.mass)
    lam, phi = linalg.eigh(K, M)  # mass-normalised modes: phi^T M phi = I
    zeta = np.diag(phi.T @ C @ phi) / (2.0 * np.sqrt(lam))
    for mode, z in ratios.items():
        assert zeta[mode - 1] == pytest.approx(z, abs=1e-12)
    if kind == "rayleigh":  # Rayleigh over-damps the higher modes
        assert zeta[2] > 0.05


def test_one_story_rayleigh_uses_its_only_mode():
    b = Building(mass=[10.0], k0=[1e4], alpha=[0.2], p=[2.0], dy=[5.0], delta_eta=[0.0])
    w = np.sqrt(1e4 / 10.0)
    assert b.damping_matrix()[0, 0] / (2.0 * 10.0 * w) == pytest.approx(0.05, rel=1e-12)


def test_geometric_stiffness():
    b = Building.from_stories([{"weight_kN": w, "k0": 1e4, "alpha": 0.1, "p": 2.0, "dy": 5.0, "delta_eta": 0.0,
                                "height_mm": h} for w, h in ((300.0, 4000.0), (200.0, 3000.0), (100.0, 3000.0))])
    assert b.pdelta_active
    np.testing.assert_allclose(b.geometric_stiffness(), [600e3 / 4000.0, 300e3 / 3000.0, 100e3 / 3000.0], rtol=1e-12)
    np.testing.assert_array_equal(b.replace(pdelta=False).geometric_stiffness(), 0.0)
    heavy = b.replace(gravity_load=np.array([1e6, 1e6, 1e6]))
    np.testing.assert_allclose(heavy.geometric_stiffness(), [3e6 / 4000.0, 2e6 / 3000.0, 1e6 / 3000.0])
    np.testing.assert_allclose(b.floor_gravity(), b.mass * G_MM_S2)


def test_elastic_stiffness_eq11(table1):
    eta = np.array([[1.0, 1.0, 1.0], [2.0, 3.0, 4.0]])
    ke = table1.elastic_stiffness(eta)
    np.testing.assert_allclose(ke[0], table1.k0)
    np.testing.assert_allclose(ke[1], table1.alpha * table1.k0 + (1 - table1.alpha) * table1.k0 / eta[1])


# ---------------------------------------------------------------------- the torch right-hand side
def _random_states(rng, b: Building, batch: int) -> np.ndarray:
    n = b.n_stories
    u = np.cumsum(rng.normal(0, 3 * b.dy.mean(), (batch, n)), axis=1)
    v = rng.normal(0, 300.0, (batch, n))
    z = rng.uniform(-1, 1, (batch, n)) * b.dy
    e = rng.uniform(0, 5e3, (batch, n))
    return np.concatenate([u, v, z, e], axis=1)


@pytest.mark.parametrize("n,pdelta", [(1, False), (3, True), (8, False), (20, True)])
def test_rates_against_independent_numpy_model(n, pdelta):
    """BoucWenBuilding.rates equals the model written again from docs/DESIGN.md section 3."""
    rng = np.random.default_rng(10 + n)
    kw = {"height": np.full(n, 3000.0), "pdelta": True} if pdelta else {}
    bs = [random_building(rng, n, **kw) for _ in range(4)]
    module = BoucWenBuilding.from_buildings(bs)
    for i, b in enumerate(bs):
        ref = _ref(b)
        assert (ref.kg > 0).all() == pdelta
        y = _random_states(rng, b, 16)
        ag = rng.normal(0, 3000.0, 16)
        got = module.params.index([i] * 16)
        out = BoucWenBuilding(got).rates(torch.as_tensor(y), torch.as_tensor(ag)).numpy()
        want = np.stack([ref.rhs(y[k], ag[k]) for k in range(16)])
        for j in range(4):  # du/dt, dv/dt, dz/dt, de/dt, each to its own scale
            blk = slice(j * n, (j + 1) * n)
            assert np.abs(out[:, blk] - want[:, blk]).max() <= 1e-12 * np.abs(want[:, blk]).max()


def test_batched_parameters_are_batch_by_story():
    rng = np.random.default_rng(0)
    bs = [random_building(rng, 5) for _ in range(3)]
    P = BuildingTensors.stack(bs)
    for name in STORY_FIELDS + ("kg",):
        t = getattr(P, name)
        assert t.shape == (3, 5) and t.dtype == torch.float64
    assert P.damping.shape == (3, 5, 5)
    assert P.index([2, 0]).k0[0].tolist() == bs[2].k0.tolist()
    with pytest.raises(InputError, match="same number of stories"):
        BuildingTensors.stack([bs[0], random_building(rng, 4)])
    m = BoucWenBuilding(P)
    y = m.initial_state()
    assert y.shape == (3, 20)
    assert m.rates(y, torch.zeros(3)).abs().max() == 0.0  # at rest without ground motion
    r = m.rates(y, torch.full((3,), 1000.0))
    np.testing.assert_array_equal(r[:, 5:10].numpy(), -1000.0)  # -ag on every floor


def test_ground_interpolation(table1):
    g = torch.tensor([[0.0, 10.0, -20.0, 40.0]], dtype=torch.float64)
    m = BoucWenBuilding.from_buildings(table1, ground_acc=g, dt=0.5)
    got = [float(m.ground_at(torch.tensor(t, dtype=torch.float64))[0]) for t in (0.0, 0.25, 0.5, 0.9, 1.5, 1.6)]
    np.testing.assert_allclose(got, [0.0, 5.0, 10.0, 10.0 - 30.0 * 0.8, 40.0, 0.0])


def test_rates_are_differentiable(table1):
    P = BuildingTensors.stack([table1])
    k0 = P.k0.clone().requires_grad_(True)
    m = BoucWenBuilding(BuildingTensors(**{**vars(P), "k0": k0}))
    y = torch.as_tensor(_random_states(np.random.default_rng(1), table1, 1))
    m.rates(y, torch.zeros(1))[:, 3:6].sum().backward()
    assert k0.grad is not None and torch.isfinite(k0.grad).all() and k0.grad.abs().sum() > 0
