"""YAML configs: schema validation with FILE:LINE in every error, and the shipped configs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pytest
from conftest import REPO
from reference_systems import TABLE1, table1_masses

from hlaid.config import config_from_dict, config_to_dict, load_config
from hlaid.errors import ConfigError, InputError
from hlaid.specs import BuildingSpec, MotionSpec
from hlaid.synthetic import SimulationConfig, load_simulation_config

POC = REPO / "configs" / "poc_3story.yaml"


@pytest.mark.parametrize("path", [POC, REPO / "hlaid" / "data" / "poc_3story.yaml"], ids=["configs", "package"])
def test_poc_config_is_table1(path):
    cfg = load_simulation_config(path)
    b = cfg.building.build()
    np.testing.assert_allclose(b.mass, table1_masses(), rtol=1e-15)
    for name in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_array_equal(getattr(b, name), TABLE1[name])
    assert not b.pdelta_active and b.damping.ratio == 0.05 and b.damping.modes == (1, 2)
    assert cfg.motion.pga_g == 0.62 and cfg.measurement.rate_hz == 200 and cfg.measurement.noise_rms == 0.10
    gm = cfg.motion.load()
    assert gm.pga_g == pytest.approx(0.62)


def _write(tmp_path, text, name="cfg.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


_BASE = """\
building:
  stories:
    - {weight_kN: 171.85, k0: 1.94e4, alpha: 0.23, p: 2.5, dy: 7.0, delta_eta: 0.70}
    - {weight_kN: 90.0, k0: 1.37e4, alpha: 0.12, p: 1.9, dy: 3.0, delta_eta: 1.54}
