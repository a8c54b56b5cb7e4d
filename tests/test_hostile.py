"""Hostile and careless input: every case is refused with exit status 2 (130/143 for signals) and
one line on stderr, within a deadline (nothing hangs or allocates gigabytes), and nothing outside
the output is touched (the folder tree is hashed before and after).

Covered: ``--force`` never replaces what hlaid did not write nor an input of the run; every file is
read as a regular file within its size limit; NPZ headers are checked before allocation; config
values, clone fields and ``HLAID_MAX_*`` are bounded (the generated sweep over every field is in
``tests/test_bounds.py``); scheduler addresses; JSON depth and huge integers; long output names;
SIGTERM; terminal escape sequences in names; a full disk; refusals before heavy imports.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import importlib
import io
import json
import os
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_loss import needs_pelicun

from hlaid._fileio import MARKER, atomic_directory, is_hlaid_output, write_json
from hlaid.cli import main
from hlaid.clone import Clone
from hlaid.errors import HlaidWarning

REPO = Path(__file__).resolve().parents[1]
HEIGHTS = [3000.0, 3000.0, 3000.0]
HEAVY = ("torch", "numba", "scipy")
POSIX = pytest.mark.skipif(os.name != "posix", reason="FIFOs, devices and signals of POSIX")


class Hang(Exception):
    """A case did not finish within its deadline."""


@contextlib.contextmanager
def deadline(seconds: float):
    """Fail (instead of hanging the test run) when the block takes longer than ``seconds``."""
    def expired(signum, frame):
        raise Hang(f"still running after {seconds} s")
    old = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def tree(root: Path, skip: tuple[Path, ...] = ()) -> dict[str, str]:
    """Every entry under ``root`` (not following links) with its content hash, link target or kind."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            if any(p == s or s in p.parents for s in skip):
                continue
            st = p.lstat()
            rel = str(p.relative_to(root))
            if stat.S_ISLNK(st.st_mode):
                out[rel] = "link:" + os.readlink(p)
            elif stat.S_ISREG(st.st_mode) and st.st_size > 2**24:  # a sparse giant: its size and time
                out[rel] = f"size:{st.st_size}:{st.st_mtime_ns}"
            elif stat.S_ISREG(st.st_mode):
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
            else:
                out[rel] = f"mode:{stat.S_IFMT(st.st_mode)}"
    return out


def refused(capsys, argv, expect, *, root: Path, within: float = 120.0, code: int = 2) -> str:
    """``hlaid ARGV`` exits with ``code`` and one line naming one of ``expect``, no traceback, within
    ``within`` seconds (a guard against hangs: a command may import torch first when it legitimately
    needs it, which takes seconds on a loaded machine), and changes nothing under ``root``. Returns
    the line."""
    before = tree(root)
    with deadline(within):
        rc = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == code, (argv, err)
    assert len(err) == 1, err
    assert "Traceback" not in err[0] and "internal error" not in err[0], err
    assert any(e in err[0] for e in expect), err[0]
    assert tree(root) == before, f"files changed by {argv}"
    return err[0]


@pytest.fixture()
def clone_file(table1, tmp_path) -> Path:
    return Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "clone.json")


def _clone_dict(table1) -> dict:
    return Clone(building=table1.replace(height=HEIGHTS)).to_dict()


def _fleet_yaml(folder: Path) -> Path:
    cfg = folder / "fleet.yaml"
    cfg.write_text("records: builtin:elcentro-1940-ns\nbuildings:\n  - name: B1\n"
                   "    measurements: {ev1: {file: b1.npz}}\n")
    return cfg


# ----------------------------------------------------------------------------- --force
def test_force_never_replaces_a_folder_hlaid_did_not_write(tmp_path, capsys, clone_file, monkeypatch):
    v = tmp_path / "v"
    v.mkdir()
    (v / "meas.npz").write_bytes(b"a measurement")
    (v / "thesis.txt").write_text("four years")
    other = tmp_path / "other.npz"
    other.write_bytes(b"a measurement")
    fleet = _fleet_yaml(tmp_path)
    not_ours = ["not an output folder of hlaid", "an input of this run"]
    refused(capsys, ["hla", v / "meas.npz", "-o", v, "--force"], not_ours, root=tmp_path)
    refused(capsys, ["hla", other, "-o", v, "--force"], ["not an output folder of hlaid"], root=tmp_path)
    refused(capsys, ["ida", clone_file, "-o", v, "--force"], ["not an output folder of hlaid"], root=tmp_path)
    refused(capsys, ["demo", "--out", v, "--force"], ["not an output folder of hlaid"], root=tmp_path)
    refused(capsys, ["run", fleet, "-o", v, "--force"], ["not an output folder of hlaid"], root=tmp_path)
    refused(capsys, ["fleet", fleet, "-o", v, "--force"], ["not an hlaid fleet output"], root=tmp_path)
    # the current folder, however it is named
    monkeypatch.chdir(v)
    for out in (".", "../v", str(v)):
        refused(capsys, ["ida", clone_file, "-o", out, "--force"], ["current folder", "not an output folder"],
                root=tmp_path)


def test_force_never_replaces_an_input_even_in_an_hlaid_output(tmp_path, capsys, clone_file):
    out = tmp_path / "out"
    with atomic_directory(out) as tmp:
        (tmp / "meas.npz").write_bytes(b"a measurement")
        (tmp / "run.yaml").write_text("measurement: {file: meas.npz}\n")
    assert is_hlaid_output(out)
    refused(capsys, ["hla", out / "meas.npz", "-o", out, "--force"], ["an input of this run"], root=tmp_path)
    refused(capsys, ["run", out / "run.yaml", "-o", out, "--force"], ["an input of this run"], root=tmp_path)
    refused(capsys, ["ida", clone_file, "--records", out / "meas.npz", "-o", out, "--force"],
            ["an input of this run"], root=tmp_path)
    refused(capsys, ["demo", "--out", out, "--cache", out / "cache", "--force"], ["an input of this run"],
            root=tmp_path)


def test_file_outputs_never_overwrite_an_input(tmp_path, capsys, clone_file):
    meas = tmp_path / "meas.npz"
    meas.write_bytes(b"a measurement")
    (tmp_path / "alias.npz").symlink_to(meas)
    os.link(meas, tmp_path / "hardlink.npz")
    cfg = tmp_path / "sim.yaml"
    cfg.write_text("building: {stories: [{mass_t: 1, k0: 1, alpha: 0.1, p: 2, dy: 1, delta_eta: 0}]}\n"
                   "motion: {file: 'builtin:elcentro-1940-ns'}\n")
    for out in (meas, tmp_path / "alias.npz", tmp_path / "hardlink.npz"):
        refused(capsys, ["identify", meas, "-o", out, "--force"], ["is an input of this run"], root=tmp_path)
    refused(capsys, ["export-opensees", clone_file, "-o", clone_file, "--force"], ["is an input of this run"],
            root=tmp_path)
    refused(capsys, ["simulate", cfg, "-o", cfg, "--force"], ["is an input of this run"], root=tmp_path)
    refused(capsys, ["identify", meas, "-o", cfg, "--config", cfg, "--force"], ["is an input of this run"],
            root=tmp_path)


