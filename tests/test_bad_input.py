"""Bad input across every command (issue 8): each case exits with status 2 and one line on
stderr naming the problem, never a traceback, and leaves no output behind."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.cli.main import main
from hlaid.synthetic import simulate_measurement

AT2_HEAD = "PEER NGA STRONG MOTION DATABASE RECORD\nTest, 1/1/2000, Nowhere, 0\nACCELERATION TIME SERIES IN UNITS OF G\n"


@pytest.fixture(scope="module")
def meas_file(tmp_path_factory, table1):
    d = tmp_path_factory.mktemp("bad")
    m = simulate_measurement(table1, window(paper_record("kocaeli-1999-dzc180"), 12.0), noise_rms=0.05, seed=0)
    return m.save(d / "meas.npz"), m


@pytest.fixture(scope="module")
def clone_file(tmp_path_factory, table1):
    from hlaid.clone import Clone
    d = tmp_path_factory.mktemp("clone")
    return Clone(building=table1.replace(height=[3000.0] * 3)).save(d / "clone.json")


def _npz(path, **arrays):
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return path


def _check(capsys, argv, expect, out=None):
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, (argv, err)
    assert err, "no message"
    last = err[-1]
    assert "Traceback" not in "\n".join(err)
    assert "error" in last and any(e.lower() in last.lower() for e in expect), last
    if out is not None:
        assert not out.exists(), f"partial output left at {out}"


def cases(tmp, meas, m, clone):
    """(argv, one of the expected words, output that must not exist)."""
    T = m.n_samples
    at2_bad = tmp / "npts.AT2"
    at2_bad.write_text(AT2_HEAD + "NPTS=   10, DT=   .0100 SEC\n" + " 0.1 0.2 0.3\n")
    at2_nan = tmp / "nan.AT2"
    at2_nan.write_text(AT2_HEAD + "NPTS=   10, DT=   .0100 SEC\n" + " 0.1 0.2 nan 0.1 0.1 0.1 0.1 0.1 0.1 0.1\n")
    txt = tmp / "nounits.txt"
    txt.write_text("\n".join(f"{0.01 * i:.2f} {np.sin(i):.4f}" for i in range(100)))
    dt0 = tmp / "dt0.AT2"
    dt0.write_text(AT2_HEAD + "NPTS=   10, DT=   0.0 SEC\n" + " 0.1" * 10 + "\n")

    def sim_cfg(name, motion_line, extra=""):
        p = tmp / name
        p.write_text("building:\n  stories:\n    - {weight_kN: 171.85, k0: 1.94e4, alpha: 0.23, p: 2.5, dy: 7.0, "
                     f"delta_eta: 0.7}}\n{extra}motion: {motion_line}\n")
        return p

    out = tmp / "out.npz"
    yield ["simulate", str(tmp / "missing.yaml"), "-o", str(out)], ["not found"], out
    yield ["simulate", str(sim_cfg("k.yaml", "{file: 'builtin:elcentro-1940-ns'}", "colour: red\n")), "-o", str(out)], \
        ["colour"], out
    p = tmp / "type.yaml"
    p.write_text("building:\n  stories:\n    - {weight_kN: 100, k0: abc, alpha: 0.2, p: 2, dy: 5, delta_eta: 1}\n"
                 "motion: {file: 'builtin:elcentro-1940-ns'}\n")
    yield ["simulate", str(p), "-o", str(out)], ["k0"], out
    p = tmp / "range.yaml"
    p.write_text("building:\n  stories:\n    - {weight_kN: 100, k0: 1e4, alpha: 1.5, p: 2, dy: 5, delta_eta: 1}\n"
                 "motion: {file: 'builtin:elcentro-1940-ns'}\n")
    yield ["simulate", str(p), "-o", str(out)], ["alpha"], out
    yield ["simulate", str(sim_cfg("at2.yaml", f"{{file: '{at2_bad}'}}")), "-o", str(out)], ["NPTS"], out
    yield ["simulate", str(sim_cfg("nan.yaml", f"{{file: '{at2_nan}'}}")), "-o", str(out)], ["non-numeric", "NaN"], out
    yield ["simulate", str(sim_cfg("units.yaml", f"{{file: '{txt}'}}")), "-o", str(out)], ["units"], out
    yield ["simulate", str(sim_cfg("dt.yaml", f"{{file: '{dt0}'}}")), "-o", str(out)], ["dt"], out
    yield ["simulate", str(sim_cfg("unknown.yaml", "{file: 'builtin:no-such-record'}")), "-o", str(out)], \
        ["unknown built-in"], out
    yield ["simulate", str(sim_cfg("ok.yaml", "{file: 'builtin:elcentro-1940-ns'}")), "-o",
           str(tmp / "nodir" / "x.npz")], ["does not exist"], tmp / "nodir"
    yield ["simulate", str(sim_cfg("ok2.yaml", "{file: 'builtin:elcentro-1940-ns'}")), "-o", str(meas)], \
        ["already exists"], None

    o = tmp / "hla_out"
    yield ["hla", str(tmp / "nope.npz"), "-o", str(o)], ["not found"], o
    rnd = tmp / "random.npz"
    rnd.write_bytes(bytes(range(256)) * 8)
    yield ["hla", str(rnd), "-o", str(o)], ["npz", "read"], o
    yield ["hla", str(_npz(tmp / "nofloor.npz", dt=0.005, ground_acc=m.ground_acc)), "-o", str(o)], ["floor_acc"], o
    bad = np.array(m.floor_acc)
    bad[100, 1] = np.nan
    yield ["hla", str(_npz(tmp / "nan.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=bad, mass=m.mass)), "-o",
           str(o)], ["NaN"], o
    yield ["hla", str(_npz(tmp / "len.npz", dt=m.dt, ground_acc=m.ground_acc[:-10], floor_acc=m.floor_acc,
                           mass=m.mass)), "-o", str(o)], ["different lengths"], o
    yield ["hla", str(_npz(tmp / "short.npz", dt=m.dt, ground_acc=m.ground_acc[:30], floor_acc=m.floor_acc[:30],
                           mass=m.mass)), "-o", str(o)], ["samples"], o
    yield ["hla", str(_npz(tmp / "g.npz", dt=m.dt, ground_acc=m.ground_acc / 9806.65, floor_acc=m.floor_acc / 9806.65,
                           mass=m.mass)), "-o", str(o)], ["units"], o
    yield ["hla", str(_npz(tmp / "mass.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=m.floor_acc,
                           mass=m.mass[:2])), "-o", str(o)], ["mass"], o
    yield ["hla", str(_npz(tmp / "dt.npz", dt=-0.01, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass)),
           "-o", str(o)], ["dt"], o
    csv = tmp / "bad.csv"
    csv.write_text("# dt_s: 0.005\ntime_s,ground_acc,floor_acc_1\n0,1,x\n0.005,2,3\n")
    yield ["hla", str(csv), "-o", str(o)], ["non-numeric"], o
    hcfg = tmp / "h.yaml"
    hcfg.write_text("stiffness: {windoww: 3}\n")
    yield ["hla", str(meas), "-o", str(o), "--config", str(hcfg)], ["windoww"], o

    c = tmp / "c.json"
    yield ["identify", str(_npz(tmp / "nofl.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=np.zeros((T, 0)))),
           "-o", str(c)], ["floor"], c
    weak = simulate_measurement(m.truth.building, window(paper_record("kocaeli-1999-dzc180"), 12.0).scaled(0.04),
                                noise_rms=0.02, seed=0).save(tmp / "weak.npz")
    yield ["identify", str(weak), "-o", str(c), "--no-cache"], ["no story yielded"], c

    ida_out = tmp / "ida_out"
    broken = tmp / "broken.json"
    broken.write_text('{"format": "hlaid-clone", "version": 1, "stories": [')
    yield ["ida", str(broken), "--records", "builtin-suite", "-o", str(ida_out)], ["JSON"], ida_out
    wrong = tmp / "wrong.json"
    wrong.write_text(json.dumps({"format": "hlaid-clone", "version": 99, "stories": []}))
    yield ["ida", str(wrong), "--records", "builtin-suite", "-o", str(ida_out)], ["version"], ida_out
    empty = tmp / "empty_records"
    empty.mkdir()
    yield ["ida", str(clone), "--records", str(empty), "-o", str(ida_out)], ["record"], ida_out
    yield ["ida", str(clone), "--records", "builtin-suite", "--levels", "0.5", "0.3", "-o", str(ida_out)], \
        ["increasing"], ida_out
    yield ["export-opensees", str(tmp / "none.json"), "-o", str(tmp / "m.py")], ["not found"], tmp / "m.py"

    rc = tmp / "run.yaml"
    rc.write_text(f"measurement: {{file: '{meas}', simulate: {{building: {{stories: []}}, motion: {{file: x}}}}}}\n")
    yield ["run", str(rc), "-o", str(tmp / "run_out")], ["stories", "exactly one"], tmp / "run_out"
    yield ["report", str(tmp)], ["run folder"], None
    taken = tmp / "taken"
    taken.mkdir()
    (taken / "keep.txt").write_text("mine")
    yield ["demo", "--out", str(taken)], ["exists"], None


def test_bad_input_suite(tmp_path, capsys, meas_file, clone_file):
    meas, m = meas_file
    n = 0
    for argv, expect, out in cases(tmp_path, meas, m, clone_file):
        _check(capsys, argv, expect, out)
        n += 1
    assert n >= 25
    assert (tmp_path / "taken" / "keep.txt").read_text() == "mine"  # nothing the user had is lost


def test_usage_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        main(["no-such-command"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "invalid choice" in err


def test_console_script_prints_no_traceback(tmp_path):
    bad = tmp_path / "x.npz"
    bad.write_text("nonsense")
    r = subprocess.run([sys.executable, "-m", "hlaid", "hla", str(bad), "-o", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
