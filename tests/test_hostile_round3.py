"""Hostile inputs, third round: every container bounded while it is read, internal errors turned
into one-line refusals, checks moved before the work, values that make no sense refused. Each case
is exit 2 with one line and leaves the sandbox (``tmp_path``) as it was."""

from __future__ import annotations

import io
import json
import os
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from test_hostile import HEIGHTS, _clone_dict, _measurement, refused, tree
from test_loss import needs_pelicun

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.record import EventRecord

REPO = Path(__file__).resolve().parents[1]
POSIX = pytest.mark.skipif(os.name != "posix", reason="FIFOs, rlimits and signals of POSIX")


@pytest.fixture()
def clone_file(table1, tmp_path) -> Path:
    return Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "clone.json")


def _cli(tmp_path: Path, argv: list, *, env: dict | None = None, pre: str = "") -> tuple[int, list[str], bool]:
    """``hlaid ARGV`` in a fresh interpreter: (exit status, stderr lines, whether torch was loaded)."""
    code = (f"import sys\n{pre}\nfrom hlaid.cli import main\nrc = main({[str(a) for a in argv]!r})\n"
            "print('TORCH' if 'torch' in sys.modules else 'LIGHT')\nsys.exit(rc)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": str(REPO), **(env or {})})
    return r.returncode, r.stderr.strip().splitlines(), "TORCH" in r.stdout