motion: {file: "builtin:elcentro-1940-ns", pga_g: 0.62}
seed: 3
"""


def test_minimal_config_and_defaults(tmp_path):
    cfg = load_simulation_config(_write(tmp_path, _BASE))
    assert cfg.seed == 3 and cfg.measurement.rate_hz == 200.0 and cfg.building.damping.kind == "rayleigh"
    assert cfg.building.stories[0].k0 == 1.94e4 and isinstance(cfg.building.stories[0].k0, float)
    assert cfg.building.build().n_stories == 2


@pytest.mark.parametrize("old,new,line,match", [
    ("alpha: 0.12", "alhpa: 0.12", 4, "unknown key 'building.stories[1].alhpa'; expected one of: k0, alpha"),
    ("seed: 3", "seed: 3\nsed: 4", 7, "unknown key 'sed'; expected one of: building, motion, measurement, seed"),
    ("pga_g: 0.62}", "pga_g: 0.62, scael: 2}", 5, "unknown key 'motion.scael'"),
    ("alpha: 0.12", "alpha: 1.12", 4, "building.stories[1].alpha = 1.12 is out of range; expected 0 <= alpha <= 1"),
    ("dy: 7.0", "dy: -7.0", 3, "building.stories[0].dy = -7 is out of range; expected 1e-06 <= dy <= 100000 [mm]"),
    ("p: 1.9", "p: 0.5", 4, "p = 0.5 is out of range; expected 1 <= p <= 50"),
    ("delta_eta: 1.54", "delta_eta: -1", 4, "delta_eta = -1 is out of range"),
    ("k0: 1.37e4", "k0: 0", 4, "k0 = 0 is out of range; expected 1e-06 <= k0"),
    ("weight_kN: 90.0", "weight_kN: -90.0", 4, "weight_kN = -90 is out of range"),
    ("weight_kN: 90.0, ", "", 4, "give exactly one of mass_t or weight_kN"),
    ("seed: 3", "seed: three", 6, "seed: expected an integer, got 'three'"),
    ("seed: 3", "seed: 3.5", 6, "seed: expected an integer, got 3.5"),
    ("k0: 1.37e4", "k0: stiff", 4, "building.stories[1].k0: expected a number, got 'stiff'"),
    ("pga_g: 0.62}", "pga_g: 0.62, format: sac}", 5, "motion.format: 'sac' is not allowed; expected one of"),
    ("pga_g: 0.62}", "pga_g: 0.62, scale: 2.0}", 5, "give pga_g or scale, not both"),
    ("seed: 3", "seed: 3\nseed: 4", 7, "key 'seed' appears twice"),
    ("seed: 3", "seed: [3", 6, "invalid YAML"),
    ("seed: 3", "measurement: {rate_hz: 0}", 6, "measurement.rate_hz = 0 is out of range; expected 5 <= rate_hz"),
])
def test_config_errors_name_file_line_and_key(tmp_path, old, new, line, match):
    text = _BASE.replace(old, new)
    assert text != _BASE
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_simulation_config(p)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"{p}:{line}: ") or (match == "invalid YAML" and msg.startswith(f"{p}:")), msg
    assert match in msg


def test_missing_keys_and_files(tmp_path):
    p = _write(tmp_path, "motion: {file: x.AT2}\n")
    with pytest.raises(ConfigError, match=r"cfg.yaml:1: top level: missing key\(s\) building"):
        load_simulation_config(p)
    with pytest.raises(ConfigError, match="config file not found"):
        load_simulation_config(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="top level: expected a mapping, got a list"):
        load_simulation_config(_write(tmp_path, "- 1\n- 2\n", "list.yaml"))
    with pytest.raises(ConfigError, match="stories: at least one story"):
        load_simulation_config(_write(tmp_path, "building: {stories: []}\nmotion: {file: x}\n", "empty.yaml"))


def test_relative_motion_path_is_taken_from_the_config_folder(tmp_path):
    rec = tmp_path / "rec.txt"
    rec.write_text("# units: g\n" + "".join(f"{0.01 * i:.2f} {0.1 * np.sin(i / 5):.6f}\n" for i in range(200)))
    cfg = load_simulation_config(_write(tmp_path, _BASE.replace("builtin:elcentro-1940-ns", "rec.txt")))
    gm = cfg.motion.load(base_dir=tmp_path)
    assert gm.source == str(rec) and gm.npts == 200 and gm.pga_g == pytest.approx(0.62)
    with pytest.raises(InputError, match="file not found"):
        cfg.motion.load(base_dir=tmp_path / "elsewhere")


@dataclass(frozen=True, kw_only=True)
class _Inner:
    name: str
    weight: float = 1.0


@dataclass(frozen=True, kw_only=True)
class _Schema:
    mode: Literal["fast", "exact"] = "fast"
    levels: list[float] = field(default_factory=list)
    pair: tuple[int, int] = (1, 2)
    inner: _Inner | None = None
    table: dict[str, float] = field(default_factory=dict)
    flag: bool = False


def test_schema_types(tmp_path):
    cfg = load_config(_write(tmp_path, "mode: exact\nlevels: [1, 2.5, 1e3]\npair: [3, 4]\ninner: {name: a}\n"
                                       "table: {x: 1}\nflag: true\n"), _Schema)
    assert cfg == _Schema(mode="exact", levels=[1.0, 2.5, 1000.0], pair=(3, 4), inner=_Inner(name="a"),
                          table={"x": 1.0}, flag=True)
    assert config_from_dict(_Schema, config_to_dict(cfg)) == cfg
    for text, match in (("flag: yes please", "flag: expected true or false"),
                        ("levels: 3", "levels: expected a list, got 3"),
                        ("levels: [1, a]", "levels[1]: expected a number, got 'a'"),
                        ("inner: {weight: 2}", "inner: missing key(s) name"),
                        ("inner: 3", "inner: expected a mapping"),
                        ("table: {x: y}", "table.x: expected a number")):
        with pytest.raises(ConfigError, match=match.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
            load_config(_write(tmp_path, text, "s.yaml"), _Schema)


def test_config_to_dict_round_trip_of_a_building_spec():
    spec = config_from_dict(BuildingSpec, {"stories": [{"mass_t": 10.0, "k0": 1e4, "alpha": 0.1, "p": 2.0,
                                                        "dy": 5.0, "delta_eta": 0.5, "height_mm": 3000.0}],
                                           "pdelta": True, "damping": {"kind": "mass", "ratio": 0.02}})
    again = config_from_dict(BuildingSpec, config_to_dict(spec))
    assert again == spec
    b = spec.build()
    assert b.pdelta_active and b.damping.kind == "mass" and b.geometric_stiffness()[0] > 0
    assert config_from_dict(MotionSpec, {"file": "builtin:kobe-1995-nis000", "scale": 2.0}).load().pga_g == \
        pytest.approx(2.0 * config_from_dict(MotionSpec, {"file": "builtin:kobe-1995-nis000"}).load().pga_g)


def test_simulation_config_schema_is_frozen():
    cfg = config_from_dict(SimulationConfig, {"building": {"stories": [{"mass_t": 1.0, "k0": 1.0, "alpha": 0.5,
                                                                        "p": 1.0, "dy": 1.0, "delta_eta": 0.0}]},
                                              "motion": {"file": "builtin:elcentro-1940-ns"}})
    with pytest.raises(AttributeError):
        cfg.seed = 2
