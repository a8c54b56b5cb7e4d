"""The clone's modes an engineer checks: against the complex eigenvalues of the first-order system
(an independent reference), their flags, and their place in the clone file."""

import numpy as np
import pytest
import scipy.linalg

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.joint.vector import RATIO_BOUNDS, _ratio_of, at_limit
from hlaid.model import Building, Damping
from hlaid.model.modes import ModalCheck, Mode, clone_modes, modal_check


def _building(ratio=0.03, ratio2=None):
    return Building(mass=[2.0, 1.5, 1.0], k0=[3000.0, 2000.0, 1200.0], alpha=[0.1] * 3, p=[2.0] * 3,
                    dy=[10.0] * 3, delta_eta=[0.0] * 3, damping=Damping(ratio=ratio, ratio2=ratio2))


def test_modes_match_the_state_space_eigenvalues():
    b = _building(0.03, 0.08)
    M, K, C = np.diag(b.mass), b.stiffness_matrix(), b.damping_matrix()
    n = 3
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam = scipy.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]
    modes = clone_modes(b)
    np.testing.assert_allclose([m.frequency_hz for m in modes], np.abs(lam) / (2 * np.pi), rtol=1e-9)
    np.testing.assert_allclose([m.damping_ratio for m in modes], -lam.real / np.abs(lam), rtol=1e-9)
    np.testing.assert_allclose([m.damping_ratio for m in modes[:2]], [0.03, 0.08], rtol=1e-9)
    for m in modes:  # K phi = w^2 M phi, roof at 1
        phi = np.asarray(m.shape)
        assert phi[-1] == pytest.approx(1.0)
        np.testing.assert_allclose(K @ phi, (2 * np.pi * m.frequency_hz) ** 2 * M @ phi, rtol=1e-8, atol=1e-8)


def test_flags_say_implausible_damping_and_frequencies_off_the_records():
    b = _building(0.025, 0.5)
    check = modal_check(b, "steel-moment-frame")
    assert check.damping_max == pytest.approx(0.10)
    (flag,) = check.flags()
    assert "mode 2 50.0 %" in flag and "mode 1" not in flag
    assert modal_check(_building(0.03, 0.05), "steel-moment-frame").flags() == []
    records = tuple(Mode(m.frequency_hz * f, 0.02, m.shape) for m, f in zip(check.clone, (1.0, 1.2, 0.95)))
    flags = ModalCheck(check.clone, records, 1.0, "generic").flags()
    assert len(flags) == 1 and "mode 2" in flags[0] and "mode 1" not in flags[0] and "mode 3" not in flags[0]


def test_the_search_clip_is_a_bound():
    assert _ratio_of(5.0) == RATIO_BOUNDS[1]
    assert at_limit("damping2", _ratio_of(5.0)) and at_limit("damping", _ratio_of(-50.0))
    assert not at_limit("damping", 0.05)
    assert at_limit("alpha", 0.0) and not at_limit("alpha", 0.1)


def test_clone_file_keeps_the_modes_and_older_files_load():
    b = _building()
    clone = Clone(building=b, system="steel-moment-frame", modes=modal_check(b, "steel-moment-frame"))
    d = clone.to_dict()
    back = Clone.from_dict(d)
    assert back.modes == clone.modes
    d.pop("modes")
    assert Clone.from_dict(d).modes is None
    d["modes"] = {"clone": [{"frequency_hz": -1, "damping_ratio": 0.1, "shape": [1]}]}
    with pytest.raises(InputError, match="modes.clone"):
        Clone.from_dict(d, source="c.json")
