"""Hysteresis loop analysis on the real shake-table data (skipped without ``../shared/data``).

Findings these tests hold (docs/hla.md, "Real data"; ``scripts/hla_real_data.py`` prints the
tables):

- Steel moment frame, runs s1..s4 of one ground motion at increasing scale: with a first-mode
  band (``configs/hla_steel_frame.yaml``) k0 per story does not rise from run to run (damage
  accumulates), and agrees with an independent equivalent-linear reference, ``Re(F/X)`` at the
  first mode from Welch spectra. With the default band (to 20 Hz) story 3 does not: the frame is
  not a shear building above its first mode (its story-3 ``Re(F/X)`` near the second mode is
  about twice that at the first), and the default band mixes both.
- Mini shake table (flexible and stiff models): linear; every story is reported elastic, and
  the shear building of the identified k0 reproduces the measured first mode.

References are computed here with numpy/scipy only, not with hlaid's HLA code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from io_checks import data_path
from scipy import signal

from hlaid.config import load_config
from hlaid.hla import HLAConfig, run_hla
from hlaid.io import read_mini_shake_table, read_steel_frame

STEEL = "shake_table_3story_steel_mrf_fixedbase"
MINI = "mini_shake_table_3story_model"
STEEL_CONFIG = Path(__file__).resolve().parents[1] / "configs" / "hla_steel_frame.yaml"


# ---------------------------------------------------------------------- independent references
def equal_mass_story_force(floor_acc: np.ndarray) -> np.ndarray:
    """``-sum_{j>=i} a_j / n`` (equal floor masses summing to 1), ``(time, story)``."""
    n = floor_acc.shape[1]
    return -np.flip(np.cumsum(np.flip(floor_acc, axis=1), axis=1), axis=1) / n


def re_force_over_drift(meas, lo: float, hi: float, nperseg: int = 2048) -> np.ndarray:
    """Mean ``Re(F/X)`` per story between ``lo`` and ``hi`` Hz (Welch): equivalent linear stiffness."""
    x = np.diff(meas.floor_disp, axis=1, prepend=0.0)
    f = equal_mass_story_force(meas.floor_acc)
    fs = 1.0 / meas.dt
    out = []
    for i in range(x.shape[1]):
        fr, pxf = signal.csd(x[:, i], f[:, i], fs=fs, nperseg=nperseg)
        _, pxx = signal.welch(x[:, i], fs=fs, nperseg=nperseg)
        band = (fr >= lo) & (fr <= hi)
        out.append(np.mean((pxf[band] / pxx[band]).real))
    return np.array(out)


def first_mode_hz(meas, lo: float, hi: float, nperseg: int = 2048) -> float:
    """Peak of the roof displacement spectrum (steel) between ``lo`` and ``hi`` Hz."""
    f, p = signal.welch(meas.floor_disp[:, -1], fs=1.0 / meas.dt, nperseg=nperseg)
    band = (f >= lo) & (f <= hi)
    return float(f[band][np.argmax(p[band])])


def transfer_peak_hz(meas, lo: float, hi: float, nperseg: int = 2048) -> float:
    """Frequency of the largest |roof / ground| (H1) between ``lo`` and ``hi`` Hz."""
    fs = 1.0 / meas.dt
    f, pgr = signal.csd(meas.ground_acc, meas.floor_acc[:, -1], fs=fs, nperseg=nperseg)
    _, pgg = signal.welch(meas.ground_acc, fs=fs, nperseg=nperseg)
    band = (f >= lo) & (f <= hi)
    return float(f[band][np.argmax(np.abs(pgr[band] / pgg[band]))])


def shear_building_f1(k: np.ndarray, m: np.ndarray) -> float:
    """First natural frequency [Hz] of a shear building (k [N/mm/t] with mass fractions m: s^-2)."""
    n = len(k)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        if i > 0:
            K[i - 1, i - 1] += k[i]
            K[i - 1, i] -= k[i]
            K[i, i - 1] -= k[i]
    w2 = np.linalg.eigvals(K / np.asarray(m)[:, None]).real
    return float(np.sqrt(w2.min()) / (2 * np.pi))


# ---------------------------------------------------------------------- steel moment frame
@pytest.fixture(scope="module")
def steel():
    runs = [read_steel_frame(data_path(STEEL, f"filtered_fbgm152s{s}_denoised.tsv.gz")) for s in (1, 2, 3, 4)]
    cfg = load_config(STEEL_CONFIG, HLAConfig)
    return {"runs": runs, "first_mode": [run_hla(m, cfg) for m in runs], "default": [run_hla(m) for m in runs]}


def test_steel_frame_k0_does_not_rise_from_run_to_run(steel):
    """Damage accumulates over s1..s4: k0 per story is non-increasing with the first-mode band
    and falls by more than 10 % from s1 to s4 on every story."""
    k0 = np.array([r.k0 for r in steel["first_mode"]])  # (run, story)
    assert np.all(np.diff(k0, axis=0) <= 0), k0.round(1)
    assert np.all(k0[-1] < 0.9 * k0[0]), k0.round(1)


def test_steel_frame_k0_against_first_mode_reference(steel):
    """k0 against ``Re(F/X)`` around the first mode (an equivalent linear stiffness: equal to
    k0 for an elastic run, below it once the run yields)."""
    for j, (m, r) in enumerate(zip(steel["runs"], steel["first_mode"])):
        f1 = first_mode_hz(m, 0.8, 2.5)
        ref = re_force_over_drift(m, 0.85 * f1, 1.15 * f1)
        ratio = r.k0 / ref
        assert np.all((ratio > 0.95) & (ratio < 1.2)), (j + 1, ratio)
        if j == 0:  # s1, PGA 0.23 g, nearly elastic
            assert np.all(np.abs(ratio - 1) < 0.08), ratio
    refs = np.array([re_force_over_drift(m, 0.85 * first_mode_hz(m, 0.8, 2.5), 1.15 * first_mode_hz(m, 0.8, 2.5))
                     for m in steel["runs"]])
    assert np.all(np.diff(refs, axis=0) < 0)  # the reference decreases too


def test_steel_frame_is_not_a_shear_building_above_its_first_mode(steel):
    """Why the steel frame needs a first-mode band: story 3's apparent stiffness near the second
    mode (4-5 Hz) is over 1.5 x that at the first, so the default band (to 20 Hz), which mixes
    both, gives a higher k0 for story 3 on every run."""
    for m, d, f in zip(steel["runs"], steel["default"], steel["first_mode"]):
        f1 = first_mode_hz(m, 0.8, 2.5)
        assert re_force_over_drift(m, 4.0, 5.0)[2] > 1.5 * re_force_over_drift(m, 0.85 * f1, 1.15 * f1)[2]
        assert d.band_hz[1] >= 20.0 and f.band_hz == (0.3, 2.5)
        assert d.k0[2] > 1.25 * f.k0[2]


def test_steel_frame_damping_option(steel):
    """A passive story dissipates energy. The default 5 % Rayleigh correction over-corrects this
    frame (negative hysteretic energy on every story of s2); the regression option does not."""
    def energy(r):
        return np.array([np.trapezoid(s.force * s.drift_velocity, dx=r.dt) for s in r.stories])

    assert steel["default"][1].damping == "rayleigh" and np.all(energy(steel["default"][1]) < 0)
    for r in steel["first_mode"][1:]:
        assert r.damping == "regression" and np.all(energy(r) > 0)
        assert np.all(np.isfinite(r.stories[0].half_cycles.damping_coefficient))


def test_steel_frame_result_is_mass_normalised(steel):
    r = steel["first_mode"][3]
    assert r.mass_normalised and np.allclose(r.mass, 1 / 3)
    assert r.units["stiffness"].startswith("N/mm/t") and "per unit total mass" in r.units["force"]
    s = r.summary()
    assert s["mass_normalised"] and s["units"] == r.units and not s["pdelta_corrected"]
    # the measured floor displacements are the drift (the reader's relative displacements)
    x = np.diff(steel["runs"][3].floor_disp, axis=1, prepend=0.0)
    assert np.corrcoef(r.stories[2].drift, x[:, 2])[0, 1] > 0.95


# ---------------------------------------------------------------------- mini shake table
@pytest.fixture(scope="module")
def mini():
    names = ("flexible_3story_northridge", "flexible_3story_sine1p5", "stiff_3story_northridge", "stiff_3story_sine1p5")
    out = {}
    for n in names:
        m = read_mini_shake_table(data_path(MINI, f"{n}.csv"))
        out[n] = (m, run_hla(m))
    return out


def test_mini_shake_table_reported_elastic(mini):
    """The lab models stay linear: every story is reported elastic (one stiffness, ke = k0),
    not failed, with many half cycles."""
    for name, (_m, r) in mini.items():
        assert r.mass_normalised and r.units["stiffness"].startswith("N/mm/t"), name
        for s in r.stories:
            assert not s.yielded, (name, s.story)
            assert len(s.half_cycles) > 100 and np.all(s.half_cycles.ke == s.k0) and s.k0 > 0
            assert s.summary()["final_ke_over_k0"] == 1.0


def test_mini_shake_table_k0_reproduces_the_measured_first_mode(mini):
    """The shear building of the identified k0 (equal masses) has the measured first mode
    (peak of |roof / ground|) within 5 %, and the stiff model is 3.5-6 x stiffer per story
    than the flexible one ((7.8 / 3.7 Hz)^2 = 4.5)."""
    for name, (m, r) in mini.items():
        f_meas = transfer_peak_hz(m, 2.0, 15.0)
        assert shear_building_f1(r.k0, r.mass) == pytest.approx(f_meas, rel=0.05), name
    ratio = mini["stiff_3story_northridge"][1].k0 / mini["flexible_3story_northridge"][1].k0
    assert np.all((ratio > 3.5) & (ratio < 6.0)), ratio


# ---------------------------------------------------------------------- config checks
@pytest.mark.parametrize("yaml_text, match", [
    ("force: {max_iterations: 0}", "max_iterations"),
    ("force: {damping_modes: [0, 2]}", "damping_modes"),
    ("stiffness: {k0_min_amplitude: 2}", "k0_min_amplitude"),
    ("stiffness: {yield_ratio: -1}", "yield_ratio"),
    ("stiffness: {ke_trend_z: -3}", "ke_trend_z"),
])
def test_bad_hla_config_is_one_clear_error(tmp_path, yaml_text, match):
    """Settings that used to fail deep inside the analysis (``max_iterations: 0`` raised an
    UnboundLocalError) or to be silently meaningless are refused on load, naming file and field."""
    from hlaid.errors import InputError

    path = tmp_path / "hla.yaml"
    path.write_text(yaml_text + "\n")
    with pytest.raises(InputError, match=match) as e:
        load_config(path, HLAConfig)
    assert "hla.yaml" in str(e.value)


def test_shipped_hla_configs_load():
    for name in ("hla.yaml", "hla_steel_frame.yaml"):
        assert isinstance(load_config(STEEL_CONFIG.parent / name, HLAConfig), HLAConfig)