# ----------------------------------------------------------------------------- readers bounded while reading
def test_a_text_record_longer_than_the_sample_limit_is_refused_while_read(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HLAID_MAX_SAMPLES", "1000")
    csv = tmp_path / "long.csv"
    rows = np.column_stack([np.arange(3000) * 0.01, np.sin(np.arange(3000)) * 1000, np.cos(np.arange(3000)) * 900])
    csv.write_text("# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n" + "\n".join(",".join(f"{v:.6g}" for v in r)
                                                                             for r in rows) + "\n")
    line = refused(capsys, ["hla", csv, "-o", tmp_path / "o"], ["holds more than 2,000 lines"], root=tmp_path)
    assert "HLAID_MAX_SAMPLES" in line
    at2 = tmp_path / "big.AT2"
    at2.write_text("PEER NGA STRONG MOTION DATABASE RECORD\nx\nACCELERATION TIME SERIES IN UNITS OF G\n"
                   "NPTS= 10000000, DT= .0100 SEC\n" + " 0.1 0.2 0.3 0.4 0.5\n" * 100)
    from hlaid.motions.at2 import read_at2
    with pytest.raises(InputError, match="NPTS = 10000000 exceeds the limit"):
        read_at2(at2)


def test_an_npz_whose_headers_claim_too_many_samples_is_refused_from_its_headers(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HLAID_MAX_SAMPLES", "1000")
    m = tmp_path / "m.npz"
    with open(m, "wb") as fh:
        np.savez(fh, dt=0.01, ground_acc=np.zeros(5000), floor_acc=np.zeros((5000, 1)))
    refused(capsys, ["hla", m, "-o", tmp_path / "o"], ["claims 5,000 samples"], root=tmp_path)


def _v2_zip(inner_size: int) -> bytes:
    inner = io.BytesIO()
    with zipfile.ZipFile(inner, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("CHAN001.V2", b"0" * inner_size)
    outer = io.BytesIO()
    with zipfile.ZipFile(outer, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("Free Field.zip", inner.getvalue())
    return outer.getvalue()


def test_a_nested_csmip_zip_is_bounded_as_a_whole(tmp_path, monkeypatch):
    from hlaid.io.csmip import read_csmip_channels
    monkeypatch.setenv("HLAID_MAX_FILE_MB", "1")
    p = tmp_path / "bomb.zip"
    p.write_bytes(_v2_zip(3 * 2**20))  # 3 MiB of zeros in a zip in a zip: a few KiB
    assert p.stat().st_size < 50_000
    with pytest.raises(InputError, match="zip bomb"):
        read_csmip_channels(p)


def test_a_mat_file_is_bounded_while_it_is_inflated(tmp_path, monkeypatch):
    from scipy.io import savemat

    from hlaid.io._matfile import check_mat5
    monkeypatch.setenv("HLAID_MAX_FILE_MB", "1")
    p = tmp_path / "bomb.mat"
    savemat(p, {"x": np.zeros(2**19)}, do_compression=True)  # 4 MiB of doubles, a few KiB on disk
    with pytest.raises(InputError, match="decompression bomb"):
        check_mat5(p.read_bytes(), str(p))


@POSIX
def test_a_pseudo_file_that_waits_for_data_is_refused_not_waited_on(tmp_path, monkeypatch):
    """A file that stat calls regular but whose read waits (/proc/kmsg): here a FIFO with a writer
    that never writes, shown to the reader as a regular file."""
    from hlaid import _inputs
    fifo = tmp_path / "kmsg"
    os.mkfifo(fifo)
    writer = os.open(fifo, os.O_RDWR | os.O_NONBLOCK)  # keeps it open for writing, writes nothing
    real = os.fstat

    def fstat(fd):
        st = real(fd)
        if stat.S_ISFIFO(st.st_mode):
            return os.stat_result((stat.S_IFREG | 0o400, *st[1:6], 0, *st[7:]))
        return st
    monkeypatch.setattr(_inputs.os, "fstat", fstat)
    try:
        from test_hostile import deadline
        with deadline(10), pytest.raises(InputError, match="waits for data"):
            _inputs.read_text(fifo)
    finally:
        os.close(writer)


# ----------------------------------------------------------------------------- internal errors
def test_names_longer_than_the_file_system_allows_are_one_line(tmp_path, capsys, clone_file):
    line = refused(capsys, ["ida", clone_file, "--records", "r" * 300, "-o", tmp_path / "o"],
                   ["longer than the file system allows"], root=tmp_path)
    assert len(line) < 400


def test_a_config_value_or_file_too_large_is_refused_at_once(tmp_path, capsys, clone_file):
    cfg = tmp_path / "ida.yaml"
    cfg.write_text("records: " + "x" * 100_000 + "\n")
    line = refused(capsys, ["ida", clone_file, "--config", cfg, "-o", tmp_path / "o"], ["a value of 100,000"],
                   root=tmp_path)
    assert len(line) < 300
    big = tmp_path / "big.yaml"
    with open(big, "wb") as fh:
        fh.truncate(100 * 2**20)  # sparse
    refused(capsys, ["ida", clone_file, "--config", big, "-o", tmp_path / "o"], ["a config is at most 16 MiB"],
            root=tmp_path)


@pytest.mark.parametrize("band", [("0", "1e-300"), ("1e-12", "2e-12")])
def test_tiny_filter_bands_are_refused(tmp_path, capsys, clone_file, table1, band):
    m = _measurement(tmp_path / "ev.npz", table1)
    refused(capsys, ["predict", clone_file, m, "--band", *band, "-o", tmp_path / "p"], ["cannot be designed",
                                                                                        "at least 0.001 Hz"],
            root=tmp_path, within=120)


def test_an_hla_band_below_any_design_is_refused():
    from hlaid.hla.config import PreprocessConfig
    with pytest.raises(InputError, match="cannot be designed"):
        PreprocessConfig(band_hz=(0.0, 1e-300))


@POSIX
def test_a_file_size_limit_is_one_line_and_leaves_nothing(tmp_path, clone_file):
    import resource
    code = ("import resource, sys\nresource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))\n"
            f"from hlaid.cli import main\nsys.exit(main(['export-opensees', {str(clone_file)!r}, '-o', 'm.py']))\n")
    before = tree(tmp_path)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": str(REPO)})
    assert resource.RLIMIT_FSIZE
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "ulimit -f" in lines[0], lines
    assert tree(tmp_path) == before


def _chattr(path: Path, flag: str) -> bool:
    try:
        return subprocess.run(["chattr", flag, str(path)], capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


@POSIX
def test_force_on_an_immutable_output_is_refused_before_the_work(tmp_path, capsys, clone_file):
    from hlaid._fileio import atomic_directory
    target = tmp_path / "model.py"
    target.write_text("# mine\n")
    out = tmp_path / "hout"
    with atomic_directory(out, what="hlaid hla") as tmp:
        (tmp / "hla.json").write_text("{}")
    if not _chattr(target, "+i"):
        pytest.skip("chattr +i is not available here")
    try:
        _chattr(out / "hla.json", "+i")
        refused(capsys, ["export-opensees", clone_file, "-o", target, "--force"], ["immutable"], root=tmp_path)
        refused(capsys, ["hla", _measurement(tmp_path / "m.npz", Clone.load(clone_file).building), "-o", out,
                         "--force"], ["cannot be removed"], root=tmp_path)
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    finally:
        _chattr(target, "-i")
        _chattr(out / "hla.json", "-i")


def test_force_on_a_file_whose_replacement_is_refused_is_one_line(tmp_path, capsys, clone_file, monkeypatch):
    import errno
    import shutil
    target = tmp_path / "model.py"
    target.write_text("# mine\n")
    real = os.replace

    def refuse(src, dst, *a, **k):
        if Path(dst) == target:
            raise PermissionError(errno.EPERM, "Operation not permitted", str(dst))
        return real(src, dst, *a, **k)
    monkeypatch.setattr(os, "replace", refuse)
    monkeypatch.setattr(shutil, "copyfile", lambda s, d, *a, **k: refuse(s, d))
    refused(capsys, ["export-opensees", clone_file, "-o", target, "--force"], ["cannot be replaced"], root=tmp_path)


@pytest.mark.parametrize("key", ["path", "kind", "format"])
def test_reserved_reader_options_are_refused_in_a_config(tmp_path, capsys, key):
    cfg = tmp_path / "run.yaml"
    cfg.write_text(f"measurement: {{file: m.npz, options: {{{key}: x}}}}\n")
    refused(capsys, ["run", cfg, "-o", tmp_path / "o"], [f"options.{key} is not a reader option"], root=tmp_path)


def test_fleet_cluster_settings_and_scheduler_ports_are_checked(tmp_path, capsys):
    from test_hostile import _fleet_yaml
    fleet = _fleet_yaml(tmp_path)
    fleet.write_text(fleet.read_text() + "cluster: {memory_limit: lots}\n")
    refused(capsys, ["fleet", fleet, "-o", tmp_path / "f"], ["memory_limit"], root=tmp_path)
    refused(capsys, ["fleet", fleet, "-o", tmp_path / "f", "--scheduler", "tcp://localhost:\u00b2"],
            ["the port must be a number"], root=tmp_path)


# ----------------------------------------------------------------------------- checks before the work
def test_reading_a_clone_needs_no_scipy(tmp_path, table1):
    from hlaid.model.uncertainty import ParameterUncertainty
    c = Clone(building=table1.replace(height=HEIGHTS), uncertainty=ParameterUncertainty(
        slots=(("k0", 0),), transform=("log",), centre=np.array([np.log(1e4)]), covariance=np.array([[0.01]])))
    p = c.save(tmp_path / "c.json")
    code = f"import sys\nfrom hlaid.clone import Clone\nClone.load({str(p)!r})\nprint('scipy' in sys.modules)\n"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(REPO)})
    assert r.stdout.strip() == "False", r.stderr


def test_ida_refusals_from_the_command_line_come_before_torch(tmp_path, table1):
    noh = Clone(building=table1).save(tmp_path / "noh.json")
    h = Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "h.json")
    (tmp_path / "empty").mkdir()
    for argv, expect in ((["ida", noh, "-o", "o"], "story heights are unknown"),
                         (["ida", h, "--heights", "3000", "-o", "o"], "the building has 3 stories"),
                         (["ida", h, "--records", "missing", "-o", "o"], "not found"),
                         (["ida", h, "--records", "empty", "-o", "o"], "no record files"),
                         (["predict", h, "m.npz", "--seed", "-1"], "--seed = -1 is out of range"),
                         (["demands", h, "--records", "builtin-suite", "--level", "1e300", "-o", "d.csv"],
                          "--level = 1e+300 is out of range")):
        rc, err, torch = _cli(tmp_path, argv)
        assert rc == 2 and len(err) == 1 and expect in err[0], (argv, err)
        assert not torch, argv


def test_run_refuses_a_missing_measurement_or_bad_records_before_the_pipeline(tmp_path):
    cfg = tmp_path / "run.yaml"
    cfg.write_text("measurement: {file: missing.npz}\n")
    rc, err, torch = _cli(tmp_path, ["run", cfg, "-o", "o"])
    assert rc == 2 and len(err) == 1 and "missing.npz: file not found" in err[0] and not torch, err
    m = _measurement(tmp_path / "m.npz", Clone(building=_table1()).building)
    cfg.write_text(f"measurement: {{file: {m.name}}}\nida: {{records: {tmp_path / 'empty'}}}\n")
    (tmp_path / "empty").mkdir()
    rc, err, torch = _cli(tmp_path, ["run", cfg, "-o", "o"])
    assert rc == 2 and len(err) == 1 and "no record files" in err[0] and not torch, err
    assert not (tmp_path / "o").exists()


def _table1():
    from conftest import table1_stories

    from hlaid.model import Building
    return Building.from_stories(table1_stories(), name="table1", pdelta=False)


def test_fleet_config_errors_come_before_a_cluster_starts(tmp_path, capsys, table1):
    from test_hostile import _fleet_yaml
    fleet = _fleet_yaml(tmp_path)  # one record, an ensemble assessment, a measurement that is missing
    refused(capsys, ["fleet", fleet, "-o", tmp_path / "f"], ["needs at least 2 IDA records"], root=tmp_path)
    fleet.write_text(fleet.read_text().replace("records: builtin:elcentro-1940-ns", "records: builtin-suite"))
    refused(capsys, ["fleet", fleet, "-o", tmp_path / "f"], ["b1.npz: file not found"], root=tmp_path)


# ----------------------------------------------------------------------------- values that make no sense
def test_a_constant_or_complex_record_is_refused(tmp_path, capsys, table1):
    t = np.arange(2000) * 0.01
    g = 2000.0 * np.sin(2 * np.pi * 1.3 * t)
    for name, ground, floors in (("flat.npz", np.full(t.size, 1000.0), g[:, None] * [1, 1.5, 2]),
                                 ("still.npz", g, np.column_stack([g, np.full(t.size, 5.0), g])),
                                 ("complex.npz", g + 0j, g[:, None] * [1, 1.5, 2])):
        p = tmp_path / name
        with open(p, "wb") as fh:
            np.savez(fh, dt=0.01, ground_acc=ground, floor_acc=floors, mass=table1.mass)
        refused(capsys, ["hla", p, "-o", tmp_path / "o"], ["is constant", "complex numbers"], root=tmp_path)


def test_absurd_clone_values_are_refused(tmp_path, capsys, table1):
    d = _clone_dict(table1)
    d["state"] = {"drift": [9e5, 0, 0], "z": [0, 0, 0], "work": [0, 0, 0], "peak_positive": [9e5, 0, 0],
                  "peak_negative": [0, 0, 0]}
    c = tmp_path / "state.json"
    c.write_text(json.dumps(d))
    refused(capsys, ["export-opensees", c, "-o", tmp_path / "m.py"], ["has collapsed"], root=tmp_path)
    from hlaid.model.uncertainty import ParameterUncertainty
    d = Clone(building=table1.replace(height=HEIGHTS), uncertainty=ParameterUncertainty(
        slots=(("k0", 0),), transform=("log",), centre=np.array([np.log(1e4)]),
        covariance=np.array([[0.01]]))).to_dict()
    d["uncertainty"]["covariance"] = [[1e3]]
    d["uncertainty"]["parameters"][0]["std"] = 1e3 ** 0.5
    c.write_text(json.dumps(d))
    refused(capsys, ["export-opensees", c, "-o", tmp_path / "m.py"], ["standard deviation of 31.6"], root=tmp_path)


def test_a_gravity_load_beyond_the_stories_stiffness_is_refused(tmp_path, capsys, clone_file):
    refused(capsys, ["ida", clone_file, "--gravity-kN", "1e9,1e9,1e9", "--records", "builtin-suite", "-o",
                     tmp_path / "o"], ["would buckle under its own weight"], root=tmp_path, within=120)


@pytest.mark.parametrize("variant", ["csv6", "trimmed", "scaled", "padded"])
def test_update_refuses_its_own_event_written_differently(tmp_path, capsys, table1, variant):
    from hlaid.events.identify import event_record
    from hlaid.io import read
    from hlaid.measurement import Measurement, check_not_learnt
    m = _measurement(tmp_path / "ev1.npz", table1)
    meas = read(m, "measurement")
    d = _clone_dict(table1)
    d["events"] = [event_record(meas).to_dict()]
    clone = tmp_path / "clone.json"
    clone.write_text(json.dumps(d))
    g, f = np.asarray(meas.ground_acc), np.asarray(meas.floor_acc)
    if variant == "trimmed":
        g, f = g[:-1], f[:-1]
    elif variant == "scaled":
        g, f = g * (1 + 1e-12), f * (1 + 1e-12)
    elif variant == "padded":
        g, f = np.r_[g, 0.0], np.vstack([f, np.zeros((1, f.shape[1]))])
    p = tmp_path / ("copy.csv" if variant == "csv6" else "copy.npz")
    if variant == "csv6":
        p.write_text("# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1,floor_acc_2,floor_acc_3\n" + "\n".join(
            ",".join(f"{v:.6g}" for v in (i * 0.01, g[i], *f[i])) for i in range(g.size)) + "\n")
    else:
        with open(p, "wb") as fh:
            np.savez(fh, dt=meas.dt, ground_acc=g, floor_acc=f, mass=meas.mass)
    refused(capsys, ["update", clone, p, "-o", tmp_path / "c2.json"], ["has learnt from this event already"],
            root=tmp_path, within=120)
    # another record of the same peak, duration and sample interval is another event
    other = _measurement(tmp_path / "ev2.npz", table1, seed=7)
    o = read(other, "measurement")
    scaled = Measurement(dt=o.dt, ground_acc=np.asarray(o.ground_acc)[::-1] * 1.0, floor_acc=o.floor_acc)
    scaled = Measurement(dt=o.dt, floor_acc=o.floor_acc, ground_acc=np.asarray(scaled.ground_acc)
                         * (np.abs(meas.ground_acc).max() / np.abs(scaled.ground_acc).max()))
    check_not_learnt([EventRecord.from_dict(e) for e in d["events"]], scaled)


# ----------------------------------------------------------------------------- messages
@POSIX
def test_ctrl_c_while_the_command_line_loads_is_one_line(tmp_path):
    pre = ("import os, signal\nclass Hook:\n    def find_spec(self, name, path, target=None):\n"
           "        if name == 'hlaid.cli.app':\n            os.kill(os.getpid(), signal.SIGINT)\n"
           "        return None\nsys.meta_path.insert(0, Hook())\n")
    rc, err, _ = _cli(tmp_path, ["--help"], pre=pre)
    assert rc == 130 and err == ["hlaid: interrupted"], err


def test_an_empty_home_puts_no_cache_at_the_root(monkeypatch):
    from hlaid.identify.cache import default_cache_dir
    monkeypatch.delenv("HLAID_CACHE", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", "")
    with pytest.warns(Warning, match="HOME names no folder"):
        assert default_cache_dir() is None


def test_an_event_source_longer_than_a_file_name_is_said_not_raised():
    from hlaid.events.evidence import read_event
    meas, why = read_event(EventRecord(name="e1", source="s" * 300 + ".npz"))
    assert meas is None and "cannot be looked up" in why and len(why) < 300


@needs_pelicun  # the inventory is read by pelicun's loss assessment
def test_an_inventory_quantity_no_building_holds_is_refused(tmp_path, capsys):
    demands = tmp_path / "d.csv"
    demands.write_text(",1-PID-1-1,1-PID-2-1,1-PID-3-1,1-RID-1-1\nUnits,rad,rad,rad,rad\n"
                       + "".join(f"{i},0.01,0.012,0.008,0.001\n" for i in range(5)))
    inv = tmp_path / "inv.csv"
    inv.write_text("ID,Units,Location,Direction,Theta_0\nB.10.35.021,ea,1,1,999999\n")
    refused(capsys, ["loss", demands, "-o", tmp_path / "loss", "--floor-area", "100", "--inventory", inv],
            ["line 2: column Theta_0: 999999 is 1e+04 per m2"], root=tmp_path, within=120)


def test_a_survived_drift_beyond_the_story_height_names_the_clone(tmp_path, capsys, table1):
    d = _clone_dict(table1)
    d["system"] = "steel-moment-frame"
    d["events"] = [{"name": "e1", "peak_drift": [4000.0, 10.0, 10.0]}]
    c = tmp_path / "drift.json"
    c.write_text(json.dumps(d))
    line = refused(capsys, ["export-opensees", c, "-o", tmp_path / "m.py"], ["survived a drift of 4000 mm"],
                   root=tmp_path, within=120)
    assert "drift.json" in line and "--heights" in line
