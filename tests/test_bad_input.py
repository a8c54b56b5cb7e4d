"""Bad input across every command: each case exits with status 2 and one line on
stderr naming the problem, never a traceback, and leaves no output behind."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.cli.app import main
from hlaid.errors import HlaidWarning
from hlaid.synthetic import simulate_measurement

AT2_HEAD = ("PEER NGA STRONG MOTION DATABASE RECORD\nTest, 1/1/2000, Nowhere, 0\n"
            "ACCELERATION TIME SERIES IN UNITS OF G\n")


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
    two = _npz(tmp / "two.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=m.floor_acc[:, :2], mass=m.mass[:2])
    yield ["identify", str(meas), str(two), "-o", str(c)], ["records of one building"], c
    late = _npz(tmp / "late.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass,
                recorded=np.array("2021-05-01T10:00:00Z"))
    early = _npz(tmp / "early.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass,
                 recorded=np.array("2020-05-01T10:00:00Z"))
    yield ["identify", str(late), str(early), "-o", str(c)], ["time order"], c
    yield ["identify", str(meas), str(meas), "-o", str(c)], ["each event once"], c
    stamp = _npz(tmp / "stamp.npz", dt=m.dt, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass,
                 recorded=np.array("yesterday"))
    yield ["identify", str(stamp), "-o", str(c)], ["ISO 8601"], c
    yield ["update", str(clone), str(two), "-o", str(c)], ["not of this building"], c
    yield ["update", str(clone), str(meas), "-o", str(c), "--widen", "0"], ["--widen"], c
    yield ["update", str(clone), str(meas), "-o", str(clone)], ["input"], None
    pred = tmp / "pred"
    yield ["predict", str(clone), str(two), "-o", str(pred)], ["not of this building"], pred
    yield ["predict", str(clone), str(meas), "-o", str(pred), "--band", "2", "1"], ["--band"], pred
    yield ["predict", str(clone), str(meas), "-o", str(pred), "--ensemble", "-1"], ["--ensemble"], pred
    yield ["predict", str(tmp / "none.json"), str(meas), "-o", str(pred)], ["not found"], pred

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


# ----------------------------------------------------------------- hardening
def _one_line(capsys, argv, expect, out=None, *, code=2, max_lines=1):
    """``main(argv)`` exits with ``code`` and one line on stderr (``max_lines`` when warnings are
    expected first) holding one of ``expect``, no traceback, and ``out`` was not written."""
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == code, (argv, err)
    assert err and len(err) <= max_lines, err
    assert "Traceback" not in "\n".join(err) and "internal error" not in err[-1]
    assert any(e.lower() in err[-1].lower() for e in expect), err[-1]
    if out is not None:
        assert not Path(out).exists(), f"output written at {out}"
    return err[-1]


HOSTILE_NAMES = ['b""";import os;os.system("touch {s}");"""',
                 "x'\nimport os; os.system('touch {s}')\n#",
                 "\\'''\\\"\"\"; __import__('os').system('touch {s}'); #\r\n\\"]


@pytest.mark.parametrize("pattern", HOSTILE_NAMES)
def test_hostile_clone_name_runs_no_code_in_the_exported_script(tmp_path, capsys, table1, pattern):
    """The clone's name (``hlaid identify`` takes it from the measurement's file name) is written
    into the script as data only: running or importing the script never runs the payload."""
    from hlaid.clone import Clone
    sentinel = tmp_path / "SENTINEL"
    name = pattern.format(s=sentinel)
    clone = Clone(building=table1.replace(name=name)).save(tmp_path / "clone.json")
    script = tmp_path / "model.py"
    assert main(["export-opensees", str(clone), "-o", str(script)]) == 0
    capsys.readouterr()
    text = script.read_text(encoding="utf-8")
    compile(text, str(script), "exec")
    rec = tmp_path / "tiny.txt"
    rec.write_text("".join(f"{0.01 * i:.2f} {0.05 * np.sin(0.05 * i):.6f}\n" for i in range(100)))
    for argv in ([str(script), str(rec), "--units", "g"], ["-c", f"import runpy; runpy.run_path({str(script)!r})"]):
        subprocess.run([sys.executable, *argv], capture_output=True, text=True, cwd=tmp_path, timeout=300)
        assert not sentinel.exists(), f"the clone name ran as code ({argv[0]})"


def test_identify_names_the_clone_after_the_file_and_the_name_stays_data(tmp_path, meas_file):
    """``hlaid identify`` names the clone after the measurement file: a hostile file name is only data."""
    from hlaid.io import read
    from hlaid.opensees import opensees_script
    meas, _ = meas_file
    hostile = tmp_path / 'b""";import os;os.system("touch X");""".npz'
    hostile.write_bytes(meas.read_bytes())
    m = read(hostile, "measurement")
    assert m.name == 'b""";import os;os.system("touch X");"""'
    import ast
    tree = ast.parse(opensees_script(m.truth.building.replace(name=m.name)))
    consts = [n.value.value for n in tree.body if isinstance(n, ast.Assign) and n.targets[0].id == "NAME"]
    assert consts == [m.name]


BILLION_LAUGHS = ('a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
                  "b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]\n"
                  "d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]\ne: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]\n"
                  "f: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]\ng: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]\n"
                  "h: &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]\ni: &i [*h,*h,*h,*h,*h,*h,*h,*h,*h]\n")


@pytest.mark.parametrize("text,line", [
    (BILLION_LAUGHS, 2),
    ("a: &x [1, *x]\n", 1),                                  # recursive alias
    ("building: &b {stories: []}\nmotion: *b\n", 2),          # a plain alias
    ("base: &b {seed: 1}\nother:\n  <<: *b\n", 3),             # a merge key is an alias too
])
def test_yaml_aliases_are_refused_at_once(tmp_path, capsys, text, line):
    import time

    from hlaid.config import load_config
    from hlaid.errors import ConfigError
    from hlaid.synthetic import SimulationConfig
    cfg = tmp_path / "bomb.yaml"
    cfg.write_text(text)
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=rf"bomb.yaml:{line}: YAML aliases"):
        load_config(cfg, SimulationConfig)
    assert time.perf_counter() - t0 < 1.0
    out = tmp_path / "out.npz"
    t0 = time.perf_counter()
    msg = _one_line(capsys, ["simulate", cfg, "-o", out], ["alias"], out)
    assert time.perf_counter() - t0 < 5.0  # a guard: it takes milliseconds
    assert f"bomb.yaml:{line}:" in msg
    for command in (["identify", "x.npz", "-o", tmp_path / "c.json", "--config", cfg],
                    ["hla", "x.npz", "-o", tmp_path / "h", "--config", cfg],
                    ["run", cfg, "-o", tmp_path / "r"],
                    ["ida", "x.json", "--config", cfg, "-o", tmp_path / "i"]):
        _one_line(capsys, command, ["alias", "not found"], command[command.index("-o") + 1])


def test_yaml_python_tags_and_deep_nesting_are_input_errors(tmp_path, capsys):
    out = tmp_path / "o.npz"
    for name, text, expect in (("tag.yaml", "building: !!python/object/apply:os.system ['touch X']\n", "expected"),
                               ("tag2.yaml", "building: !!python/name:os.system ''\n", "invalid YAML"),
                               ("deep.yaml", "a: " + "[" * 5000 + "]" * 5000 + "\n", "invalid YAML")):
        (tmp_path / name).write_text(text)
        _one_line(capsys, ["simulate", tmp_path / name, "-o", out], [expect], out)
    assert not (tmp_path / "X").exists()


def test_input_at_fault_is_status_2(tmp_path, capsys, meas_file, clone_file):
    meas, m = meas_file
    o = tmp_path / "hla_out"
    for dt, what in ((1e6, "1e-06 Hz"), (1e-9, "1e+09 Hz"), (0.5, "2 Hz")):
        bad = _npz(tmp_path / f"dt{dt:g}.npz", dt=dt, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass)
        msg = _one_line(capsys, ["hla", bad, "-o", o], ["sample rate"], o)
        assert "dt" in msg and what in msg and bad.name in msg
        _one_line(capsys, ["identify", bad, "-o", tmp_path / "c.json"], ["sample rate"], tmp_path / "c.json")
    # band-pass corners above the Nyquist frequency of a legal (if slow) record
    slow = _npz(tmp_path / "slow.npz", dt=0.1, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass)
    band = tmp_path / "band.yaml"
    band.write_text("preprocess: {band_hz: [6.0, 20.0]}\n")
    msg = _one_line(capsys, ["hla", slow, "-o", o, "--config", band], ["band_hz"], o, max_lines=2)
    assert "Nyquist" in msg and "slow.npz" in msg
    band.write_text("refine: {band_hz: [6.0, 20.0]}\n")
    _one_line(capsys, ["identify", slow, "-o", tmp_path / "c.json", "--config", band], ["refine.band_hz"],
              tmp_path / "c.json", max_lines=2)
    # an existing folder as the output file, even with --force, is refused before the work
    folder = tmp_path / "a_folder"
    folder.mkdir()
    cfg = tmp_path / "sim.yaml"
    cfg.write_text("building:\n  stories:\n    - {weight_kN: 171.85, k0: 1.94e4, alpha: 0.23, p: 2.5, dy: 7.0, "
                   "delta_eta: 0.7}\nmotion: {file: 'builtin:elcentro-1940-ns'}\n")
    for argv in (["simulate", cfg, "-o", folder, "--force"], ["export-opensees", clone_file, "-o", folder, "--force"],
                 ["identify", meas, "-o", folder, "--force"]):
        _one_line(capsys, argv, ["is a folder"])
        assert folder.is_dir() and not any(folder.iterdir())


def test_unusual_sample_rate_warns(tmp_path, capsys, meas_file):
    from hlaid.io import read
    _, m = meas_file
    fast = _npz(tmp_path / "fast.npz", dt=1e-4, ground_acc=m.ground_acc, floor_acc=m.floor_acc, mass=m.mass)
    with pytest.warns(HlaidWarning) as seen:
        read(fast, "measurement")
    err = " ".join(str(w.message) for w in seen)
    assert "10000 Hz" in err and "fast.npz" in err
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read(_npz(tmp_path / "usual.npz", dt=0.005, ground_acc=m.ground_acc, floor_acc=m.floor_acc), "measurement")
    assert capsys.readouterr().err == ""


RUN_CONFIG = """# a run config whose ida block has an error on line 17
name: lines
measurement:
  file: meas.npz
  mass_t: [17.5, 17.5, 9.2]
  height_mm: [3000, 3000, 3000]
