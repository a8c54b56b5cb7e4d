"""Mass-normalised identification, end to end: when a measurement has no masses, HLA, the
identification, the clone file and the replay work per unit of relative masses (the
``force.mass_ratios``, normalised to sum to 1), and the clone still predicts drifts.

The references are independent of the identification: the dynamics of a shear building depend
on k/m only (a building with masses m/M and stiffnesses k0/M responds exactly as the original),
and the true Table 1 building simulated under a record it was not identified from.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid import identify_clone
from hlaid.clone import Clone
from hlaid.hla import HLAConfig, run_hla
from hlaid.hla.config import ForceConfig
from hlaid.hla.features import half_cycle_features
from hlaid.identify import IdentifyConfig, OuterConfig, RefineConfig, TrainingConfig
from hlaid.identify.regression import story_delta_eta, story_yield_displacement
from hlaid.identify.replaycheck import corrcoef
from hlaid.simulate import simulate_response
from hlaid.synthetic import simulate_measurement


@pytest.fixture(scope="module")
def record():
    return window(paper_record("kocaeli-1999-dzc180"), 14.0, before_peak=4.0)


def _withheld(meas):
    return dataclasses.replace(meas, mass=None)


def _config(ratios, **kw) -> IdentifyConfig:
    return IdentifyConfig(hla=HLAConfig(force=ForceConfig(mass_ratios=ratios)),
                          training=TrainingConfig(samples=60, n_segments=8),
                          outer=OuterConfig(max_iterations=1), **kw)


def test_scaled_building_responds_identically(table1, records):
    """Masses m/M and stiffnesses k0/M (P-Delta with heights and default gravity m g) give the
    same drifts, accelerations and eta as the original building: what a mass-normalised clone rests on."""
    b = table1.replace(height=np.array([3000.0, 3000.0, 3000.0]), pdelta=True)
    M = float(b.mass.sum())
    scaled = b.replace(mass=b.mass / M, k0=b.k0 / M)
    r = simulate_response([b, scaled], records["elcentro-1940-ns"])
    assert np.all(r.status == 0)
    for name in ("drift", "acc", "eta"):
        a, s = getattr(r, name)
        assert np.allclose(s, a, rtol=1e-9, atol=1e-9 * np.max(np.abs(a))), name
    assert np.allclose(r.force[1] * M, r.force[0], rtol=1e-9, atol=1e-6)


def test_hla_and_regressions_are_equivariant(table1, record):
    """HLA of a measurement with its masses withheld (right mass ratios) gives k0 / M, the same
    half cycles, ke / M and the same delta_eta and dy regressions as with the masses."""
    meas = simulate_measurement(table1, record, noise_rms=0.05, seed=4)
    M = float(table1.mass.sum())
    known = run_hla(meas)
    norm = run_hla(_withheld(meas), HLAConfig(force=ForceConfig(mass_ratios=list(table1.mass))))
    assert not known.mass_normalised and norm.mass_normalised
    assert np.allclose(norm.mass, table1.mass / M) and norm.units["stiffness"].startswith("N/mm/t")
    assert np.allclose(norm.k0 * M, known.k0, rtol=1e-8)
    for a, b in zip(known.stories, norm.stories):
        assert np.array_equal(a.half_cycles.start, b.half_cycles.start) and a.yielded == b.yielded
        assert np.allclose(b.half_cycles.ke * M, a.half_cycles.ke, rtol=1e-8)
        i = a.story - 1
        fa, fb = (half_cycle_features(s, 8, with_ke=True) for s in (a, b))
        assert np.allclose(fa.values, fb.values, rtol=1e-8, atol=1e-12)
        kw = {"alpha": table1.alpha[i]}
        de_a = story_delta_eta(a, mass=table1.mass[i], k0=known.k0[i], **kw)
        de_b = story_delta_eta(b, mass=norm.mass[i], k0=norm.k0[i], **kw)
        assert de_b.value == pytest.approx(de_a.value, rel=1e-8)
        dy_a = story_yield_displacement(a, fa, p=table1.p[i], k0=known.k0[i], **kw)
        dy_b = story_yield_displacement(b, fb, p=table1.p[i], k0=norm.k0[i], **kw)
        assert dy_b.value == pytest.approx(dy_a.value, rel=1e-8)


def test_equal_ratios_are_the_default(table1, record):
    meas = simulate_measurement(table1, record, noise_rms=0.0)
    res = run_hla(_withheld(meas))
    assert res.mass_normalised and np.allclose(res.mass, 1.0 / 3.0)


def test_clone_without_masses_predicts_another_record(table1, record, records, tmp_path):
    """Noise-free Table 1 data, masses withheld, right mass ratios: identify -> clone JSON ->
    Clone.load -> replay under El Centro (not the identification record) against the true
    building: R >= 0.98 per floor, peak drifts within 5 %; stiffness ratios, alpha, p, dy and
    delta_eta close to the truth; masses and stiffnesses per unit total mass."""
    meas = simulate_measurement(table1, record, noise_rms=0.0)
    res = identify_clone(_withheld(meas), _config(list(table1.mass / table1.mass[0])), cache_dir="")
    path = res.clone.save(tmp_path / "clone.json")
    clone = Clone.load(path)
    b, M = clone.building, float(table1.mass.sum())
    assert clone.mass_normalised and clone.to_dict()["mass_normalised"] is True
    assert np.allclose(b.mass, table1.mass / M, rtol=1e-12)
    assert np.allclose((b.k0 / b.k0[0]) / (table1.k0 / table1.k0[0]), 1.0, atol=0.02)
    assert np.allclose(b.k0 * M, table1.k0, rtol=0.02)
    assert np.allclose(b.alpha, table1.alpha, atol=0.02)
    for name in ("p", "dy", "delta_eta"):
        assert np.allclose(getattr(b, name), getattr(table1, name), rtol=0.10), name
    other = records["elcentro-1940-ns"]
    true, pred = simulate_response(table1, other), simulate_response(b, other)
    assert pred.status[0] == 0
    assert np.all(corrcoef(pred.disp[0], true.disp[0]) >= 0.98)
    assert np.allclose(pred.peak_drift, true.peak_drift, rtol=0.05)


@pytest.mark.slow
def test_identification_equivariant_to_withheld_masses(table1, record):
    """The paper's method (no refinement) with masses known or withheld (right ratios) gives the
    same alpha, p, dy, delta_eta and k0 / M (the whole pipeline, classifiers included)."""
    meas = simulate_measurement(table1, record, noise_rms=0.05, seed=1)
    cfg = _config(list(table1.mass), refine=RefineConfig(method="none"))
    known = identify_clone(meas, cfg, cache_dir="").paper_estimate
    norm = identify_clone(_withheld(meas), cfg, cache_dir="").paper_estimate
    for name in ("alpha", "p", "dy", "delta_eta"):
        assert np.allclose(getattr(norm, name), getattr(known, name), rtol=1e-6), name
    assert np.allclose(norm.k0 * table1.mass.sum(), known.k0, rtol=1e-6)
