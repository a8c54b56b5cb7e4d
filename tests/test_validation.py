"""Real-structure validation protocol (``hlaid.studies.validation``, ``scripts/validate_real.py``).

- The comparison itself against an independent reference: a clone that *is* the simulated
  building predicts its response with R = 1 and no peak-drift error; a wrong clone does not.
- The labelled linear fallback on elastic simulated data recovers the true stiffnesses.
- One small end-to-end run on the real steel frame (skipped without ``../shared/data``): a
  linear clone from s1 (no story yields) predicting s2, and a nonlinear clone from s4 (small
  training settings) predicting s3, each through its clone JSON file.
- The config: the shipped one loads, bad keys are refused with file and line, the script
  turns bad input into one line and exit status 2.

The full protocol (every structure, full settings) is the script; its numbers are in
docs/validation.md.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, REPO, paper_record, requires, window

from hlaid.clone import Clone
from hlaid.config import config_from_dict
from hlaid.errors import ConfigError, InputError
from hlaid.hla import HLAConfig
from hlaid.hla.config import ForceConfig
from hlaid.identify import IdentifyConfig
from hlaid.studies.validation import (
    ValidationConfig,
    format_tables,
    identify_config_of,
    linear_clone,
    load_validation_config,
    run_validation,
    study_prediction,
)
from hlaid.synthetic import simulate_measurement

CONFIG = REPO / "configs" / "validate_real.yaml"
STEEL = DATA / "structural_response" / "shake_table_3story_steel_mrf_fixedbase"


def _normalised(building):
    M = float(building.mass.sum())
    return Clone(building=building.replace(mass=building.mass / M, k0=building.k0 / M), mass_normalised=True)


def test_prediction_of_the_true_building_is_exact(table1):
    """A mass-normalised clone equal to the simulated building: R > 0.999 on every floor, peak
    drifts within 1 %, and its ke(t) within 3 % of what HLA measures; a clone 30 % too stiff is
    caught by every metric."""
    gm = window(paper_record("elcentro-1940-ns"), 20.0)
    meas = dataclasses.replace(simulate_measurement(table1, gm, noise_rms=0.0), mass=None)
    hcfg = HLAConfig(force=ForceConfig(mass_ratios=list(table1.mass)))
    good = study_prediction(_normalised(table1), meas, hcfg)
    assert good.prediction.status == 0 and np.all(good.r > 0.999) and np.all(good.r_broadband > 0.999)
    assert np.max(np.abs(good.peak_drift_error)) < 0.01
    assert np.all(good.stiffness_error < 0.03)
    bad = study_prediction(_normalised(table1.replace(k0=1.3 * table1.k0)), meas, hcfg)
    assert np.all(bad.r < 0.95) and np.all(bad.stiffness_error > 0.15)
    assert np.max(np.abs(bad.peak_drift_error)) > 0.05


def test_linear_clone_of_elastic_data(table1):
    """A linear building (alpha = 1, 5 % Rayleigh), masses withheld: the linear clone keeps
    HLA's k0 with ``fit='none'`` (within 5 % of the truth), recovers the true k0 / M within 1 %
    when the replay fits k0, and with the default ``scale+damping`` keeps HLA's stiffness ratios
    and finds the damping ratio within 0.005."""
    linear = table1.replace(alpha=np.ones(3))
    gm = window(paper_record("kocaeli-1999-dzc180"), 14.0).scaled(0.1 / 0.62)
    meas = dataclasses.replace(simulate_measurement(linear, gm, noise_rms=0.0), mass=None)
    cfg = IdentifyConfig(hla=HLAConfig(force=ForceConfig(mass_ratios=list(table1.mass))))
    M = float(table1.mass.sum())
    fitted = linear_clone(meas, cfg, fit="k0")
    assert fitted.mass_normalised and np.all(fitted.building.alpha == 1.0)
    assert np.allclose(fitted.building.k0 * M, table1.k0, rtol=0.01)
    raw = linear_clone(meas, cfg, fit="none")
    assert np.allclose(raw.building.k0, raw.diagnostics["k0_hla"]) and raw.diagnostics["refine"] is None
    assert np.allclose(raw.building.k0 * M, table1.k0, rtol=0.05)
    scaled = linear_clone(meas, cfg)
    assert scaled.diagnostics["fit"] == "scale+damping"
    assert np.allclose(scaled.building.k0 / scaled.building.k0[0], raw.building.k0 / raw.building.k0[0])
    assert np.allclose(scaled.building.k0 * M, table1.k0, rtol=0.05)
    assert scaled.building.damping.ratio == pytest.approx(0.05, abs=0.005)
    with pytest.raises(InputError, match="expected one of"):
        linear_clone(meas, cfg, fit="everything")


def test_shipped_config_loads():
    cfg = load_validation_config(CONFIG)
    names = [s.name for s in cfg.structures]
    assert {"steel-frame", "mini-flexible", "mini-stiff", "hotel", "berkeley"} <= set(names)
    steel = cfg.structures[names.index("steel-frame")]
    icfg = identify_config_of(steel)
    assert icfg.hla.preprocess.band_hz == (0.3, 2.5) and icfg.hla.stiffness.yield_ratio == 0.8
    variant = cfg.structures[names.index("steel-frame-y0.6")]
    assert variant.optional and identify_config_of(variant).hla.stiffness.yield_ratio == 0.6
    assert Path(cfg.data_dir).name == "structural_response"


def test_config_errors_name_file_and_line(tmp_path):
    bad = tmp_path / "v.yaml"
    bad.write_text("structures:\n  - name: a\n    events: [{name: e, path: x}]\n    identify_from: [e]\n"
                   "    identfy_config: x.yaml\n")
    with pytest.raises(ConfigError, match=r"v\.yaml:5: unknown key 'structures\[0\]\.identfy_config'|v\.yaml:5"):
        load_validation_config(bad)
    bad.write_text("structures:\n  - name: a\n    events: [{name: e, path: x}]\n    identify_from: [f]\n")
    with pytest.raises(ConfigError, match="unknown events"):
        load_validation_config(bad)
    ok = config_from_dict(ValidationConfig, {"structures": [{"name": "a", "events": [{"name": "e", "path": "x"}],
                                                              "identify_from": ["e"],
                                                              "overrides": {"training": {"samplez": 3}}}]})
    with pytest.raises(ConfigError, match="samplez"):
        identify_config_of(ok.structures[0])


def _script():
    spec = importlib.util.spec_from_file_location("validate_real", REPO / "scripts" / "validate_real.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_script_bad_input_is_one_line(tmp_path, capsys):
    main = _script().main
    assert main(["--config", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "o"), "--figures", ""]) == 2
    err = capsys.readouterr().err
    assert "none.yaml" in err and "not found" in err and "Traceback" not in err
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "keep.txt").write_text("x")
    assert main(["--config", str(CONFIG), "--out", str(tmp_path / "o"), "--figures", "", "--structures", "nope"]) == 2
    assert "--force" in capsys.readouterr().err and (tmp_path / "o" / "keep.txt").exists()
    figs = tmp_path / "figs"  # existing figures: refused before any identification, nothing written
    figs.mkdir()
    (figs / "old.png").write_bytes(b"png")
    assert main(["--config", str(CONFIG), "--out", str(tmp_path / "new"), "--figures", str(figs)]) == 2
    err = capsys.readouterr().err
    assert "figs" in err and "--force" in err and not (tmp_path / "new").exists()


@requires(STEEL.is_dir(), f"steel-frame data not found at {STEEL}", data=True)
@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_steel_frame_end_to_end(tmp_path):
    """Real data, small settings: s1 stays elastic, so its clone is the labelled linear one;
    s4 yields, so the paper's method runs. Each clone goes through its JSON file and predicts a
    run it never saw; R above sanity thresholds (the full settings give 0.68 and 0.93,
    docs/validation.md)."""
    cfg = load_validation_config(CONFIG)
    steel = next(s for s in cfg.structures if s.name == "steel-frame")
    small = {"training": {"samples": 60}, "outer": {"max_iterations": 1},
             "refine": {"max_iterations": 6}}
    spec = dataclasses.replace(steel, identify_from=["s1", "s4"], predict=["s2", "s3"], overrides=small)
    cfg = dataclasses.replace(cfg, structures=[spec])
    res = run_validation(cfg, clone_dir=str(tmp_path / "clones"), cache_dir=str(tmp_path / "cache"))
    kinds = {c.event: c for c in res.clones}
    assert kinds["s1"].kind == "linear" and "no story yielded" in kinds["s1"].reason
    assert kinds["s4"].kind == "nonlinear" and kinds["s4"].reason == ""
    for c in res.clones:
        on_disk = Clone.load(tmp_path / "clones" / c.path)
        assert on_disk.mass_normalised and np.allclose(on_disk.building.mass, 1.0 / 3.0)
        assert np.allclose(on_disk.building.k0, c.clone.building.k0)
    pred = {(p.identified_from, p.event): p for p in res.predictions}
    assert set(pred) == {("s1", "s1"), ("s1", "s2"), ("s1", "s3"), ("s4", "s4"), ("s4", "s2"), ("s4", "s3")}
    assert np.all(pred["s4", "s4"].r > 0.9)
    assert np.mean(pred["s4", "s3"].r) > 0.8
    assert np.mean(pred["s1", "s2"].r) > 0.5
    for p in pred.values():
        assert p.status == 0 and p.band_hz == (0.3, 2.5)
        assert np.all(np.isfinite(p.peak_drift_error)) and np.all(np.isfinite(p.stiffness_error))
    d = json.loads(json.dumps(res.to_dict()))
    assert d["summary"][0]["structure"] == "steel-frame" and d["summary"][0]["cross"]["n"] == 4
    table = format_tables(res)
    assert f"{np.mean(pred['s4', 's3'].r):.3f}" in table and "linear (fallback)" in table
