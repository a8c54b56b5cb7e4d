"""The records' modes: a linear output-error fit recovers a coupled frame's modes from its
simulated record (the simulator, not the fit's filters, makes the record), and the clone's
choice of linear part is a typed, round-tripped field."""

import numpy as np
import pytest

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.events.coupled import coupled_start
from hlaid.identify.modal import fit_linear, linear_response
from hlaid.model import Building, Damping
from hlaid.model.coupling import Coupling
from hlaid.model.modes import clone_modes
from hlaid.motions import GroundMotion
from hlaid.record import LinearPart
from hlaid.simulate import simulate_response


def _frame():
    return Building(mass=[1.0, 1.0, 1.0], k0=[500.0, 280.0, 300.0], alpha=[1.0] * 3, p=[2.0] * 3, dy=[5.0] * 3,
                    delta_eta=[0.0] * 3, coupling=Coupling((300.0, 300.0)),
                    damping=Damping(kind="modal", ratio=0.03, ratio2=0.02, higher=(0.025,)))


def test_fit_recovers_the_modes_of_a_simulated_record():
    b = _frame()
    rng = np.random.default_rng(3)
    dt = 1 / 128
    ag = np.convolve(rng.standard_normal(1600), np.ones(3) / 3, mode="same") * 500.0
    acc = simulate_response(b, GroundMotion(acc=ag, dt=dt), substeps=4, outputs="full").acc[0]
    np.testing.assert_allclose(linear_response(b.k0, (300.0, 300.0), (0.03, 0.02, 0.025), b.mass, ag, dt), acc,
                               atol=2e-3 * np.max(np.abs(acc)))
    fit = fit_linear(ag, acc + 0.01 * np.std(acc) * rng.standard_normal(acc.shape), dt, k_start=[300, 200, 150],
                     band_hz=(0.5, 20.0))
    truth = clone_modes(b)
    np.testing.assert_allclose([m.frequency_hz for m in fit.modes], [m.frequency_hz for m in truth], rtol=0.01)
    np.testing.assert_allclose([m.damping_ratio for m in fit.modes], [0.03, 0.02, 0.025], atol=0.005)
    for got, want in zip(fit.modes[:2], truth[:2]):
        np.testing.assert_allclose(got.shape, want.shape, atol=0.03)
    start = coupled_start(b.replace(alpha=[0.1] * 3), fit)
    assert start.coupling is not None and start.damping.kind == "modal"
    np.testing.assert_allclose([m.frequency_hz for m in clone_modes(start)], [m.frequency_hz for m in fit.modes],
                               rtol=1e-9)


def test_linear_part_is_a_typed_field_of_the_clone():
    part = LinearPart("coupled", (("shear", -10.0), ("coupled", 50.0)), "the records' modes need it", "s1")
    clone = Clone(building=_frame(), linear=part)
    assert Clone.from_dict(clone.to_dict()).linear == part
    d = clone.to_dict()
    d["linear"]["form"] = "beam"
    with pytest.raises(InputError, match="linear.form"):
        Clone.from_dict(d, source="c.json")


class _Fit:
    """A joint fit as far as the choice of linear part reads it."""

    def __init__(self, z):
        self.n_eff = np.array([100.0])
        self.z = z

    def log_evidence(self, n_eff):
        return self.z


def test_the_coupling_is_kept_only_where_its_evidence_clears_the_margin():
    from hlaid.events.coupled import choose_form

    form, part = choose_form(_Fit(0.0), _Fit(4.5), 2, "s1")
    assert form == "coupled" and part.form == "coupled" and dict(part.log_evidence)["coupled"] == 4.5
    assert choose_form(_Fit(0.0), _Fit(3.5), 2, "s1")[0] == "shear"  # 2 log units per coupling term
    assert choose_form(_Fit(0.0), None, 2, "s1")[1].log_evidence == (("shear", None), ("coupled", None))


def test_the_shear_chain_suffices_where_its_modes_reach_the_records():
    from types import SimpleNamespace

    from hlaid.events.coupled import shear_reaches
    from hlaid.model.modes import Mode

    def fit(*f, top=12.5):
        return SimpleNamespace(modes=tuple(Mode(v, 0.02, (1.0,)) for v in f), band_hz=(0.5, top))

    assert shear_reaches(fit(1.39, 5.08, 10.1), fit(1.40, 5.2, 9.5))
    assert not shear_reaches(fit(1.39, 5.08, 10.1), fit(1.58, 4.45, 6.0))
    assert shear_reaches(fit(7.8, 22.7, 31.8, top=20.0), fit(7.8, 22.7, 16.0))  # beyond the band: not the record's