def test_force_replaces_an_hlaid_output_or_an_empty_folder(tmp_path):
    out = tmp_path / "out"
    with atomic_directory(out, what="hlaid test") as tmp:
        (tmp / "a.json").write_text("{}")
    marker = json.loads((out / MARKER).read_text())
    assert marker["format"] == "hlaid-output" and marker["command"] == "hlaid test"
    with atomic_directory(out, force=True) as tmp:
        (tmp / "b.json").write_text("{}")
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "b.json"]
    empty = tmp_path / "empty"
    empty.mkdir()
    with atomic_directory(empty, force=True) as tmp:
        (tmp / "c.json").write_text("{}")
    assert (empty / "c.json").exists()
    # a symlink in the output's place: replaced by the folder, its target left alone, nothing left over
    target = tmp_path / "target"
    with atomic_directory(target) as tmp:
        (tmp / "old.json").write_text("{}")
    (tmp_path / "link").symlink_to(target)
    before = tree(target)
    with atomic_directory(tmp_path / "link", force=True) as tmp:
        (tmp / "new.json").write_text("{}")
    assert (tmp_path / "link").is_dir() and not (tmp_path / "link").is_symlink()
    assert tree(target) == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# ----------------------------------------------------------------------------- hlaid loss RUN_DIR
LOSS = ["--no-curve", "--realizations", "50"]
"""A small loss assessment: the recorded event alone, 50 realizations."""


@pytest.fixture(scope="module")
def loss_run(tmp_path_factory, table1) -> Path:
    """A run folder ``hlaid loss`` can assess: the summary and figures of a run with an IDA (collapse
    median 1.1 g, beta 0.4), the clone and the measurement of its event."""
    from conftest import paper_record, window
    from test_bad_input import _run_folder

    from hlaid.synthetic import simulate_measurement
    run = _run_folder(tmp_path_factory.mktemp("loss") / "run")
    building = table1.replace(height=HEIGHTS)
    Clone(building=building).save(run / "clone.json")
    gm = window(paper_record("kocaeli-1999-dzc180"), 8.0)
    simulate_measurement(building, gm, noise_rms=0.05, seed=0).save(run / "measurement.npz")
    return run


def _copy_run(loss_run: Path, tmp_path: Path) -> Path:
    import shutil
    return Path(shutil.copytree(loss_run, tmp_path / "run"))


def test_loss_output_names_are_checked_before_the_work(loss_run, tmp_path, capsys):
    """A 300-byte ``-o``, one inside the run folder (or the run folder itself), a taken folder:
    refused (one line, exit 2) before any loss is computed, nothing touched."""
    run = _copy_run(loss_run, tmp_path)
    refused(capsys, ["loss", run, "-o", tmp_path / ("n" * 300), *LOSS], ["bytes long"], root=tmp_path, within=60)
    for out in (run / "loss2", run, run / "figures"):
        refused(capsys, ["loss", run, "-o", out, *LOSS, "--force"], ["inside the run folder"], root=tmp_path,
                within=60)
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "thesis.txt").write_text("four years")
    refused(capsys, ["loss", run, "-o", tmp_path / "taken", *LOSS], ["--force"], root=tmp_path, within=60)
    refused(capsys, ["loss", run, "-o", tmp_path, *LOSS, "--force"], ["an input of this run"], root=tmp_path,
            within=60)


def test_loss_with_a_figure_missing_is_refused_before_the_work(loss_run, tmp_path, capsys):
    """The run folder's report could not be rebuilt: refused before the losses are computed, and
    the run folder left exactly as it was (no loss/, no loss block)."""
    run = _copy_run(loss_run, tmp_path)
    (run / "figures" / "replay.png").unlink()
    refused(capsys, ["loss", run, *LOSS], ["figures/replay.png is missing"], root=tmp_path, within=60)


@needs_pelicun
def test_loss_with_an_output_folder_leaves_the_run_folder_alone(loss_run, tmp_path, capsys):
    """``hlaid loss RUN_DIR -o OUT`` writes the losses into OUT and nothing else: the run folder
    (summary.json, report.html, no loss/) and everything beside OUT keep their hashes."""
    run = _copy_run(loss_run, tmp_path)
    out = tmp_path / "out"
    before = tree(tmp_path)
    rc, err = main([str(a) for a in ["loss", run, "-o", out, *LOSS]]), capsys.readouterr().err
    assert rc == 0 and f"wrote {out}/" in err, err
    assert tree(tmp_path, skip=(out,)) == before
    loss = json.loads((out / "loss.json").read_text())
    assert loss["collapse_fragility"] == {"median_g": 1.1, "beta": 0.4, "source": "IDA of the identified clone, "
                                                                                  "3 records"}
    assert loss["recorded"]["n_realizations"] == 50 and loss["stripes"] == [] and loss["n_ensemble"] == 0
    assert (out / "repair_cost.png").is_file() and (out / "recorded" / "demands.csv").is_file()
    assert is_hlaid_output(out)
    before = tree(tmp_path)  # a second time: the output exists, replaced only with --force
    refused(capsys, ["loss", run, "-o", out, *LOSS], ["--force"], root=tmp_path, within=60)
    assert main([str(a) for a in ["loss", run, "-o", out, *LOSS, "--force"]]) == 0
    assert tree(tmp_path, skip=(out,)) == {k: v for k, v in before.items() if not k.startswith("out")}


@needs_pelicun
def test_loss_updates_the_run_folder_all_or_nothing(loss_run, tmp_path, capsys):
    """Without -o: loss/, the loss block of summary.json and report.html are written together; a
    failure after the work (a figure of the run that is not a PNG, found when the report is
    rebuilt) leaves the run folder exactly as it was."""
    run = _copy_run(loss_run, tmp_path)
    png = (run / "figures" / "loops.png").read_bytes()
    (run / "figures" / "loops.png").write_text("not an image")
    refused(capsys, ["loss", run, *LOSS, "-q"], ["figures/loops.png is not a PNG"], root=tmp_path, within=300)
    (run / "figures" / "loops.png").write_bytes(png)
    written = ("loss", "summary.json", "report.html")
    before = tree(tmp_path, skip=tuple(run / n for n in written))
    old = json.loads((run / "summary.json").read_text())
    rc, err = main([str(a) for a in ["loss", run, *LOSS]]), capsys.readouterr().err
    assert rc == 0 and f"wrote {run / 'loss'}/" in err, err
    assert tree(tmp_path, skip=tuple(run / n for n in written)) == before
    new = json.loads((run / "summary.json").read_text())
    loss = json.loads((run / "loss" / "loss.json").read_text())
    assert new["version"] == 2 and new["loss"]["recorded"] == loss["recorded"] and new["loss"]["curve"] == []
    assert {k: new[k] for k in old if k != "version"} == {k: v for k, v in old.items() if k != "version"}
    assert {k: v for k, v in new.items() if k not in old} == {"ida_after": None, "assessment": None, "events": [],
                                                              "survival": None, "flags": [], "loss": new["loss"],
                                                              "figures": True, "basis": None}
    page = (run / "report.html").read_text()
    assert "Losses (FEMA P-58 through pelicun)" in page and 'alt="repair_cost.png"' in page
    assert [p.name for p in run.iterdir() if p.name.startswith(".")] == []


# ----------------------------------------------------------------------------- regular files, sizes
@POSIX
@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "sparse-3GB", "folder"])
def test_report_reads_summary_only_as_a_regular_file(tmp_path, capsys, kind):
    run = tmp_path / "run"
    run.mkdir()
    s = run / "summary.json"
    if kind == "fifo":
        os.mkfifo(s)
    elif kind == "dev-zero":
        s.symlink_to("/dev/zero")
    elif kind == "sparse-3GB":
        with open(s, "wb") as fh:
            fh.truncate(3 * 2**30)
    else:
        s.mkdir()
    expect = {"fifo": "FIFO", "dev-zero": "character device", "sparse-3GB": "over the limit of 512 MiB",
              "folder": "is a folder"}[kind]
    refused(capsys, ["report", run], [expect], root=tmp_path, within=30)


@POSIX
@pytest.mark.parametrize("argv", [["hla", "m.npz", "-o", "out", "--config", "{bad}"],
                                  ["ida", "c.json", "-o", "out", "--config", "{bad}"],
                                  ["simulate", "{bad}", "-o", "out.npz"],
                                  ["export-opensees", "{bad}", "-o", "m.py"],
                                  ["hla", "{bad}", "-o", "out"]])
