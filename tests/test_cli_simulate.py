"""``hlaid simulate`` and ``hlaid records``: outputs, exit status and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

from hlaid.cli.app import main
from hlaid.io.native import read_native

POC = REPO / "configs" / "poc_3story.yaml"

DOCUMENTED_KEYS = {"dt", "ground_acc", "floor_acc", "mass", "true_disp", "true_drift", "true_force", "true_z",
                   "true_eta", "true_params"}


def _short_config(tmp_path, **replace) -> str:
    """The Table 1 config on a short window of a built-in record (fast)."""
    text = POC.read_text().replace('file: "builtin:elcentro-1940-ns"', 'file: "rec.txt"')
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    rec = tmp_path / "rec.txt"
    t = np.arange(800) * 0.01
    rec.write_text("# units: g\n" + "".join(f"{a:.3f} {0.3 * np.sin(2 * np.pi * 1.5 * a) * np.exp(-a / 3):.6f}\n"
                                             for a in t))
    p = tmp_path / "cfg.yaml"
    p.write_text(text)
    return str(p)


def _stderr_lines(capsys) -> list[str]:
    return [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]


def test_simulate_writes_the_documented_keys(tmp_path, capsys):
    out = tmp_path / "meas.npz"
    assert main(["simulate", str(POC), "-o", str(out), "--seed", "7"]) == 0
    with np.load(out) as z:
        assert DOCUMENTED_KEYS <= set(z.files)
        n = z["ground_acc"].shape[0]
        assert float(z["dt"]) == 0.005 and z["floor_acc"].shape == (n, 3) and z["mass"].shape == (3,)
        for k in ("true_disp", "true_drift", "true_force", "true_z", "true_eta"):
            assert z[k].shape == (n, 3)
        params = json.loads(str(z["true_params"]))
    assert [s["k0"] for s in params["stories"]] == [1.94e4, 1.65e4, 1.37e4]
    m = read_native(out)
    assert m.truth is not None and m.noise_rms == 0.10
    assert np.abs(m.ground_acc).max() == pytest.approx(0.62 * 9806.65, rel=0.5)  # noisy 0.62 g record
    assert "wrote" in capsys.readouterr().err


def test_seed_controls_the_noise(tmp_path):
    cfg = _short_config(tmp_path)
    paths = [tmp_path / f"{name}.npz" for name in ("a", "b", "c")]
    for p, seed in zip(paths, ("1", "1", "2")):
        assert main(["simulate", cfg, "-o", str(p), "--seed", seed, "-q"]) == 0
    a, b, c = (np.load(p) for p in paths)
    np.testing.assert_array_equal(a["floor_acc"], b["floor_acc"])
    assert not np.array_equal(a["floor_acc"], c["floor_acc"])
    np.testing.assert_array_equal(a["true_drift"], c["true_drift"])  # same structure, same truth


def test_csv_output(tmp_path):
    out = tmp_path / "meas.csv"
    assert main(["simulate", _short_config(tmp_path), "-o", str(out), "-q"]) == 0
    m = read_native(out)
    assert m.n_floors == 3 and m.dt == 0.005 and m.truth is not None


def test_existing_output_needs_force(tmp_path, capsys):
    cfg = _short_config(tmp_path)
    out = tmp_path / "meas.npz"
    out.write_bytes(b"precious")
    assert main(["simulate", cfg, "-o", str(out)]) == 2
    lines = _stderr_lines(capsys)
    assert lines == [f"hlaid simulate: error: {out}: already exists; use --force to overwrite"]
    assert out.read_bytes() == b"precious"
    assert main(["simulate", cfg, "-o", str(out), "--force", "-q"]) == 0
    assert read_native(out).n_floors == 3


@pytest.mark.parametrize("replace,match", [
    ({"alpha: 0.17": "alpah: 0.17"}, "cfg.yaml:9: unknown key 'building.stories[1].alpah'"),
    ({"alpha: 0.17": "alpha: 1.7"}, "cfg.yaml:9: building.stories[1].alpha = 1.7 is out of range"),
    ({"dy: 3.0": "dy: 0"}, "cfg.yaml:10: building.stories[2].dy = 0 is out of range; expected 1e-06 <= dy"),
    ({"rate_hz: 200": "rate_hz: fast"}, "measurement.rate_hz: expected a number, got 'fast'"),
    ({'file: "rec.txt"': 'file: "bad.AT2"'}, "bad.AT2: header says NPTS = 12 but the file holds 10 values"),
    ({'file: "rec.txt"': 'file: "missing.AT2"'}, "missing.AT2: file not found"),
    ({'file: "rec.txt"': 'file: "nan.txt"'}, "nan.txt: acceleration has 1 NaN or inf samples"),
    ({'file: "rec.txt"': 'file: "dt0.txt"'}, "dt0.txt: the first column increases like a time axis"),
])
def test_bad_input_exits_2_with_one_line_and_no_output(tmp_path, capsys, replace, match):
    cfg = _short_config(tmp_path, **replace)
    (tmp_path / "bad.AT2").write_text("PEER\nx\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS= 12, DT= .01 SEC\n"
                                      "1 2 3 4 5\n6 7 8 9 10\n")
    (tmp_path / "nan.txt").write_text("# units: g\n" + "".join(f"{0.01 * i:.2f} {'nan' if i == 3 else 0.1}\n"
                                                                for i in range(20)))
    (tmp_path / "dt0.txt").write_text("# units: g\n" + "".join(f"{0.01 * i * i:.2f} 0.1\n" for i in range(20)))
    before = sorted(p.name for p in tmp_path.iterdir())
    out = tmp_path / "meas.npz"
    assert main(["simulate", cfg, "-o", str(out)]) == 2
    lines = _stderr_lines(capsys)
    errors = [ln for ln in lines if "error" in ln]
    assert len(errors) == 1 and errors[0] == lines[-1], lines  # the error is the last line, and one line
    assert errors[0].startswith("hlaid simulate: error: ") and match in errors[0]
    assert not any("Traceback" in ln for ln in lines)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no output, no temporary file


def test_subprocess_exit_status_and_stderr(tmp_path):
    """The installed entry point: bad config -> status 2, one stderr line, no traceback, no file."""
    cfg = _short_config(tmp_path, **{"alpha: 0.23": "alpha: -0.23"})
    out = tmp_path / "meas.npz"
    script = Path(sys.executable).with_name("hlaid")  # the console script of the installed package
    cmd = [str(script)] if script.exists() else [sys.executable, "-c", "import sys; from hlaid.cli import main; "
                                                                       "sys.exit(main())"]
    proc = subprocess.run(cmd + ["simulate", cfg, "-o", str(out), "-q"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr
    assert lines[0].startswith("hlaid simulate: error: ")
    assert "cfg.yaml:8: building.stories[0].alpha = -0.23" in lines[0]
    assert not out.exists()


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["simulate", str(POC)])  # -o is required
    assert e.value.code == 2
    err = _stderr_lines(capsys)
    assert len(err) == 1 and "the following arguments are required: -o/--out" in err[0]
    with pytest.raises(SystemExit) as e:
        main(["simulat"])
    assert e.value.code == 2


def test_records_lists_the_builtin_records(capsys):
    assert main(["records"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 11 and sum("[suite]" in ln for ln in out) == 10
    assert any(ln.startswith("builtin:elcentro-1940-ns") for ln in out)
