"""Every config shipped in configs/ loads against its schema; bad keys and types are refused
with the key, the file and the line."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from hlaid.config import load_config
from hlaid.errors import ConfigError, InputError

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

LOADERS = {
    "poc_3story.yaml": ("hlaid.synthetic", "SimulationConfig"),
    "hla.yaml": ("hlaid.hla", "HLAConfig"),
    "hla_steel_frame.yaml": ("hlaid.hla", "HLAConfig"),
    "identify.yaml": ("hlaid.identify", "IdentifyConfig"),
    "identify_steel_frame.yaml": ("hlaid.identify", "IdentifyConfig"),
    "identify_leastsquares.yaml": ("hlaid.identify", "IdentifyConfig"),
    "identify_monitoring.yaml": ("hlaid.identify", "IdentifyConfig"),
    "svm.yaml": ("hlaid.studies.training_samples", "TrainingSamplesConfig"),
    "ida.yaml": ("hlaid.ida", "IDAConfig"),
    "demo.yaml": ("hlaid.run.config", "load_run_config"),
    "run_example.yaml": ("hlaid.run.config", "load_run_config"),
    "compare.yaml": ("hlaid.studies.compare", "CompareConfig"),
    "validate_real.yaml": ("hlaid.studies.validation", "ValidationConfig"),
    "fleet_example.yaml": ("hlaid.fleet", "load_fleet_config"),
    "columns_example.yaml": ("hlaid.io", "ColumnsConfig"),
}
"""Each config file and its schema (a dataclass) or loader (a function). A new config must
be listed here."""


def _load(path: Path):
    mod, name = LOADERS[path.name]
    obj = getattr(importlib.import_module(mod), name)
    return obj(path) if callable(obj) and not isinstance(obj, type) else load_config(path, obj)


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_every_config_loads(path):
    assert path.name in LOADERS, f"{path.name} is not listed in tests/test_configs_all.py::LOADERS"
    assert _load(path) is not None


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_unknown_key_rejected_with_file_and_line(path, tmp_path):
    text = path.read_text()
    bad = tmp_path / path.name
    bad.write_text(text.rstrip("\n") + "\nnot_a_key: 1\n")
    line = len(bad.read_text().splitlines())
    with pytest.raises(ConfigError) as err:
        _load(bad)
    msg = str(err.value)
    assert "not_a_key" in msg and f"{bad.name}:{line}" in msg and "\n" not in msg


def test_wrong_type_rejected_with_key_file_and_line(tmp_path):
    p = tmp_path / "hla.yaml"
    p.write_text("preprocess:\n  order: four\n")
    with pytest.raises(ConfigError, match=r"hla.yaml:2: preprocess.order: expected an integer, got 'four'"):
        load_config(p, importlib.import_module("hlaid.hla").HLAConfig)
    p.write_text("stiffness: {yield_ratio: 2.0}\n")
    with pytest.raises(InputError, match="hla.yaml:1"):
        load_config(p, importlib.import_module("hlaid.hla").HLAConfig)