def test_devices_and_fifos_as_inputs(tmp_path, capsys, argv, monkeypatch):
    monkeypatch.chdir(tmp_path)
    os.mkfifo(tmp_path / "fifo")
    for bad, expect in (("/dev/zero", "is a character device; expected a regular file"), ("fifo", "is a FIFO")):
        refused(capsys, [a.format(bad=bad) for a in argv], [expect], root=tmp_path, within=30)


@pytest.fixture(scope="module")
def machine():
    from hlaid.svm import KernelSVC
    rng = np.random.default_rng(0)
    X = rng.normal(size=(30, 2))
    return KernelSVC().fit(X, (X[:, 0] > 0).astype(int))


@POSIX
@pytest.mark.parametrize("name", ["a.svm", "meta.json"])
@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder"])
def test_cache_entry_replaced_by_a_special_file_is_retrained(tmp_path, machine, name, kind):
    """A FIFO or /dev/zero in a cache entry must not hang or fill memory; a folder in place of a
    file must not make every later store fail: the entry is reported, retrained and stored again."""
    from hlaid.identify.cache import MachineCache
    c = MachineCache(tmp_path)
    c.store("k1", {"a": machine}, {"stats": {}})
    p = tmp_path / "k1" / name
    p.unlink()
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "dev-zero":
        p.symlink_to("/dev/zero")
    else:
        p.mkdir()
        (p / "x").write_text("x")
    with deadline(10), pytest.warns(HlaidWarning, match="failed its integrity check .*; retraining"):
        assert c.load("k1") is None
    c.store("k1", {"a": machine}, {"stats": {}})  # the retrained machines replace the entry
    machines, _ = c.load("k1")
    assert machines["a"].predict([[1.0, 0.0]]).tolist() == [1]


# ----------------------------------------------------------------------------- NPZ headers
def _lying_npz(path: Path, **shapes) -> Path:
    """An NPZ whose members' headers claim ``shapes``: those of more than 10^6 values hold no data."""
    with zipfile.ZipFile(path, "w") as z:
        for name, shape in shapes.items():
            head = io.BytesIO()
            np.lib.format.write_array_header_1_0(head, {"descr": "<f8", "fortran_order": False, "shape": shape})
            n = int(np.prod(shape, dtype=np.float64))
            z.writestr(name + ".npy", head.getvalue() + (b"\0" * 8 * n if n <= 10**6 else b""))
    return path


@pytest.mark.parametrize("shapes, array", [({"dt": (), "ground_acc": (10**10,), "floor_acc": (10, 1)}, "ground_acc"),
                                           ({"dt": (), "ground_acc": (10,), "floor_acc": (50, 10**9)}, "floor_acc")])
def test_npz_headers_are_checked_before_allocation(tmp_path, capsys, shapes, array):
    bad = _lying_npz(tmp_path / "tiny.npz", **shapes)
    assert bad.stat().st_size < 2000
    for argv in (["hla", bad, "-o", tmp_path / "h"], ["identify", bad, "-o", tmp_path / "c.json"]):
        line = refused(capsys, argv, ["its header claims shape"], root=tmp_path)
        assert array in line


# ----------------------------------------------------------------------------- values out of bounds
def test_config_and_clone_values_out_of_bounds(tmp_path, capsys, table1, monkeypatch):
    sim = tmp_path / "sim.yaml"
    sim.write_text("building: {stories: [{mass_t: 1, k0: 1, alpha: 0.1, p: 2, dy: 1, delta_eta: 0}]}\n"
                   "motion: {file: 'builtin:elcentro-1940-ns'}\nmeasurement: {rate_hz: 0.001}\n")
    refused(capsys, ["simulate", sim, "-o", tmp_path / "m.npz"], ["measurement.rate_hz = 0.001"], root=tmp_path)
    ida = tmp_path / "ida.yaml"
    ida.write_text("records: builtin:elcentro-1940-ns\nlevels: [0.1, 0.2, 1e308]\n")
    refused(capsys, ["ida", "c.json", "--config", ida, "-o", tmp_path / "i"], ["levels[2] = 1e+308"], root=tmp_path)
    refused(capsys, ["ida", "c.json", "--levels", "0.1,0.2,1e308", "-o", tmp_path / "i"], ["levels[2] = 1e+308"],
            root=tmp_path)
    fleet = _fleet_yaml(tmp_path)
    fleet.write_text(fleet.read_text() + "n_ensemble: 1000000000\n")
    refused(capsys, ["fleet", fleet, "-o", tmp_path / "f"], ["n_ensemble = 1000000000"], root=tmp_path)
    for change, expect in ((lambda d: d["stories"][0].update(dy=1e-300), "dy = 1e-300"),
                           (lambda d: d["damping"].update(modes=[1, 99]), "damping.modes"),
                           (lambda d: d["stories"][1].update(k0="HUGE"), "stories[1].k0"),
                           (lambda d: d["damping"].update(ratio=float("nan")), "damping.ratio")):
        d = _clone_dict(table1)
        change(d)
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(d).replace('"HUGE"', "9" * 5000))
        refused(capsys, ["export-opensees", bad, "-o", tmp_path / "m.py"], [expect], root=tmp_path)
    monkeypatch.setenv("HLAID_MAX_FILE_MB", "inf")
    refused(capsys, ["hla", "m.npz", "-o", tmp_path / "h"], ["HLAID_MAX_FILE_MB = 'inf'"], root=tmp_path)


@pytest.mark.parametrize("block, field", [("bins: {p_fine: 1.0e-12}", "p_fine"),
                                          ("bins: {p_range: [1, 1.0e+300]}", "p_range"),
                                          ("training: {n_segments: 1000000}", "n_segments")])
def test_identify_config_values_out_of_bounds(tmp_path, capsys, block, field):
    cfg = tmp_path / "identify.yaml"
    cfg.write_text(block + "\n")
    refused(capsys, ["identify", "m.npz", "--config", cfg, "-o", tmp_path / "c.json"], [field], root=tmp_path)


# ----------------------------------------------------------------------------- scheduler
@pytest.mark.parametrize("address", ["garbage", "tcp://[::1", "http://", "file://", "inproc://x", "tcp://host:0"])
def test_scheduler_addresses_are_checked_first(tmp_path, capsys, address):
    refused(capsys, ["fleet", "missing.yaml", "-o", tmp_path / "f", "--scheduler", address], ["--scheduler"],
            root=tmp_path, within=30)


def _server(reply: bytes | None) -> tuple[socket.socket, int]:
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()

    def serve():
        with contextlib.suppress(OSError):
            while True:
                conn, _ = srv.accept()
                if reply is not None:
                    conn.sendall(reply)
                time.sleep(2)
                conn.close()
    threading.Thread(target=serve, daemon=True).start()
    return srv, srv.getsockname()[1]


@pytest.mark.parametrize("reply, expect", [(b"SSH-2.0-OpenSSH_9.6\r\n", "not a dask scheduler"),
                                           (b"HTTP/1.1 400 Bad Request\r\n\r\n", "not a dask scheduler"),
                                           (None, "sent nothing within 1 s")])
def test_a_server_that_is_no_scheduler_is_refused_before_any_allocation(tmp_path, capsys, monkeypatch, reply, expect):
    import hlaid.fleet.address as address
    monkeypatch.setattr(address, "CONNECT_TIMEOUT_S", 1.0)
    srv, port = _server(reply)
    with srv:
        refused(capsys, ["fleet", _fleet_yaml(tmp_path), "-o", tmp_path / "f", "--scheduler",
                         f"tcp://127.0.0.1:{port}"], [expect], root=tmp_path)
    with socket.socket() as unused:  # a port nothing listens on
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    refused(capsys, ["fleet", _fleet_yaml(tmp_path), "-o", tmp_path / "f", "--scheduler", f"127.0.0.1:{port}"],
            ["cannot connect"], root=tmp_path)


