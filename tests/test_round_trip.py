"""Every file hlaid writes is read by the commands that take it: a clone (also one with a parameter
its record did not identify) by predict, demands, ida, export-opensees and update; the demands and
the IDA folder by the losses' readers; a measurement hlaid wrote by hla and predict; a run folder by
report. The demo-size building (Table 1's three stories), few records and small ensembles; the
whole pipeline from identify on is marked slow."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_hostile import HEIGHTS

from hlaid import _outdir
from hlaid._fileio import MARKER
from hlaid.cli.app import main
from hlaid.clone import Clone

RECORD = "builtin:elcentro-1940-ns"


def _ok(capsys, argv) -> str:
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert rc == 0, (argv, err)
    return err


@pytest.fixture(scope="module")
def written(table1, tmp_path_factory) -> dict[str, Path]:
    """A measurement and a clone as hlaid writes them (the clone with an unidentified parameter)."""
    from hlaid.model.uncertainty import ParameterUncertainty
    from hlaid.motions import GroundMotion, load_builtin
    from hlaid.synthetic import simulate_measurement

    d = tmp_path_factory.mktemp("round")
    b = table1.replace(height=HEIGHTS)
    rec = load_builtin(RECORD.split(":")[1]).scaled_to_pga(0.3)
    rec = GroundMotion(acc=rec.acc[:int(12.0 / rec.dt)], dt=rec.dt, name="elcentro-12s")
    meas = simulate_measurement(b, rec, rate_hz=50.0, seed=1)
    u = ParameterUncertainty(slots=(("k0", 0), ("k0", 1), ("p", 2)), transform=("log", "log", "log1"),
                             centre=np.log([b.k0[0], b.k0[1], b.p[2] - 1.0]),
                             covariance=np.diag([0.01, 0.02, 14.0**2]))
    return {"meas": meas.save(d / "meas.npz"), "clone": Clone(building=b, uncertainty=u).save(d / "clone.json"),
            "dir": d}


def test_a_clone_is_read_by_every_command_that_takes_it(written, capsys):
    d, clone, meas = written["dir"], written["clone"], written["meas"]
    assert "p[3]" in json.loads(clone.read_text())["uncertainty"]["info"]["unidentified"]
    _ok(capsys, ["export-opensees", clone, "-o", d / "model.py"])
    assert "def " in (d / "model.py").read_text()
    _ok(capsys, ["predict", clone, meas, "-o", d / "p", "--ensemble", "2", "--no-plots"])
    assert _outdir.not_ours(d / "p") is None
    _ok(capsys, ["demands", clone, "--motion", meas, "--ensemble", "2", "-o", d / "d.csv"])
    from hlaid.loss.demands import read_demand_csv
    assert read_demand_csv(d / "d.csv").n_realizations >= 1
    json.loads(Path(str(d / "d.csv") + ".basis.json").read_text())
    _ok(capsys, ["ida", clone, "--records", RECORD, "builtin:kocaeli-1999-dzc180", "builtin:northridge-1994-los000",
                 "builtin:kobe-1995-nis000", "--levels", "0.25:8:0.25", "--drift-limit", "0.05", "--no-refine",
                 "--bootstrap", "10", "--no-plots", "-o", d / "i", "--im", "pga"])
    assert _outdir.not_ours(d / "i") is None
    _ok(capsys, ["hla", meas, "-o", d / "h", "--no-plots"])
    assert json.loads((d / "h" / "hla.json").read_text())
    assert (d / "h" / MARKER).is_file() and _outdir.not_ours(d / "h") is None


def test_the_ida_folder_gives_the_losses_its_fragility(written, capsys, tmp_path):
    """``loss DEMANDS --collapse-from IDA_DIR`` reads what ``ida`` and ``demands`` wrote (the reading,
    which needs no pelicun)."""
    from hlaid.cli.loss import ida_fragility
    d, clone = written["dir"], written["clone"]
    if not (d / "i").is_dir():
        pytest.skip("needs the IDA folder of the test above")
    cfg = tmp_path / "ida.yaml"
    cfg.write_text("im: pga\ndrift_limit: 0.05\n")
    _ok(capsys, ["demands", clone, "--records", RECORD, "--level", "0.3", "--ensemble", "0", "--config", cfg,
                 "-o", tmp_path / "dp.csv"])
    summary = json.loads((d / "i" / "summary.json").read_text())
    if "median_g" not in json.dumps(summary.get("collapse_fragility")):
        pytest.skip("no collapse within the levels")
    median, beta = ida_fragility(str(d / "i"), tmp_path / "dp.csv")
    assert median > 0 and beta > 0


def test_update_reads_the_clone_and_writes_one_every_command_reads(written, capsys, tmp_path):
    clone, meas = written["clone"], written["meas"]
    _ok(capsys, ["update", clone, meas, "-o", tmp_path / "c2.json"])
    c2 = Clone.load(tmp_path / "c2.json")
    assert len(c2.events) >= 1
    _ok(capsys, ["export-opensees", tmp_path / "c2.json", "-o", tmp_path / "m.py"])


@pytest.mark.slow
def test_identify_then_every_command(written, capsys, tmp_path):
    """The clone identify writes (whatever its spread) is read by predict, demands, ida and update."""
    meas = written["meas"]
    _ok(capsys, ["identify", meas, "-o", tmp_path / "c.json"])
    c = tmp_path / "c.json"
    _ok(capsys, ["predict", c, meas, "-o", tmp_path / "p", "--ensemble", "2", "--no-plots"])
    _ok(capsys, ["demands", c, "--motion", meas, "--ensemble", "2", "-o", tmp_path / "d.csv"])
    _ok(capsys, ["ida", c, "--records", RECORD, "--levels", "0.2,1", "--no-refine", "--no-plots", "-o", tmp_path / "i"])
    _ok(capsys, ["export-opensees", c, "-o", tmp_path / "m.py"])


@pytest.mark.slow
def test_a_run_folder_is_read_by_report_and_loss(tmp_path, capsys):
    """``hlaid demo`` (the whole pipeline), then ``report RUN`` and ``loss RUN`` add to it, and it
    stays hlaid's (so --force may replace it)."""
    run = tmp_path / "run"
    _ok(capsys, ["demo", "--out", run])
    _ok(capsys, ["report", run])
    assert _outdir.not_ours(run) is None
    try:
        import pelicun  # noqa: F401
    except ImportError:
        return
    _ok(capsys, ["loss", run, "--no-curve", "--realizations", "50"])
    assert _outdir.not_ours(run) is None
    _ok(capsys, ["report", run])
