"""Settings chosen from the data (``"auto"``, :mod:`hlaid.hla.auto`, :mod:`hlaid.identify.auto`).

Each rule on simulated records whose answer is known: a linear frame whose floors are also
coupled by a bending stiffness (as joint rotations couple a moment frame's stories: its second
mode is not a shear building's) against the same frame without it; a building damped less than
HLA assumes against one damped as assumed; a file with floor displacements against one without;
known against unknown masses. On the paper's Table 1 case the rules give the settings the
identification used before they were chosen from the data.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import paper_record, window
from scipy import linalg, signal

from hlaid import identify_clone
from hlaid.clone import Clone
from hlaid.config import load_config
from hlaid.errors import InputError
from hlaid.hla import Choice, HLAConfig, resolve_hla, run_hla
from hlaid.hla import analysis as hla_analysis
from hlaid.hla.auto import shear_frequencies
from hlaid.hla.config import PreprocessConfig, auto_hla_config
from hlaid.identify import IdentifyConfig, OuterConfig, RefineConfig, TrainingConfig
from hlaid.identify.auto import Resolution, damping_ran_away, held_damping, records_band, resolve_like, resolve_settings
from hlaid.identify.config import ResolvedSettings
from hlaid.measurement import Measurement
from hlaid.model import Damping
from hlaid.motions import load_builtin
from hlaid.synthetic import simulate_measurement

REPO_CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FIXED = {"hla.preprocess.band_hz": None, "hla.force.damping": "rayleigh", "hla.stiffness.yield_ratio": 0.6,
         "refine.method": "eiv", "refine.band_hz": [0.1, 20.0],
         "refine.parameters": ["k0", "alpha", "p", "dy", "delta_eta"], "refine.damping": False,
         "refine.compare": "acc"}
"""The settings of the identification before they were chosen from the data."""


def _shear_matrix(k: np.ndarray) -> np.ndarray:
    n = len(k)
    K = np.diag(k + np.append(k[1:], 0.0))
    for i in range(n - 1):
        K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    return K


def _bending_matrix(n: int, kb: float) -> np.ndarray:
    """A stiffness on the second differences of the floor displacements (curvature of a
    cantilever fixed at the ground): it stiffens the modes with more curvature, the higher ones."""
    D = np.zeros((n, n))
    for j in range(n):
        D[j, j] = 1.0
        if j >= 1:
            D[j, j - 1] = -2.0
        if j >= 2:
            D[j, j - 2] = 1.0
    return kb * D.T @ D


def _linear(K: np.ndarray, mass: np.ndarray, *, zeta: float = 0.03, pga_g: float = 0.3, noise: float = 0.02,
            with_disp: bool = False, seed: int = 0) -> tuple[Measurement, np.ndarray]:
    """A linear building (stiffness matrix ``K``, modal damping ``zeta``) under El Centro at
    200 Hz by modal superposition, noise on every channel; its natural frequencies [Hz]."""
    gm = load_builtin("elcentro-1940-ns").resampled(200.0).scaled_to_pga(pga_g)
    n, t, ag = len(mass), np.arange(gm.npts) * gm.dt, np.asarray(gm.acc)
    w2, phi = linalg.eigh(K, np.diag(mass))
    gamma = phi.T @ (mass * np.ones(n))
    rel = np.zeros((gm.npts, n))
    for j in range(n):
        _, q, _ = signal.lsim(([-gamma[j]], [1.0, 2 * zeta * np.sqrt(w2[j]), w2[j]]), ag, t)
        rel += np.outer(q, phi[:, j])
    acc = np.gradient(np.gradient(rel, gm.dt, axis=0), gm.dt, axis=0) + ag[:, None]
    rng = np.random.default_rng(seed)
    meas = Measurement(dt=gm.dt, ground_acc=ag + noise * ag.std() * rng.standard_normal(ag.size),
                       floor_acc=acc + noise * acc.std(axis=0) * rng.standard_normal(acc.shape), mass=mass,
                       floor_disp=rel if with_disp else None, name="linear")
    return meas, np.sqrt(w2) / (2 * np.pi)


MASS = np.full(3, 1.0 / 3.0)
K_STORY = np.array([135.0, 82.5, 60.0])  # per unit total mass: first mode near 1.2 Hz


@pytest.fixture(scope="module")
def frame():
    """The moment-frame-like building: its second mode 1.4x the shear building's."""
    return _linear(_shear_matrix(K_STORY) + _bending_matrix(3, K_STORY.mean()), MASS)


@pytest.fixture(scope="module")
def shear():
    return _linear(_shear_matrix(K_STORY), MASS)


def _chosen(resolution) -> dict:
    return {c.setting: c.value for c in resolution.choices}


