"""``hlaid ida`` and ``hlaid export-opensees`` from the command line: outputs and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hlaid.cli import main
from hlaid.clone import Clone

HEIGHTS = [3000.0, 3000.0, 3000.0]
RECS = ["builtin:elcentro-1940-ns", "builtin:kocaeli-1999-dzc180"]


@pytest.fixture()
def clone_file(table1, tmp_path):
    path = tmp_path / "clone.json"
    Clone(building=table1.replace(height=HEIGHTS), provenance={"test": True}).save(path)
    return path


def _err_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    return err[-1]


def test_ida_command_writes_the_result(clone_file, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["ida", str(clone_file), "--records", *RECS, "--levels", "1:3:1", "--drift-limit", "0.03",
               "--bootstrap", "20", "--no-plots", "-o", str(out), "-q"])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["levels_g"] == [1.0, 2.0, 3.0] and s["collapse_criteria"]["drift_limit"] == 0.03
    assert [r["name"] for r in s["records"]] == ["elcentro-1940-ns", "kocaeli-1999-dzc180"]
    assert s["building"]["pdelta"] is True  # on by default: heights are known
    assert sorted(p.name for p in out.iterdir()) == [".hlaid-output.json", "ida.npz", "points.csv", "summary.json"]
    # the existing result is kept unless --force
    assert main(["ida", str(clone_file), "--records", *RECS, "-o", str(out)]) == 2
    assert "not empty; use --force" in _err_line(capsys)


def test_ida_command_with_config(clone_file, tmp_path):
    cfg = tmp_path / "ida.yaml"
    cfg.write_text("records: [builtin:kocaeli-1999-dzc180]\nim: pga\nlevels: [0.5, 1.0]\nrefine: false\n"
                   "pdelta: false\nbootstrap: 0\n")
    out = tmp_path / "o"
    assert main(["ida", str(clone_file), "--config", str(cfg), "--no-plots", "-o", str(out), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["intensity_measure"]["name"] == "pga" and s["building"]["pdelta"] is False
    assert s["settings"]["refine"] is False


@pytest.mark.parametrize("args, message", [
    (["--levels", "0.5,0.3"], "levels must be strictly increasing"),
    (["--levels", "a,b"], "--levels must be numbers"),
    (["--im", "sa_t1", "--heights", "3000,3000"], "height has 2 values but the building has 3 stories"),
])
def test_ida_command_bad_arguments(clone_file, tmp_path, capsys, args, message):
    rc = main(["ida", str(clone_file), "--records", *RECS, "-o", str(tmp_path / "x"), *args])
    assert rc == 2
    line = _err_line(capsys)
    assert message in line and line.startswith("hlaid ida: error:")
    assert not (tmp_path / "x").exists()


def test_ida_command_bad_inputs(clone_file, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["ida", str(clone_file), "--records", str(empty), "-o", str(tmp_path / "x")]) == 2
    assert "no record files in the folder" in _err_line(capsys)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "hlaid-clone", "version": 7}))
    assert main(["ida", str(bad), "--records", *RECS, "-o", str(tmp_path / "x")]) == 2
    assert "clone version 7 is not supported" in _err_line(capsys)
    cfg = tmp_path / "c.yaml"
    cfg.write_text("im: sa_t1\nlevel: [1, 2]\n")
    assert main(["ida", str(clone_file), "--config", str(cfg), "-o", str(tmp_path / "x")]) == 2
    assert f"{cfg}:2: unknown key 'level'" in _err_line(capsys)
    assert not (tmp_path / "x").exists()


def test_export_opensees_command(clone_file, tmp_path, capsys):
    out = tmp_path / "model.py"
    assert main(["export-opensees", str(clone_file), "-o", str(out), "-q"]) == 0
    text = out.read_text()
    compile(text, str(out), "exec")
    ns: dict = {"__name__": "x"}
    exec(compile(text, str(out), "exec"), ns)  # noqa: S102 - the script under test
    assert np.allclose(ns["PDELTA_K"], Clone.load(clone_file).building.replace(pdelta=True).geometric_stiffness())
    assert main(["export-opensees", str(clone_file), "-o", str(out), "--no-pdelta", "--force", "-q"]) == 0
    ns = {"__name__": "x"}
    exec(compile(out.read_text(), str(out), "exec"), ns)  # noqa: S102 - the script under test
    assert ns["PDELTA_K"] == [0.0, 0.0, 0.0]
    assert main(["export-opensees", str(clone_file), "-o", str(out)]) == 2
    assert "already exists" in _err_line(capsys)