# ----------------------------------------------------------------------------- JSON depth, huge integers
@pytest.mark.parametrize("text, expect", [("[" * 100_000, "nested more than 64 levels"),
                                          ('{"format": "hlaid-clone", "version": ' + "9" * 5000 + "}", "version"),
                                          ('{"a": ' * 70 + "1" + "}" * 70, "nested more than 64 levels")])
def test_json_depth_and_huge_integers(tmp_path, capsys, text, expect):
    bad = tmp_path / "bad.json"
    bad.write_text(text)
    refused(capsys, ["export-opensees", bad, "-o", tmp_path / "m.py"], [expect], root=tmp_path)
    refused(capsys, ["ida", bad, "--records", "builtin-suite", "-o", tmp_path / "i"], [expect], root=tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    (run / "summary.json").write_text(text)
    refused(capsys, ["report", run], [expect, "not an hlaid run"], root=tmp_path)


def test_a_bad_fleet_unit_file_does_not_stop_a_resume(tmp_path):
    from hlaid.fleet.engine import result_path, stored_result
    job = SimpleNamespace(unit="B1@ev1")
    p = result_path(tmp_path, job)
    p.parent.mkdir()
    for text in ("[" * 100_000, '{"status": ' + "9" * 5000 + "}"):
        p.write_text(text)
        with deadline(10), warnings_as_list() as seen:
            d = stored_result(tmp_path, job)
        assert d is None or d.get("status") != "ok"
        assert all("\n" not in w for w in seen)
    os.unlink(p)
    os.mkfifo(p)
    with deadline(10), pytest.warns(HlaidWarning, match="FIFO"):
        assert stored_result(tmp_path, job) is None


@contextlib.contextmanager
def warnings_as_list():
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seen: list[str] = []
        yield seen
        seen += [str(w.message) for w in caught]


# ----------------------------------------------------------------------------- long names
@pytest.mark.parametrize("size", [236, 245, 253, 255])
def test_long_legal_output_names(tmp_path, size):
    name = "x" * (size - 5) + ".json"
    write_json(tmp_path / name, {"a": 1})
    with atomic_directory(tmp_path / ("d" * size)) as tmp:
        write_json(tmp / "r.json", {})
    assert sorted(len(p.name) for p in tmp_path.iterdir()) == [size, size]


def test_a_name_too_long_is_refused_before_the_work(tmp_path, capsys, clone_file):
    long = "n" * 300
    refused(capsys, ["export-opensees", clone_file, "-o", tmp_path / (long + ".py")], ["bytes long"], root=tmp_path)
    refused(capsys, ["ida", clone_file, "-o", tmp_path / long], ["bytes long"], root=tmp_path)


def test_export_with_a_long_name_writes(tmp_path, capsys, clone_file):
    out = tmp_path / ("m" * 250 + ".py")
    assert main(["export-opensees", str(clone_file), "-o", str(out), "-q"]) == 0
    assert out.is_file() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# ----------------------------------------------------------------------------- escapes in messages
def test_terminal_escapes_in_names_are_escaped(tmp_path, capsys):
    hostile = "\x1b]0;pwned\x07\x1b[2J\u202e.npz"
    for argv in (["hla", str(tmp_path / hostile), "-o", str(tmp_path / "o")],
                 ["report", str(tmp_path / hostile)],
                 ["identify", str(tmp_path / "m.npz"), "-o", str(tmp_path / hostile / "c.json")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "\\x1b]0;pwned\\x07\\x1b[2J\\u202e" in err
        assert not any(c in err for c in "\x1b\x07\u202e")
    with pytest.raises(SystemExit):
        main(["\x1b[2J"])
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\\x1b[2J" in err


def test_progress_and_warning_lines_are_escaped(capsys):
    from hlaid import _progress
    _progress.set_verbosity(1)
    with _progress.cli_warnings():
        _progress.info("wrote \x1b[2Jout/")
        _progress.warn("file \x07 name")
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\x07" not in err and "\\x1b[2J" in err and "\\x07" in err


# ----------------------------------------------------------------------------- full disk
def test_a_full_quota_is_said_so(tmp_path, capsys, monkeypatch, table1):
    """EDQUOT (and ENOSPC) while an output is written: one line, nothing partial left."""
    run = tmp_path / "run"
    run.mkdir()
    clone = Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "clone.json")

    def full(self, *a, **k):
        raise OSError(errno.EDQUOT, "Disk quota exceeded")
    monkeypatch.setattr(Path, "write_text", full)
    line = refused(capsys, ["export-opensees", clone, "-o", tmp_path / "m.py"], ["disk quota exceeded"],
                   root=tmp_path)
    assert "m.py" in line


def _unshare_works() -> bool:
    if sys.platform != "linux":
        return False
    try:
        r = subprocess.run(["unshare", "-rm", "true"], capture_output=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


@pytest.mark.skipif(not _unshare_works(), reason="needs a private mount namespace (unshare -rm) for a full tmpfs")
def test_a_full_disk_is_said_so(tmp_path):
    """A real ENOSPC: a 1 MiB tmpfs filled up, then ``hlaid report`` writes its report.html there."""
    from test_bad_input import _run_folder
    src = _run_folder(tmp_path / "run")
    disk = tmp_path / "disk"
    disk.mkdir()
    script = (f"mount -t tmpfs -o size=1m tmpfs {disk} && cp -r {src} {disk}/run && "
              f"(dd if=/dev/zero of={disk}/filler bs=4k 2>/dev/null; true) && "
              f"{sys.executable} -m hlaid report {disk}/run; echo \"rc=$?\"; ls -a {disk}/run; "
              f"sha256sum {disk}/run/summary.json")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    r = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=300, env=env)
    err = r.stderr.strip().splitlines()
    assert "rc=2" in r.stdout, (r.stdout, r.stderr)
    assert len(err) == 1 and "no space left on the device" in err[0] and "report.html" in err[0], err
    listing = r.stdout.split()
    assert "report.html" not in listing and not [n for n in listing if n.startswith(".report.html")]
    assert hashlib.sha256((src / "summary.json").read_bytes()).hexdigest() in r.stdout


# ----------------------------------------------------------------------------- SIGTERM
@pytest.mark.skipif(sys.platform != "linux", reason="process groups and /proc are Linux-specific here")
def test_sigterm_during_identify_workers(tmp_path):
    """``kill PID`` (SIGTERM to the command only) while the worker pool trains: exit 143, one
    line, no traceback of an orphaned worker, no process left, no output."""
    from test_interrupt import _interrupt, _leftovers

    from hlaid.synthetic import load_simulation_config, measurement_from_config
    cfg = load_simulation_config(REPO / "configs" / "poc_3story.yaml")
    measurement_from_config(cfg, base_dir=REPO / "configs").save(tmp_path / "meas.npz")
    (tmp_path / "out").mkdir()
    rc, elapsed, lines = _interrupt(["identify", "meas.npz", "-o", "out/c.json", "--no-cache", "--tensorboard", "tb"],
                                    tmp_path, after="[identify] hysteresis loop analysis", workers=2, delay=1.0,
                                    signum=signal.SIGTERM, group=False)
    assert rc == 143 and elapsed < 10
    assert lines[-1] == "hlaid identify: terminated"
    assert not any(w in ln for ln in lines for w in ("Traceback", "BrokenPipe", "Error")), lines
    assert _leftovers(tmp_path / "out", "c.json") == [] and not (tmp_path / "tb").exists()


def test_interrupted_identify_removes_its_tensorboard_folder(tmp_path, capsys, monkeypatch):
    import hlaid.cli.identify as cli
    import hlaid.io

    class Interrupted:
        def __init__(self, tensorboard=None, **kw):
            self.tb = tensorboard

        def fit(self, meas):
            Path(self.tb).mkdir()
            (Path(self.tb) / "events.out").write_text("x")
            raise KeyboardInterrupt

    monkeypatch.setattr(hlaid.io, "read", lambda *a, **k: object())
    monkeypatch.setattr(cli, "check_identify_bands", lambda *a: None)
    monkeypatch.setattr(importlib.import_module("hlaid.estimators"), "HLASVMIdentifier", Interrupted)
    (tmp_path / "runs").mkdir()
    (tmp_path / "m.npz").write_bytes(b"read by the stand-in reader")
    rc = main(["identify", str(tmp_path / "m.npz"), "-o", str(tmp_path / "c.json"), "--tensorboard",
               str(tmp_path / "runs" / "id1")])
    assert rc == 130 and capsys.readouterr().err.strip().endswith("interrupted")
    assert list((tmp_path / "runs").iterdir()) == [] and not (tmp_path / "c.json").exists()


# ----------------------------------------------------------------------------- before heavy imports
PROBE = """
import contextlib, io, json, sys
from hlaid.cli.app import main
rows = []
for argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rc = main(argv)
    rows.append([argv[0], rc, sorted(m for m in {heavy!r} if m in sys.modules), err.getvalue().strip()])
print(json.dumps(rows))
"""


def test_bad_inputs_are_refused_before_heavy_imports(tmp_path, table1):
    """Configs, clones, measurements' NPZ headers, outputs, environment: each refused (exit 2)
    in a fresh interpreter that has not imported torch, numba or scipy by then."""
    (tmp_path / "h.yaml").write_text("stiffness: {k_window: 1000000000}\n")
    (tmp_path / "i.yaml").write_text("levels: [0.1, 1e308]\n")
    (tmp_path / "id.yaml").write_text("bins: {p_fine: 1.0e-12}\n")
    (tmp_path / "r.yaml").write_text("measurement: {file: m.npz}\nidentify: {training: {n_segments: 1000000}}\n")
    (tmp_path / "fl.yaml").write_text("records: builtin-suite\nidentify: {svm: {n_bags: 0}}\nbuildings:\n"
                                      "  - {name: B1, measurements: {ev1: {file: b.npz}}}\n")
    (tmp_path / "s.yaml").write_text("building: {stories: [{mass_t: 1, k0: 1, alpha: 0.1, p: 2, dy: 1.0e-300, "
                                     "delta_eta: 0}]}\nmotion: {file: 'builtin:elcentro-1940-ns'}\n")
    d = _clone_dict(table1)
    d["stories"][0]["dy"] = 1e-300
    (tmp_path / "c.json").write_text(json.dumps(d))
    _lying_npz(tmp_path / "tiny.npz", dt=(), ground_acc=(10**10,), floor_acc=(10, 1))
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "keep.txt").write_text("x")
    from test_bad_input import _run_folder
    _run_folder(tmp_path / "run")
    t = str(tmp_path)
    cases = [["hla", f"{t}/tiny.npz", "-o", f"{t}/o", "--config", f"{t}/h.yaml"],
             ["ida", f"{t}/c.json", "-o", f"{t}/o", "--config", f"{t}/i.yaml"],
             ["identify", f"{t}/tiny.npz", "-o", f"{t}/c2.json", "--config", f"{t}/id.yaml"],
             ["run", f"{t}/r.yaml", "-o", f"{t}/o"],
             ["fleet", f"{t}/fl.yaml", "-o", f"{t}/o"],
             ["ida", f"{t}/c.json", "-o", f"{t}/o"],
             ["export-opensees", f"{t}/c.json", "-o", f"{t}/m.py"],
             ["simulate", f"{t}/s.yaml", "-o", f"{t}/m.npz"],
             ["hla", f"{t}/tiny.npz", "-o", f"{t}/o"],
             ["hla", f"{t}/tiny.npz", "-o", f"{t}/taken", "--force"],
             ["report", t],
             ["loss", f"{t}/run", "-o", f"{t}/{'n' * 300}"],
             ["loss", f"{t}/run", "-o", f"{t}/run/loss2"],
             ["fleet", f"{t}/f.yaml", "-o", f"{t}/o", "--scheduler", "garbage"]]
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    r = subprocess.run([sys.executable, "-c", PROBE.format(heavy=HEAVY), json.dumps(cases)], capture_output=True,
                       text=True, env=env, cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stderr
    for command, rc, heavy, err in json.loads(r.stdout):
        assert rc == 2 and "\n" not in err and "error" in err, (command, err)
        assert heavy == [], (command, heavy, err)


# ----------------------------------------------------------------------------- inputs named inside inputs
def _measurement(path: Path, table1, *, mass_factor: float = 1.0, seed: int = 0, n_floors: int = 3) -> Path:
    """A measurement file of ``table1``'s floors (made-up accelerations of plausible size: every case
    below is refused before any analysis)."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) * 0.01
    g = 2000.0 * np.sin(2 * np.pi * 1.3 * t) * np.exp(-0.1 * t) + rng.normal(0, 50, t.size)
    f = g[:, None] * np.linspace(1.2, 2.0, n_floors) + rng.normal(0, 50, (t.size, n_floors))
    mass = np.asarray(table1.mass[:n_floors], dtype=float) * mass_factor
    if path.suffix == ".csv":
        cols = ",".join(["t", "g", *(f"f{j + 1}" for j in range(n_floors))])
        path.write_text(cols + "\n" + "\n".join(",".join(f"{v:.6g}" for v in (t[i], g[i], *f[i]))
                                                   for i in range(t.size)) + "\n")
    else:
        with open(path, "wb") as fh:
            np.savez(fh, dt=np.float64(0.01), ground_acc=g, floor_acc=f, mass=mass)
    return path


def _columns_yaml(path: Path, data: str) -> Path:
    path.write_text(f"file: {data}\ntime: t\nground: {{column: g, units: mm/s^2}}\nfloors:\n"
                    + "".join(f"  - {{column: f{j}, units: mm/s^2}}\n" for j in (1, 2, 3)))
    return path


def test_files_named_in_a_columns_yaml_are_inputs_of_the_run(tmp_path, capsys, table1, clone_file):
    """A table named by a columns YAML is an input like the YAML itself: no output may replace it,
    nor a folder holding it, even with --force (refused before the work)."""
    _measurement(tmp_path / "data.csv", table1)
    yaml_file = _columns_yaml(tmp_path / "map.yaml", "data.csv")
    refused(capsys, ["demands", clone_file, "--motion", yaml_file, "--ensemble", "0", "-o", tmp_path / "data.csv",
                     "--force"], ["is an input of this run"], root=tmp_path, within=60)
    out = tmp_path / "colout"
    with atomic_directory(out) as tmp:
        _measurement(tmp / "data.csv", table1)
    outside = _columns_yaml(tmp_path / "map2.yaml", "colout/data.csv")
    refused(capsys, ["hla", outside, "-o", out, "--force"], ["an input of this run"], root=tmp_path, within=60)
    refused(capsys, ["predict", clone_file, outside, "-o", out, "--force"], ["an input of this run"], root=tmp_path,
            within=60)
    refused(capsys, ["identify", outside, "-o", out / "data.csv", "--force"], ["is an input of this run"],
            root=tmp_path, within=60)


# ----------------------------------------------------------------------------- what --force removes
def test_a_hand_made_marker_is_not_trusted(tmp_path, capsys):
    v = tmp_path / "F"
    (v / ".ssh").mkdir(parents=True)
    (v / ".ssh" / "id_ed25519").write_text("a key")
    (v / "thesis").mkdir()
    (v / "thesis" / "ch1.tex").write_text("four years")
    (v / MARKER).write_text('{"format": "hlaid-output"}')
    m = tmp_path / "m.npz"
    m.write_bytes(b"a measurement")
    refused(capsys, ["hla", m, "-o", v, "--force"], ["not written there by hlaid"], root=tmp_path)
    # a real marker copied into another folder is no marker of that folder
    real = tmp_path / "real"
    with atomic_directory(real) as tmp:
        (tmp / "hla.json").write_text("{}")
    (v / MARKER).write_bytes((real / MARKER).read_bytes())
    (v / "hla.json").write_text("{}")
    refused(capsys, ["hla", m, "-o", v, "--force"], ["not written there by hlaid"], root=tmp_path)
    assert not is_hlaid_output(v) and is_hlaid_output(real)


def test_force_keeps_what_the_user_put_into_an_output_folder(tmp_path, capsys):
    out = tmp_path / "out"
    with atomic_directory(out) as tmp:
        (tmp / "hla.json").write_text("{}")
        (tmp / "figures").mkdir()
        (tmp / "figures" / "loops.png").write_bytes(b"png")
    mark = json.loads((out / MARKER).read_text())
    assert mark["files"] == ["figures", "figures/loops.png", "hla.json"]
    assert mark["folder"] == {"device": out.stat().st_dev, "inode": out.stat().st_ino}
    (out / "notes.txt").write_text("mine")
    (out / "figures" / "sketch.png").write_bytes(b"mine too")
    m = tmp_path / "m.npz"
    m.write_bytes(b"a measurement")
    line = refused(capsys, ["hla", m, "-o", out, "--force"], ["hlaid did not write there"], root=tmp_path)
    assert "2 entries" in line and "figures/sketch.png" in line and "notes.txt" in line
    # a folder written into an output later by hlaid (RUN/loss/) is hlaid's: replaced with it
    (out / "notes.txt").unlink()
    (out / "figures" / "sketch.png").unlink()
    with atomic_directory(out / "loss") as tmp:
        (tmp / "loss.json").write_text("{}")
    with atomic_directory(out, force=True) as tmp:
        (tmp / "new.json").write_text("{}")
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "new.json"]


# ----------------------------------------------------------------------------- folders that cannot be renamed
def test_an_output_folder_whose_rename_is_refused_is_replaced_in_place(tmp_path, monkeypatch):
    """A mount point (EBUSY on rename): the output is written into the folder itself, nothing left
    beside or inside it; only what hlaid wrote there is replaced."""
    out = tmp_path / "out"
    with atomic_directory(out) as tmp:
        (tmp / "old.json").write_text("{}")
        (tmp / "keep").mkdir()
        (tmp / "keep" / "a.txt").write_text("a")
    inode = out.stat().st_ino
    real_replace = os.replace

    def busy(src, dst, *a, **k):
        if Path(src) == out or Path(dst) == out:
            raise OSError(errno.EBUSY, "Device or resource busy", str(src))
        return real_replace(src, dst, *a, **k)
    monkeypatch.setattr(os, "replace", busy)
    with atomic_directory(out, force=True) as tmp:
        (tmp / "new.json").write_text('{"new": 1}')
        (tmp / "sub").mkdir()
        (tmp / "sub" / "b.txt").write_text("b")
    assert out.stat().st_ino == inode
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "new.json", "sub"]
    assert json.loads((out / "new.json").read_text()) == {"new": 1} and (out / "sub" / "b.txt").read_text() == "b"
    assert json.loads((out / MARKER).read_text())["files"] == ["new.json", "sub", "sub/b.txt"]
    assert is_hlaid_output(out)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    # an output file that cannot be renamed over (a bind-mounted file) is rewritten in place
    f = tmp_path / "f.json"
    write_json(f, {"a": 1})
    monkeypatch.setattr(os, "replace", lambda src, dst, *a, **k: (_ for _ in ()).throw(
        OSError(errno.EBUSY, "Device or resource busy")) if Path(dst) == f else real_replace(src, dst))
    write_json(f, {"a": 2})
    assert json.loads(f.read_text()) == {"a": 2} and sorted(p.name for p in tmp_path.iterdir()) == ["f.json", "out"]


MOUNTED = """
import os, sys
from pathlib import Path
from hlaid._fileio import atomic_directory
from hlaid.errors import InputError
out = Path(sys.argv[1])
for name in ("a.json", "b.json"):
    with atomic_directory(out, force=True) as tmp:
        (tmp / name).write_text("{}")
    print(sorted(os.listdir(out)))
(out / "mine.txt").write_text("x")
try:
    with atomic_directory(out, force=True) as tmp:
        (tmp / "c.json").write_text("{}")
except InputError as err:
    print("refused", err.detail.split(" (")[0])
print(sorted(os.listdir(out)), sorted(os.listdir(out.parent)))
"""


@pytest.mark.skipif(not _unshare_works(), reason="needs a private mount namespace (unshare -rm) for a mount point")
def test_a_mount_point_as_the_output_folder(tmp_path):
    """A real mount point (a tmpfs mounted on the output folder): written, replaced with --force,
    a user's file in it refused, and no temporary folder left anywhere."""
    script = tmp_path / "write.py"
    script.write_text(MOUNTED)
    (tmp_path / "mnt").mkdir()
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    r = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=1m tmpfs {tmp_path}/mnt && "
                        f"{sys.executable} {script} {tmp_path}/mnt"], capture_output=True, text=True, timeout=300,
                       env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == ["['.hlaid-output.json', 'a.json']", "['.hlaid-output.json', 'b.json']",
                                     "refused holds 1 entry hlaid did not write there or that changed since",
                                     "['.hlaid-output.json', 'b.json', 'mine.txt'] ['mnt', 'write.py']"]


# ----------------------------------------------------------------------------- inventories
def test_inventories_are_bounded(tmp_path, capsys):
    demands = tmp_path / "d.csv"
    demands.write_text(",1-PID-1-1,1-PID-2-1,1-PID-3-1,1-RID-1-1\nUnits,rad,rad,rad,rad\n"
                       + "".join(f"{i},0.01,0.012,0.008,0.001\n" for i in range(5)))
    head = "ID,Units,Location,Direction,Theta_0\n"
    inv = tmp_path / "inv.csv"
    for rows, expect in (("B.10.35.021,ea,1,1,1e300\n", "line 2: column Theta_0: 1e+300"),
                         ("B.10.35.021,ea,1,1,nan\n", "column Theta_0: no number"),
                         ("B.10.35.021,ea,1,1,2\n" * 200_000, "more than 10000 component rows (line 10002)")):
        inv.write_text(head + rows)
        refused(capsys, ["loss", demands, "-o", tmp_path / "loss", "--floor-area", "100", "--inventory", inv],
                [expect], root=tmp_path, within=60)


# ----------------------------------------------------------------------------- events
def test_update_refuses_an_event_the_clone_has_learnt(tmp_path, capsys, table1):
    from hlaid.io import read
    from hlaid.measurement import ground_digest
    m = _measurement(tmp_path / "ev1.npz", table1)
    meas = read(m, "measurement")
    record = {"name": "ev1", "source": str(m), "sha256": hashlib.sha256(m.read_bytes()).hexdigest(),
              "pga_g": float(np.abs(meas.ground_acc).max() / 9806.65), "duration_s": meas.n_samples * meas.dt,
              "dt": meas.dt, "n_floors": 3}
    for extra in ({}, {"ground_sha256": ground_digest(meas)}):
        d = _clone_dict(table1)
        d["events"] = [{**record, **extra}]
        clone = tmp_path / "clone.json"
        clone.write_text(json.dumps(d))
        refused(capsys, ["update", clone, m, "-o", tmp_path / "c2.json"], ["has learnt from this event already"],
                root=tmp_path, within=60)
        copy = tmp_path / "ev1-copy.csv"  # the same record written again in another format
        copy.write_text("# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1,floor_acc_2,floor_acc_3\n" + "\n".join(
            ",".join(repr(float(v)) for v in (i * 0.01, meas.ground_acc[i], *meas.floor_acc[i]))
            for i in range(meas.n_samples)) + "\n")
        refused(capsys, ["update", clone, copy, "-o", tmp_path / "c2.json"], ["has learnt from this event already"],
                root=tmp_path, within=60)
        copy.unlink()


def test_predict_refuses_a_carried_start_without_a_state(tmp_path, capsys, table1, clone_file):
    m = _measurement(tmp_path / "ev.npz", table1)
    refused(capsys, ["predict", clone_file, m, "-o", tmp_path / "p", "--start", "carried"], ["carries no state"],
            root=tmp_path, within=60)


@pytest.mark.parametrize("band", [["0.3", "inf"], ["0.3", "5000"], ["0.3", "49"]])
def test_bands_above_the_nyquist_frequency_are_refused(tmp_path, capsys, table1, clone_file, band):
    m = _measurement(tmp_path / "ev.npz", table1)  # 100 Hz: corners up to 45 Hz
    expect = ["finite"] if band[1] == "inf" else ["above 45 Hz (0.9 x the Nyquist frequency"]
    refused(capsys, ["predict", clone_file, m, "-o", tmp_path / "p", "--band", *band], expect, root=tmp_path,
            within=60)
    if band[1] != "inf":
        cfg = tmp_path / "hla.yaml"
        cfg.write_text(f"preprocess: {{band_hz: [{band[0]}, {band[1]}]}}\n")
        refused(capsys, ["hla", m, "-o", tmp_path / "h", "--config", cfg], expect, root=tmp_path, within=60)
        cfg.unlink()


# ----------------------------------------------------------------------------- the last internal errors
def test_a_symlink_output_into_a_missing_folder(tmp_path, capsys, clone_file):
    link = tmp_path / "link.py"
    link.symlink_to(tmp_path / "missing" / "dir" / "x.py")
    refused(capsys, ["export-opensees", clone_file, "-o", link], ["exists as a symbolic link; use --force"],
            root=tmp_path)
    assert main(["export-opensees", str(clone_file), "-o", str(link), "--force", "-q"]) == 0
    assert link.is_file() and not link.is_symlink() and not (tmp_path / "missing").exists()
    folder = tmp_path / "link-out"
    folder.symlink_to(tmp_path / "missing" / "dir")
    refused(capsys, ["ida", clone_file, "-o", folder], ["exists as a symbolic link"], root=tmp_path)


def test_long_folder_names_in_output_paths(tmp_path, capsys, clone_file):
    long = tmp_path / ("p" * 300)
    for argv in (["export-opensees", clone_file, "-o", long / "x.py"], ["ida", clone_file, "-o", long / "out"],
                 ["identify", "m.npz", "-o", tmp_path / "c.json", "--tensorboard", long / "tb"],
                 ["identify", "m.npz", "-o", tmp_path / "c.json", "--tensorboard", tmp_path / ("t" * 300)]):
        refused(capsys, argv, ["longer than the file system allows", "bytes long"], root=tmp_path)


def test_a_control_character_in_a_yaml_string(tmp_path, capsys):
    cfg = tmp_path / "esc.yaml"
    cfg.write_text("building: {stories: [{mass_t: 1, k0: 1, alpha: 0.1, p: 2, dy: 1, delta_eta: 0}]}\n"
                   "motion: {file: 'builtin:elcentro-1940-ns'}\nname: \"a\x1bb\"\n")
    line = refused(capsys, ["simulate", cfg, "-o", tmp_path / "m.npz"], ["control character"], root=tmp_path)
    assert "esc.yaml:3:" in line and "\x1b" not in line


def test_the_errors_in_variables_stage_falls_back_when_it_fails_numerically(monkeypatch):
    """A whitening matrix that is not positive definite (a very soft first story under a stiff
    superstructure) is a numerical failure of that stage: least squares instead, with a warning
    and a note kept in the clone's diagnostics, never an internal error."""
    import dataclasses

    import scipy.linalg

    import hlaid.joint.fit as events
    from hlaid.errors import UnstableTangentError
    from hlaid.identify.eiv import TangentWhitener

    def not_pd(*a, **k):
        raise np.linalg.LinAlgError("2-th leading minor not positive definite")
    monkeypatch.setattr(scipy.linalg, "cholesky_banded", not_pd)
    tangent = SimpleNamespace(lead=1, n_lags=3, floors=1, response=np.ones((20, 3, 1)))
    with pytest.raises(UnstableTangentError, match="not positive definite"):
        TangentWhitener(tangent, np.ones(1), 1.0)

    @dataclasses.dataclass(frozen=True)
    class Fit:
        events: list
    calls = []

    def fake_map_refine(*a, ground_noise="ignore", **k):
        calls.append(ground_noise)
        if ground_noise == "tangent":
            raise np.linalg.LinAlgError("2-th leading minor not positive definite")
        return Fit(events=[{"n_eff": 10.0}, {"n_eff": 12.0}])
    monkeypatch.setattr(events, "map_refine", fake_map_refine)
    from hlaid.identify.config import IdentifyConfig, RefineConfig

    cfg = IdentifyConfig(refine=RefineConfig(method="eiv", parameters=("k0",), damping=False, band_hz=(0.1, 20.0),
                                             max_iterations=5, tangent_max_mb=100.0, compare="acc"))
    cfg = dataclasses.replace(cfg, hla=dataclasses.replace(cfg.hla, preprocess=dataclasses.replace(
        cfg.hla.preprocess, band_hz=None), stiffness=dataclasses.replace(cfg.hla.stiffness, yield_ratio=0.6)))
    with pytest.warns(HlaidWarning, match="errors-in-variables stage skipped .*not positive definite"):
        fit = events.joint_fit(object(), [], None, cfg, masses=False)
    assert calls == ["tangent", "ignore"]
    assert [e["errors_in_variables"]["fitted_by"] for e in fit.events] == ["least squares"] * 2
    assert fit.events[0]["n_eff"] == 10.0


# ----------------------------------------------------------------------------- values that make no sense
def test_clone_states_and_events_that_no_building_has(tmp_path, capsys, table1, clone_file):
    for change, expect in ((lambda d: d.update(state={"drift": [0.0] * 3, "z": [1e6, 0.0, 0.0], "work": [0.0] * 3,
                                                      "peak_positive": [0.0] * 3, "peak_negative": [0.0] * 3}),
                            "state.z[0] = 1000000 mm is beyond the story's dy"),
                           (lambda d: d.update(events=[{"name": "e", "dt": float("nan")}]), "events[0].dt"),
                           (lambda d: d.update(events=[{"name": "e", "pga_g": "big"}]), "events[0].pga_g")):
        d = _clone_dict(table1)
        change(d)
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(d))
        refused(capsys, ["export-opensees", bad, "-o", tmp_path / "m.py"], [expect], root=tmp_path)
    text = clone_file.read_text()
    dup = tmp_path / "dup.json"
    dup.write_text(text.replace('"name":', '"name": "first", "name":', 1))
    refused(capsys, ["export-opensees", dup, "-o", tmp_path / "m.py"], ["key 'name' appears twice"], root=tmp_path)


def test_measurement_masses_out_of_bounds_or_of_another_building(tmp_path, capsys, table1, clone_file):
    huge = _measurement(tmp_path / "huge.npz", table1, mass_factor=1e300 / float(table1.mass[0]))
    refused(capsys, ["hla", huge, "-o", tmp_path / "h"], ["mass[0] = 1e+300 is out of range"], root=tmp_path,
            within=60)
    heavy = _measurement(tmp_path / "heavy.npz", table1, mass_factor=10.0)
    refused(capsys, ["predict", clone_file, heavy, "-o", tmp_path / "p"], ["not of this building"], root=tmp_path,
            within=60)
    refused(capsys, ["update", clone_file, heavy, "-o", tmp_path / "c.json"], ["not of this building"],
            root=tmp_path, within=60)


def test_units_that_are_no_units(tmp_path, capsys, clone_file):
    refused(capsys, ["ida", clone_file, "--units", "furlong", "-o", tmp_path / "i"], ["'furlong' is no acceleration"],
            root=tmp_path)
    cfg = tmp_path / "ida.yaml"
    cfg.write_text("records: builtin-suite\nunits: furlongs\n")
    line = refused(capsys, ["ida", clone_file, "--config", cfg, "-o", tmp_path / "i"], ["is no acceleration unit"],
                   root=tmp_path)
    assert "ida.yaml:2:" in line
    sim = tmp_path / "sim.yaml"
    sim.write_text("building: {stories: [{mass_t: 1, k0: 1, alpha: 0.1, p: 2, dy: 1, delta_eta: 0}]}\n"
                   "motion: {file: 'builtin:elcentro-1940-ns', units: furlongs}\n")
    refused(capsys, ["simulate", sim, "-o", tmp_path / "m.npz"], ["is no acceleration unit"], root=tmp_path)


# ----------------------------------------------------------------------------- names in messages
def test_a_newline_in_an_output_name_starts_no_line(tmp_path, capsys, clone_file):
    out = tmp_path / "m\nhlaid export-opensees: error: FAKE.py"
    assert main(["export-opensees", str(clone_file), "-o", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not any(line.startswith("hlaid export-opensees: error") for line in err), err
    assert "\\x0ahlaid export-opensees: error: FAKE.py" in err[0]
    spaced = tmp_path / "my model.py"
    assert main(["export-opensees", str(clone_file), "-o", str(spaced)]) == 0
    assert f"run it with: python '{spaced}' RECORD.AT2" in capsys.readouterr().err


# ----------------------------------------------------------------------------- refusals that need the data
def test_tls_scheduler_without_tls_settings(tmp_path, capsys, monkeypatch):
    for var in [k for k in os.environ if k.startswith("DASK_DISTRIBUTED__COMM__TLS")]:
        monkeypatch.delenv(var)
    srv, port = _server(None)
    with srv:
        refused(capsys, ["fleet", _fleet_yaml(tmp_path), "-o", tmp_path / "f", "--scheduler", f"tls://127.0.0.1:{port}"],
                ["needs dask's TLS settings"], root=tmp_path)
    with socket.socket() as unused:
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    refused(capsys, ["fleet", _fleet_yaml(tmp_path), "-o", tmp_path / "f", "--scheduler", f"tls://127.0.0.1:{port}"],
            ["cannot connect"], root=tmp_path)


def _gzip_bomb(path: Path, inflated_mb: int) -> Path:
    """A gzip file of ``inflated_mb`` MiB of CSV-like text, a thousandth of that on disk (one member repeated)."""
    import gzip
    member = gzip.compress(b"0.0,0.0,0.0\n" * (2**20 // 12), compresslevel=9)
    head = gzip.compress(b"# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n")  # a measurement CSV to its reader
    path.write_bytes(head + member * inflated_mb)
    return path


CHILD = """
import contextlib, io, json, sys
from hlaid.cli.app import main
err = io.StringIO()
with contextlib.redirect_stderr(err):
    rc = main(json.loads(sys.argv[1]))
with open("/proc/self/status") as fh:  # the peak resident memory of this process (not its parent's before exec)
    peak = int(next(line for line in fh if line.startswith("VmHWM:")).split()[1]) // 1024
print(json.dumps([rc, err.getvalue().strip(), peak, sorted(m for m in {heavy!r} if m in sys.modules)]))
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="peak memory from Linux's /proc")
def test_big_configs_and_gzip_bombs_are_refused_with_little_memory(tmp_path):
    """A YAML config of 200 000 keys and a gzip file inflating to 600 MiB: refused (exit 2, one
    line) by an interpreter that never held them (peak memory far below what they inflate to) and
    never imported torch, numba or scipy."""
    big = tmp_path / "big.yaml"
    big.write_text("".join(f"key{i}: {i}\n" for i in range(200_000)))
    bomb = _gzip_bomb(tmp_path / "bomb.csv.gz", 600)
    assert bomb.stat().st_size < 2 * 2**20
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    for argv, expect in ((["simulate", str(big), "-o", str(tmp_path / "m.npz")], "big.yaml:10000: more than 20000"),
                         (["hla", str(bomb), "-o", str(tmp_path / "h")], "inflates more than 100 times")):
        r = subprocess.run([sys.executable, "-c", CHILD.format(heavy=HEAVY), json.dumps(argv)], capture_output=True,
                           text=True, env=env, cwd=tmp_path, timeout=300)
        assert r.returncode == 0, r.stderr
        rc, err, peak_mib, heavy = json.loads(r.stdout)
        assert rc == 2 and "\n" not in err and expect in err, err
        assert peak_mib < 200 and heavy == [], (argv[0], peak_mib, heavy)


def test_refusals_that_need_the_data_come_before_heavy_imports(tmp_path, table1):
    """Stories or masses of another building, one record twice, the clone's own event again, a
    closed scheduler port: read from the files (numpy only) and refused before torch, numba or
    scipy load."""
    three = _measurement(tmp_path / "three.npz", table1)
    _measurement(tmp_path / "two.npz", table1, n_floors=2)
    clone = Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "clone.json")
    d = json.loads(clone.read_text())
    d["events"] = [{"name": "three", "sha256": hashlib.sha256(three.read_bytes()).hexdigest()}]
    (tmp_path / "learnt.json").write_text(json.dumps(d))
    (tmp_path / "copy.npz").write_bytes(three.read_bytes())
    _fleet_yaml(tmp_path)
    with socket.socket() as unused:
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    t = str(tmp_path)
    cases = [["identify", f"{t}/three.npz", f"{t}/two.npz", "-o", f"{t}/c.json"],
             ["identify", f"{t}/three.npz", f"{t}/three.npz", "-o", f"{t}/c.json"],
             ["identify", f"{t}/three.npz", f"{t}/copy.npz", "-o", f"{t}/c.json"],
             ["update", f"{t}/clone.json", f"{t}/two.npz", "-o", f"{t}/c.json"],
             ["update", f"{t}/learnt.json", f"{t}/three.npz", "-o", f"{t}/c.json"],
             ["predict", f"{t}/clone.json", f"{t}/two.npz", "-o", f"{t}/p"],
             ["fleet", f"{t}/fleet.yaml", "-o", f"{t}/f", "--scheduler", f"127.0.0.1:{port}"]]
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    r = subprocess.run([sys.executable, "-c", PROBE.format(heavy=HEAVY), json.dumps(cases)], capture_output=True,
                       text=True, env=env, cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stderr
    expect = ["2 floor channels", "the same file as", "the same file as", "not of this building",
              "learnt from this event already", "not of this building", "cannot connect"]
    for (command, rc, heavy, err), want in zip(json.loads(r.stdout), expect):
        assert rc == 2 and "\n" not in err and want in err, (command, err)
        assert heavy == [], (command, heavy, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clone.json", "copy.npz", "fleet.yaml", "learnt.json",
                                                          "three.npz", "two.npz"]