identify:
  outer:
    tol: 0.02
    max_iterations: {iterations}
  refine:
    method: eiv
ida:
  records: builtin-suite
  im: sa_t1
  drift_limit: 0.10
  n_levels: {levels}
  bootstrap: 50
"""


@pytest.mark.parametrize("iterations,levels,line,expect", [
    (3, 1, 17, "n_levels"), (3, "abc", 17, "n_levels"), (-1, 15, 10, "max_iterations"), (3, "[1, 2]", 17, "n_levels"),
])
def test_errors_in_nested_blocks_name_the_value_line(tmp_path, capsys, iterations, levels, line, expect):
    cfg = tmp_path / "run.yaml"
    cfg.write_text(RUN_CONFIG.format(iterations=iterations, levels=levels))
    assert cfg.read_text().splitlines()[line - 1].strip().startswith(expect)
    msg = _one_line(capsys, ["run", cfg, "-o", tmp_path / "out"], [expect], tmp_path / "out")
    assert f"run.yaml:{line}:" in msg


def test_nested_unknown_key_names_its_line(tmp_path, capsys):
    cfg = tmp_path / "run.yaml"
    cfg.write_text(RUN_CONFIG.format(iterations=3, levels=15).replace("  bootstrap: 50", "  bootstrapp: 50"))
    msg = _one_line(capsys, ["run", cfg, "-o", tmp_path / "out"], ["bootstrapp"], tmp_path / "out")
    assert "run.yaml:18:" in msg and "ida.bootstrapp" in msg


@pytest.mark.parametrize("block,expect", [
    ("outer: {max_iterations: -1}", "max_iterations"), ("outer: {max_iterations: 0}", "max_iterations"),
    ("refine: {max_iterations: -5}", "max_iterations"), ("n_jobs: 0", "n_jobs"),
    ("damping_ratio: 1.5", "damping_ratio"),
    ("training: {samples: 0}", "samples"), ("training: {seed: -1}", "seed"),
    ("svm: {C: -1}", "C = -1"), ("svm: {kernel: rbff}", "kernel"), ("refine: {band_hz: [5, 1]}", "band_hz"),
    ("outer: {tol: 0}", "tol"),
])
def test_identify_config_integers_and_ranges_are_checked(tmp_path, capsys, meas_file, block, expect):
    meas, _ = meas_file
    cfg = tmp_path / "identify.yaml"
    cfg.write_text(f"# identification\n{block}\n")
    out = tmp_path / "c.json"
    msg = _one_line(capsys, ["identify", meas, "-o", out, "--config", cfg], [expect], out)
    assert "identify.yaml:2:" in msg


def _clone_dict(table1) -> dict:
    from hlaid.clone import Clone
    return Clone(building=table1.replace(height=[3000.0] * 3)).to_dict()


@pytest.mark.parametrize("change,expect", [
    (lambda d: d.update(colour="red"), "unknown field 'colour'"),
    (lambda d: d["stories"][1].update(k00=1.0), "unknown field 'stories[1].k00'"),
    (lambda d: d["damping"].update(zeta=0.05), "unknown field 'damping.zeta'"),
    (lambda d: d["units"].update(length="m"), "units.length"),
    (lambda d: d["units"].update(force="kN"), "units.force"),
    (lambda d: d["units"].pop("time"), "units.time"),
    (lambda d: d.update(units="SI"), "units"),
    (lambda d: d.update(pdelta="yes"), "pdelta"),
    (lambda d: d.update(pdelta=1), "pdelta"),
    (lambda d: d.update(mass_normalised="false"), "mass_normalised"),
    (lambda d: d.update(name=["a"]), "name"),
    (lambda d: d.update(diagnostics=[1]), "diagnostics"),
    (lambda d: d.update(damping="rayleigh"), "damping"),
    (lambda d: d["damping"].update(ratio="0.05"), "damping.ratio"),
    (lambda d: d["damping"].update(modes="1,2"), "damping.modes"),
    (lambda d: d["stories"][0].update(height="3000"), "stories[0].height"),
    (lambda d: d["stories"][2].pop("dy"), "stories[2].dy is missing"),
])
def test_clone_files_are_read_strictly(tmp_path, capsys, table1, change, expect):
    d = _clone_dict(table1)
    change(d)
    bad = tmp_path / "clone.json"
    bad.write_text(json.dumps(d))
    for argv, out in ((["export-opensees", bad, "-o", tmp_path / "m.py"], tmp_path / "m.py"),
                      (["ida", bad, "--records", "builtin-suite", "-o", tmp_path / "ida"], tmp_path / "ida")):
        msg = _one_line(capsys, argv, [expect], out)
        assert "clone.json" in msg


def test_clone_without_units_block_still_reads(tmp_path, table1):
    from hlaid.clone import Clone
    d = _clone_dict(table1)
    d.pop("units")
    assert Clone.from_dict(d).building.n_stories == 3


# ------------------------------------------------------------------------ hlaid report
_PNG = b"\x89PNG\r\n\x1a\n" + bytes(64)


def _run_folder(path: Path) -> Path:
    """A minimal run folder as hlaid run writes it (summary.json and its figures)."""
    from hlaid.run.report import FIGURES
    frag = {"median_g": 1.1, "beta": 0.4, "median_ci_g": [0.9, 1.3], "beta_ci": [0.3, 0.5], "n_records": 3,
            "n_censored": 0, "ci": 0.9}
    rows = [{"parameter": p, "story": 1, "identified": 1.0, "true": 1.02, "error": 0.02}
            for p in ("k0", "alpha", "p", "dy", "delta_eta")]
    s = {"format": "hlaid-run", "version": 1, "name": "<b>lines</b>", "hlaid_version": "0", "config": {},
         "source": "meas.npz", "n_stories": 1, "mass_normalised": False, "parameters": rows, "paper_method": rows,
         "replay": {"r_measured": [0.99], "r_true": [0.999], "stiffness_error": [0.01]}, "outer_iterations": 1,
         "identify_timings": {}, "timings": {"total": 1.0}, "noise_rms": 0.05,
         "ida": {"intensity_measure": {"name": "sa_t1", "label": "Sa(T1)", "period_s": 0.4}, "edp": "drift",
                 "collapse_criteria": {"drift_limit": 0.1, "slope_ratio": 0.2}, "records": [{}, {}, {}], "n_runs": 9,
                 "collapse_fragility": {"capacities": frag, "counts": frag},
                 "drift_limits": {"0.01": {"fragility": frag}}, "notes": ["a note"]}}
    path.mkdir()
    (path / "summary.json").write_text(json.dumps(s))
    for rel, _ in FIGURES:
        (path / rel).parent.mkdir(exist_ok=True)
        (path / rel).write_bytes(_PNG)
    return path


def test_report_of_a_valid_folder(tmp_path, capsys):
    from hlaid.run.report import embedded_figures
    run = _run_folder(tmp_path / "run")
    assert main(["report", str(run)]) == 0
    assert len(embedded_figures(run / "report.html")) == 6
    assert "<b>lines</b>" not in (run / "report.html").read_text()  # escaped


def _set(d, path, value):
    """Set (``KeyError``: remove) the field at ``path``, ``"a.0.b"`` or a tuple of keys."""
    keys = path.split(".") if isinstance(path, str) else path
    for k in keys[:-1]:
        d = d[int(k)] if isinstance(d, list) else d[k]
    key = int(keys[-1]) if isinstance(d, list) else keys[-1]
    if value is KeyError:  # remove the field
        del d[key]
    else:
        d[key] = value


@pytest.mark.parametrize("path,value,expect", [
    ("name", 5, "name"), ("n_stories", "3", "n_stories"), ("replay.r_measured", [], "r_measured"),
    ("replay.r_measured.0", "high", "replay.r_measured[0]"), ("replay", KeyError, "replay is missing"),
    ("parameters.0.identified", "1.0", "identified"), ("parameters.0", [], "parameters[0]"),
    ("timings.total", "1 s", "timings.total"), ("noise_rms", "5%", "noise_rms"),
    ("ida.collapse_fragility.capacities.median_g", "1.1", "median_g"),
    ("ida.collapse_fragility.capacities.median_ci_g", [1.0], "median_ci_g"),
    ("ida.drift_limits", {"one percent": {}}, "drift_limits"), ("ida.notes", [1], "notes"),
    ("ida.collapse_criteria.drift_limit", "10%", "drift_limit"), ("ida", [1], "ida"),
    ("paper_method.0.story", "1", "paper_method[0].story"), ("outer_iterations", None, "outer_iterations"),
    ("version", 3, "version 3 is not supported"), ("config", [], "config"),
    ("parameters.0.lo90", "wide", "parameters[0].lo90"),
])
def test_tampered_summary_is_status_2(tmp_path, capsys, path, value, expect):
    run = _run_folder(tmp_path / "run")
    s = json.loads((run / "summary.json").read_text())
    _set(s, path, value)
    (run / "summary.json").write_text(json.dumps(s))
    msg = _one_line(capsys, ["report", run], [expect], run / "report.html")
    assert "summary.json" in msg


def test_any_wrong_type_in_summary_is_an_input_error(tmp_path):
    """Every field, replaced by a value of each other JSON type, is reported or shown: never a crash."""
    from hlaid.errors import InputError
    from hlaid.run.report import build_report
    run = _run_folder(tmp_path / "run")
    good = json.loads((run / "summary.json").read_text())

    def leaves(o, prefix=()):
        items = o.items() if isinstance(o, dict) else enumerate(o) if isinstance(o, list) else ()
        for k, v in items:
            yield (*prefix, k)
            yield from leaves(v, (*prefix, k))

    n = 0
    for path in list(leaves(good)):
        for value in ("x", 1.5, True, None, [], {}, [1, "a"], KeyError):
            s = json.loads(json.dumps(good))
            _set(s, path, value)
            (run / "summary.json").write_text(json.dumps(s))
            try:
                build_report(run)
            except InputError as err:
                assert "\n" not in str(err)
            n += 1
    assert n > 300


@pytest.mark.parametrize("rel", ["figures/replay.png", "figures/loops.png", "ida/fragility.png"])
def test_report_with_a_missing_figure_is_status_2(tmp_path, capsys, rel):
    run = _run_folder(tmp_path / "run")
    (run / rel).unlink()
    msg = _one_line(capsys, ["report", run], ["missing"], run / "report.html")
    assert rel in msg


def test_report_with_a_figure_that_is_not_a_png(tmp_path, capsys):
    run = _run_folder(tmp_path / "run")
    (run / "figures" / "loops.png").write_text("not an image")
    _one_line(capsys, ["report", run], ["not a PNG"], run / "report.html")


# ---------------------------------------------------- no file contents in error messages
def _secret_file(tmp_path) -> tuple[str, set[str]]:
    """``/etc/passwd`` when there is one, else a look-alike; with the words it holds."""
    import re
    real = Path("/etc/passwd")
    text = real.read_text(errors="replace") if real.is_file() else ""
    text += ("zq7admin:x:0:0:Zq7 Secret Operator,,,:/home/zq7admin:/bin/zq7shell\n"
             "hunter2user:$6$saltsalt$hashhashhash:1001:1001::/srv/hunter2:/usr/bin/false\n")
    words = {w for w in re.split(r"[^A-Za-z0-9_$-]+", text) if len(w) >= 4}
    return text, words


def test_messages_do_not_echo_unrelated_files(tmp_path, capsys, clone_file):
    import re
    text, words = _secret_file(tmp_path)
    stderr = []
    for name in ("passwd", "passwd.txt", "passwd.csv", "passwd.AT2"):
        f = tmp_path / name
        f.write_text(text)
        # as a ground motion: a simulation's record and an IDA record
        cfg = tmp_path / f"sim-{name}.yaml"
        cfg.write_text("building:\n  stories:\n    - {weight_kN: 171.85, k0: 1.94e4, alpha: 0.23, p: 2.5, dy: 7.0, "
                       f"delta_eta: 0.7}}\nmotion: {{file: '{f}', units: g, dt: 0.01}}\n")
        for argv, out in ((["simulate", cfg, "-o", tmp_path / "o.npz"], tmp_path / "o.npz"),
                          (["ida", clone_file, "--records", f, "--units", "g", "-o", tmp_path / "ida"],
                           tmp_path / "ida"),
                          (["hla", f, "-o", tmp_path / "h"], tmp_path / "h"),
                          (["identify", f, "-o", tmp_path / "c.json"], tmp_path / "c.json"),
                          (["simulate", f, "-o", tmp_path / "o.npz"], tmp_path / "o.npz"),
                          (["export-opensees", f, "-o", tmp_path / "m.py"], tmp_path / "m.py"),
                          (["report", tmp_path], None)):
            rc = main([str(a) for a in argv])
            err = capsys.readouterr().err
            assert rc == 2 and "Traceback" not in err, (argv, err)
            assert out is None or not Path(out).exists()
            stderr.append(err.replace(str(tmp_path), "<tmp>"))
        for fmt in ("csv", "npz", "columns", "steel-frame", "mini-shake-table", "smc", "csmip"):
            from hlaid.errors import InputError
            from hlaid.io import read
            try:
                read(f, "measurement", format=fmt)
            except InputError as err:
                stderr.append(str(err).replace(str(tmp_path), "<tmp>"))
    seen = " ".join(stderr)
    leaked = {w for w in words if re.search(rf"(?<![A-Za-z0-9_$-]){re.escape(w)}(?![A-Za-z0-9_$-])", seen)}
    assert not leaked, f"file contents in messages: {sorted(leaked)[:10]}"