def test_a_frame_not_shear_above_its_first_mode_gets_a_first_mode_band(frame):
    meas, f = frame
    assert f[1] / shear_frequencies(K_STORY, MASS)[1] > 1.3  # the bending stiffness moves the second mode
    r = resolve_settings(meas, IdentifyConfig())
    got = _chosen(r)
    lo, hi = got["hla.preprocess.band_hz"]
    assert lo == pytest.approx(0.25 * f[0], rel=0.1)
    assert hi == pytest.approx(np.sqrt(f[0] * f[1]), rel=0.1)
    assert hi < 3 * f[0] and got["hla.stiffness.yield_ratio"] == 0.8  # the low-pass cuts the third harmonic
    # the replay is fitted on every mode the records hold, not in HLA's band: above the frame's modes
    assert got["refine.method"] == "least_squares" and got["refine.band_hz"] == list(records_band(meas))
    assert got["refine.band_hz"][0] == 0.1 and got["refine.band_hz"][1] > max(f)
    assert r.config.hla.preprocess.band_hz == (lo, hi) and not r.config.unresolved()
    assert "not a shear building above its first mode" in r.choices[0].reason


def test_a_shear_building_keeps_its_own_band(shear):
    meas, f = shear
    r = resolve_settings(meas, IdentifyConfig())
    got = _chosen(r)
    assert got["hla.preprocess.band_hz"] is None and r.config.hla.preprocess.band_hz is None
    assert "second mode is a shear building's" in r.choices[0].reason
    assert got["hla.stiffness.yield_ratio"] == 0.6
    assert got["refine.method"] == "eiv" and got["refine.band_hz"] == [0.1, 20.0]
    assert run_hla(meas, r.config.hla).band_hz[1] >= 4 * f[0]


def test_table1_gets_the_fixed_settings(table1):
    """A simulated shear building with known masses, its true 5 % Rayleigh damping and 10 % noise,
    yielding: every rule gives the former fixed value, so the Table 1 results stay as they were."""
    meas = simulate_measurement(table1, paper_record("elcentro-1940-ns"), noise_rms=0.10, seed=0)
    r = resolve_settings(meas, IdentifyConfig())
    assert _chosen(r) == {**FIXED, "hla.preprocess.displacement": "integrate", "system": None}
    assert r.config.refine == RefineConfig(method="eiv", parameters=("k0", "alpha", "p", "dy", "delta_eta"),
                                           damping=False, band_hz=(0.1, 20.0), compare="acc")


@pytest.mark.parametrize("zeta,expected", [(0.01, "regression"), (0.05, "rayleigh")])
def test_damping_regression_where_the_assumed_damping_over_corrects(table1, zeta, expected):
    """Table 1 nearly elastic (PGA 0.05 g) with 1 % or its 5 % damping; HLA assumes 5 %."""
    gm = load_builtin("elcentro-1940-ns").scaled_to_pga(0.05).resampled(200.0)
    meas = simulate_measurement(table1.replace(damping=Damping(ratio=zeta)), gm, noise_rms=0.05, seed=0)
    r = resolve_settings(meas, IdentifyConfig())
    got = _chosen(r)
    assert got["hla.force.damping"] == expected
    assert got["refine.damping"] is (expected == "regression")  # the replay fits the damping it does not know


def test_displacements_of_the_file_are_used():
    K = _shear_matrix(K_STORY)
    with_disp, _ = _linear(K, MASS, with_disp=True)
    without, _ = _linear(K, MASS)
    assert _chosen(resolve_hla(with_disp, auto_hla_config()))["hla.preprocess.displacement"] == "measured"
    assert _chosen(resolve_hla(without, auto_hla_config()))["hla.preprocess.displacement"] == "integrate"


def test_yield_ratio_follows_the_low_pass_corner(shear):
    meas, f = shear  # f1 about 1.2 Hz
    cfg = dataclasses.replace(auto_hla_config(), preprocess=PreprocessConfig(band_hz=(0.3, 2.5)))
    assert resolve_hla(meas, cfg).config.stiffness.yield_ratio == 0.8
    cfg = dataclasses.replace(cfg, preprocess=PreprocessConfig(band_hz=(0.3, 20.0)))
    assert resolve_hla(meas, cfg).config.stiffness.yield_ratio == 0.6


def test_k0_is_refined_only_where_the_masses_are_known(shear):
    meas, _ = shear
    params = "refine.parameters"
    assert _chosen(resolve_settings(meas, IdentifyConfig()))[params][0] == "k0"
    unknown = dataclasses.replace(meas, mass=None)
    assert "k0" not in _chosen(resolve_settings(unknown, IdentifyConfig()))[params]
    ratios = IdentifyConfig(hla=dataclasses.replace(auto_hla_config(), force=dataclasses.replace(
        auto_hla_config().force, mass_ratios=[1.0, 1.0, 1.0])))
    assert _chosen(resolve_settings(unknown, ratios))[params][0] == "k0"


def test_values_given_override(frame):
    meas, _ = frame
    cfg = IdentifyConfig(refine=RefineConfig(method="eiv", band_hz=(0.2, 10.0)))
    r = resolve_settings(meas, cfg)
    assert r.config.refine.method == "eiv" and r.config.refine.band_hz == (0.2, 10.0)
    assert {"refine.method", "refine.band_hz"}.isdisjoint(_chosen(r))
    assert r.config.hla.preprocess.band_hz is not None  # the rest still chosen


def test_a_config_file_overrides_only_what_it_gives(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text("hla:\n  force: {mass_ratios: [1.0, 1.0, 0.5]}\nrefine: {max_iterations: 5}\n")
    cfg = load_config(p, IdentifyConfig)
    assert cfg.hla.force.mass_ratios == [1.0, 1.0, 0.5] and cfg.refine.max_iterations == 5
    assert set(cfg.unresolved()) == {"hla.preprocess.band_hz", "hla.force.damping", "hla.stiffness.yield_ratio",
                                     "refine.method", "refine.parameters", "refine.damping", "refine.band_hz",
                                     "refine.compare"}
    steel = load_config(REPO_CONFIGS / "identify_steel_frame.yaml", IdentifyConfig)
    assert steel.unresolved() == ["refine.compare"] and steel.hla.preprocess.band_hz == (0.3, 2.5)
    assert HLAConfig().unresolved() == []  # HLA on its own keeps fixed defaults


def test_hla_resolves_auto_and_its_analysis_refuses_it(shear):
    meas, _ = shear
    res = run_hla(meas, auto_hla_config())
    assert res.config.unresolved() == [] and res.config.force.damping in ("rayleigh", "regression")
    with pytest.raises(InputError, match="'auto'"):
        hla_analysis.run_hla(meas, auto_hla_config())


def test_more_records_of_a_clone_are_analysed_as_it_was(frame, shear):
    """An update (``resolve_like``) takes the clone's choices, not the new record's."""
    chosen = resolve_settings(frame[0], IdentifyConfig())
    again = resolve_like(chosen.record(), shear[0], IdentifyConfig())
    assert again.config.hla.preprocess.band_hz == chosen.config.hla.preprocess.band_hz
    assert again.config.refine == chosen.config.refine
    kept = [c for c in again.choices if c.setting not in ("hla.preprocess.displacement", "system")]  # not kept
    assert len(kept) == 8 and all(c.reason.startswith("as the clone was identified") for c in kept)
    assert resolve_like(None, shear[0], IdentifyConfig()).config.hla.preprocess.band_hz is None


def test_the_clone_keeps_the_choices(table1, tmp_path):
    meas = simulate_measurement(table1, window(paper_record("kocaeli-1999-dzc180"), 14.0, before_peak=4.0),
                                noise_rms=0.05, seed=0)
    cfg = IdentifyConfig(training=TrainingConfig(samples=60, n_segments=8), outer=OuterConfig(max_iterations=1),
                         refine=RefineConfig(method="none"))
    clone = identify_clone(meas, cfg, cache_dir="").clone
    settings = Clone.load(clone.save(tmp_path / "c.json")).settings
    assert settings is not None
    got = {c.setting: c.value for c in settings.choices}
    assert got["hla.preprocess.band_hz"] is None and got["hla.force.damping"] == "rayleigh"
    assert "refine.method" not in got  # given: not chosen
    assert all(c.reason for c in settings.choices)
    assert settings.value("hla.force.damping") == "rayleigh"
    assert settings.given is not None and settings.given["hla"]["force"]["damping"] == "auto"  # as given
    assert all(settings.value(k) not in (None, "auto") for k in ResolvedSettings.KEYS if k != "refine.method")


def test_a_damping_ratio_fitted_to_its_bound_is_held(table1):
    """A fit that runs the damping ratio to the model's bound took up model error with it: the
    identification holds it and fits again, and the choice says why."""
    cfg = IdentifyConfig(refine=RefineConfig(damping=True))
    settings = Resolution(config=cfg, choices=(Choice("refine.damping", True, "HLA's damping is regression"),))
    assert damping_ran_away(cfg, table1.replace(damping=Damping(ratio=0.5)))
    assert not damping_ran_away(cfg, table1.replace(damping=Damping(ratio=0.02)))
    assert not damping_ran_away(IdentifyConfig(refine=RefineConfig(damping=False)),
                                table1.replace(damping=Damping(ratio=0.5)))
    held = held_damping(settings, 0.5, 0.04)
    assert held.config.refine.damping is False and [c.setting for c in held.choices] == ["refine.damping"]
    assert held.choices[0].value is False and "ran to 0.50" in held.choices[0].reason
