"""Hostile inputs, fourth round: a clone hlaid wrote is always readable, outputs are hlaid's only by
their content (hashes and permissions, never size and time), the signing key is used only when it
is private, only the temporary names hlaid tagged are swept, checks come before the work, readers
are bounded by bytes, and absurd values are refused. Each refusal is exit 2 with one line and
leaves the sandbox (``tmp_path``) as it was."""

from __future__ import annotations

import json
import os
import stat
import time
from pathlib import Path

import numpy as np
import pytest
from test_bad_input import _run_folder
from test_hostile import HEIGHTS, _measurement, deadline, refused, tree

from hlaid import _outdir, _outkey
from hlaid._fileio import MARKER, atomic_directory, is_hlaid_output
from hlaid.cli.app import main
from hlaid.clone import Clone

POSIX = pytest.mark.skipif(os.name != "posix", reason="FIFOs, permissions and signals of POSIX")


@pytest.fixture()
def clone_file(table1, tmp_path) -> Path:
    return Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "clone.json")


@pytest.fixture()
def state(tmp_path_factory, monkeypatch) -> Path:
    """A key folder of this test's own (outside the sandbox the refusals check)."""
    d = tmp_path_factory.mktemp("state")
    monkeypatch.setenv("HLAID_STATE_DIR", str(d))
    return d


# ----------------------------------------------------------------------------- hlaid reads its own clone
def test_a_clone_with_an_unidentified_parameter_is_written_readable_and_flagged(tmp_path, table1, capsys):
    """Identification can leave a parameter unidentified (a standard deviation of 11.6 in its log
    scale on a record that hardly drove that story): the clone file holds it capped at the reader's
    bound and named, and every command reads it."""
    from hlaid.model.uncertainty import MAX_THETA_STD, ParameterUncertainty
    u = ParameterUncertainty(slots=(("k0", 0), ("p", 2), ("damping", -1)), transform=("log", "log1", "log"),
                             centre=np.log([1e4, 1.5, 0.02]),
                             covariance=np.array([[0.01, 0.05, 0.0], [0.05, 11.6**2, 1.0], [0.0, 1.0, 1e6]]))
    clone = Clone(building=table1.replace(height=HEIGHTS), uncertainty=u)
    path = clone.save(tmp_path / "c3.json")
    d = json.loads(path.read_text())["uncertainty"]
    assert max(p["std"] for p in d["parameters"]) == pytest.approx(MAX_THETA_STD)
    assert d["info"]["unidentified"] == ["damping", "p[3]"]
    back = Clone.load(path)
    assert back.uncertainty.unidentified == ["damping", "p[3]"]
    assert np.allclose(back.uncertainty.std, [0.1, MAX_THETA_STD, MAX_THETA_STD])
    assert np.linalg.eigvalsh(back.uncertainty.covariance).min() > -1e-9  # still a covariance
    assert back.uncertainty.covariance[0, 1] == pytest.approx(0.05 * MAX_THETA_STD / 11.6)  # correlations kept
    assert main(["export-opensees", str(path), "-o", str(tmp_path / "m.py")]) == 0
    capsys.readouterr()
    bad = json.loads(path.read_text())  # beyond the bound hlaid writes: a file hlaid did not write
    bad["uncertainty"]["covariance"][1][1] = 11.6**2
    path.write_text(json.dumps(bad))
    line = refused(capsys, ["export-opensees", path, "-o", tmp_path / "m2.py"], ["standard deviation of 11.6"],
                   root=tmp_path, within=60)
    assert "hlaid writes at most 10" in line


# ----------------------------------------------------------------------------- ownership by content
def _hlaid_run(path: Path) -> Path:
    """A run folder as hlaid writes it: signed, its files recorded."""
    src = _run_folder(path.with_name(path.name + "-src"))
    (src / "report.html").write_text("<p>the report hlaid wrote</p>")
    with atomic_directory(path, what="hlaid run") as tmp:
        for p in sorted(src.rglob("*")):
            rel = p.relative_to(src)
            if p.is_dir():
                (tmp / rel).mkdir()
            else:
                (tmp / rel).write_bytes(p.read_bytes())
    for p in sorted(src.rglob("*"), reverse=True):
        p.rmdir() if p.is_dir() else p.unlink()
    src.rmdir()
    return path


@POSIX
@pytest.mark.parametrize("edit", ["notes", "key", "readonly", "added"])
def test_report_and_loss_never_rewrite_a_run_folder_the_user_changed(tmp_path, capsys, edit):
    """Notes appended to report.html, a key added to summary.json, a file made read-only, a file
    added: ``hlaid report RUN`` and ``hlaid loss RUN`` (also with --force) refuse before writing
    anything, and the user's files keep their hashes and permissions."""
    run = _hlaid_run(tmp_path / "run")
    assert main(["report", str(run)]) == 0  # hlaid's own rewrite: recorded, the folder stays hlaid's
    capsys.readouterr()
    assert _outdir.not_ours(run) is None
    if edit == "notes":
        with open(run / "report.html", "a") as fh:
            fh.write("<p>my notes</p>")
        name = "report.html (changed)"
    elif edit == "key":
        s = json.loads((run / "summary.json").read_text())
        (run / "summary.json").write_text(json.dumps({**s, "my_key": 1}))
        name = "summary.json (changed)"
    elif edit == "readonly":
        os.chmod(run / "summary.json", 0o444)
        name = "summary.json (changed)"
    else:
        (run / "notes.txt").write_text("mine")
        name = "notes.txt"
    modes = {p: stat.S_IMODE(p.stat().st_mode) for p in run.rglob("*")}
    for argv in (["report", run], ["loss", run, "--floor-area", "100", "--no-curve"],
                 ["loss", run, "--floor-area", "100", "--no-curve", "--force"]):
        line = refused(capsys, argv, [name], root=tmp_path, within=60)
        assert "nothing was changed" in line
    assert {p: stat.S_IMODE(p.stat().st_mode) for p in run.rglob("*")} == modes


def test_a_same_size_edit_with_its_time_put_back_is_the_users(tmp_path, capsys, table1):
    out = tmp_path / "hout"
    with atomic_directory(out, what="hlaid hla") as tmp:
        (tmp / "hla.json").write_text('{"k0": 1}')
    st = (out / "hla.json").stat()
    (out / "hla.json").write_text('{"k0": 2}')  # same size
    os.utime(out / "hla.json", ns=(st.st_atime_ns, st.st_mtime_ns))  # touch -r
    assert (out / "hla.json").stat().st_mtime_ns == st.st_mtime_ns
    refused(capsys, ["hla", _measurement(tmp_path / "m.npz", table1), "-o", out, "--force"], ["hla.json (changed)"],
            root=tmp_path, within=60)


@POSIX
def test_a_file_made_read_only_makes_the_output_the_users(tmp_path, capsys, table1):
    out = tmp_path / "hout"
    with atomic_directory(out, what="hlaid hla") as tmp:
        (tmp / "hla.json").write_text('{"k0": 1}')
    os.chmod(out / "hla.json", 0o444)
    refused(capsys, ["hla", _measurement(tmp_path / "m.npz", table1), "-o", out, "--force"], ["hla.json (changed)"],
            root=tmp_path, within=60)


# ----------------------------------------------------------------------------- the key
@POSIX
@pytest.mark.parametrize("kind", ["world-readable", "group-writable", "symlink", "fifo", "folder"])
def test_a_key_file_unsafe_to_use_is_refused_before_the_work(tmp_path, capsys, state, clone_file, kind):
    """A key others may read (so they can forge a marker that lets root's --force delete a thesis),
    a link, a FIFO (whose read would block forever) or a folder: one line saying how to fix it."""
    key = state / "output-key"
    key.unlink(missing_ok=True)  # made while the clone was written
    if kind in ("world-readable", "group-writable"):
        key.write_text("ab" * 32 + "\n")
        os.chmod(key, 0o644 if kind == "world-readable" else 0o620)
    elif kind == "symlink":
        (state / "elsewhere").write_text("ab" * 32 + "\n")
        key.symlink_to(state / "elsewhere")
    elif kind == "fifo":
        os.mkfifo(key)
    else:
        key.mkdir()
    fix = ["rm ", "rmdir "]
    with deadline(60):
        line = refused(capsys, ["export-opensees", clone_file, "-o", tmp_path / "model.py"], fix, root=tmp_path)
        assert "output key" in line
        refused(capsys, ["ida", clone_file, "-o", tmp_path / "new", "--levels", "0.1"], fix, root=tmp_path)


def test_a_forged_marker_with_a_world_readable_key_opens_nothing(tmp_path, capsys, state, table1):
    """Another user read the key and signed a marker for a folder holding thesis.tex."""
    out = tmp_path / "forged"
    with atomic_directory(out, what="hlaid hla") as tmp:
        (tmp / "thesis.tex").write_text("four years")
    os.chmod(state / "output-key", 0o644)
    refused(capsys, ["hla", _measurement(tmp_path / "m.npz", table1), "-o", out, "--force"], ["output key"],
            root=tmp_path, within=60)
    assert (out / "thesis.tex").read_text() == "four years"


def test_an_output_that_cannot_be_signed_says_so_when_written_and_after(tmp_path, capsys, monkeypatch, clone_file):
    from hlaid.errors import HlaidWarning
    monkeypatch.setenv("HLAID_STATE_DIR", str(tmp_path / "no" / "such"))
    monkeypatch.setattr(_outkey, "_make", lambda root, path: setattr(_outkey, "_problem", f"{root} is not writable"))
    out = tmp_path / "i"
    with pytest.warns(HlaidWarning, match=f"{out}: its {MARKER} is unsigned .*is not writable"), \
            atomic_directory(out, what="hlaid ida") as tmp:
        (tmp / "summary.json").write_text("{}")
    line = refused(capsys, ["ida", clone_file, "-o", out, "--levels", "0.05", "--force"], ["is unsigned"],
                   root=tmp_path, within=60)
    assert "made by hand" not in line and "HOME" not in line and "is not writable" in line


# ----------------------------------------------------------------------------- sweeping leftovers
def _dead_pid() -> int:
    pid = 999_999
    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return pid
        except OSError:
            pass
        pid -= 1


def _aged(path: Path, seconds: float) -> Path:
    t = time.time() - seconds
    os.utime(path, (t, t))
    return path


def test_only_temporary_names_hlaid_tagged_are_swept(tmp_path, capsys, clone_file):
    """A user's ``.run1.old-2024/notes.txt`` (2 days old) and ``.model.py.1234-draft.tmp`` (3 hours)
    stay; a leftover hlaid tagged, whose process is gone, is removed."""
    (tmp_path / ".run1.old-2024").mkdir()
    (tmp_path / ".run1.old-2024" / "notes.txt").write_text("mine")
    _aged(tmp_path / ".run1.old-2024" / "notes.txt", 2 * 86400)
    _aged(tmp_path / ".run1.old-2024", 2 * 86400)
    _aged(tmp_path / ".model.py.1234-draft.tmp", 3 * 3600) if (tmp_path / ".model.py.1234-draft.tmp").write_text(
        "draft") else None
    for name in (".model.py.99999-abcdefgh.tmp", ".model.py.99999-0123456789abcdef01234567.tmp"):
        _aged(tmp_path / name, 3 * 3600) if (tmp_path / name).write_text("also mine") else None
    pid, token = _dead_pid(), "0123abcd"
    ours = f".model.py.{pid}-{token}{_outkey._tag('model.py', pid, token, _outkey.signing_key())}.tmp"
    _aged(tmp_path / ours, 3 * 3600) if (tmp_path / ours).write_text("left by a killed run") else None
    before = tree(tmp_path)
    assert main(["export-opensees", str(clone_file), "-o", str(tmp_path / "model.py")]) == 0
    after = tree(tmp_path)
    assert {k: v for k, v in before.items() if k != ours} == {k: v for k, v in after.items() if k != "model.py"}
    assert ours not in after
    with atomic_directory(tmp_path / "run1") as tmp:
        (tmp / "a").write_text("1")
    with atomic_directory(tmp_path / "run1", force=True) as tmp:
        (tmp / "a").write_text("2")
    assert (tmp_path / ".run1.old-2024" / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".run1")) == [".run1.old-2024"]
    assert is_hlaid_output(tmp_path / "run1")


# ----------------------------------------------------------------------------- Ctrl-C in the compiled batches
@POSIX
@pytest.mark.parametrize("sig", ["SIGTERM"])
def test_a_large_compiled_batch_stops_within_seconds_of_a_signal(tmp_path, sig):
    """A batch of the compiled simulator that runs for a minute (the ensemble of ``hlaid demands
    --ensemble 20000`` is one) stops within a second or two of Ctrl-C or SIGTERM: it runs in chunks."""
    import signal
    import subprocess
    import sys
    code = ("import sys, numpy as np\nsys.path.insert(0, 'tests')\n"
            "from reference_systems import table1_stories\nfrom hlaid._interrupt import sticky_sigint\n"
            "from hlaid.model import Building\nfrom hlaid.motions import GroundMotion\n"
            "from hlaid.simulate import simulate_response\n"
            "b = Building.from_stories(table1_stories(), name='t', pdelta=False)\n"
            "t = np.arange(8000) * 0.01\n"
            "m = GroundMotion(acc=3000 * np.sin(2 * np.pi * t) * np.exp(-0.1 * t), dt=0.01, name='x')\n"
            "simulate_response([b], [m], outputs='peaks')\n"
            "print('READY', flush=True)\n"
            "with sticky_sigint():\n"
            "    try:\n"
            "        simulate_response([b] * 2000, [m], outputs='peaks')\n"
            "    except KeyboardInterrupt as e:\n"
            "        print('STOPPED', type(e).__name__, flush=True)\n"
            "        sys.exit(130)\n")
    repo = Path(__file__).resolve().parents[1]
    p = subprocess.Popen([sys.executable, "-c", code], cwd=repo, stdout=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONPATH": str(repo)})
    try:
        assert p.stdout.readline().strip() == "READY"
        time.sleep(3.0)  # the batch is being prepared (0.1 s), then runs in the compiled kernel (a minute)
        t0 = time.monotonic()
        p.send_signal(getattr(signal, sig))
        out = p.stdout.readline()
        waited = time.monotonic() - t0
        p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130 and "STOPPED" in out, out
    assert waited < 5.0, waited  # the whole batch: a minute


# ----------------------------------------------------------------------------- bounded by bytes, checked first
def test_a_data_line_of_many_megabytes_is_refused_while_read(tmp_path, capsys):
    import tracemalloc
    csv = tmp_path / "line.csv"
    with open(csv, "wb") as fh:
        fh.write(b"# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n")
        fh.write(b"1," * (32 * 2**20 // 2) + b"\n")  # one line of 32 MiB
    tracemalloc.start()
    try:
        refused(capsys, ["hla", csv, "-o", tmp_path / "o"], ["holds a line of more than 1 MiB"], root=tmp_path,
                within=60)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20  # a block of 4 MiB and the readers' imports, not the file


def test_an_npz_of_100000_members_is_refused_from_its_end_record(tmp_path, capsys):
    import zipfile
    m = tmp_path / "members.npz"
    with zipfile.ZipFile(m, "w") as z:
        for i in range(100_000):
            z.writestr(f"a{i}.npy", b"")
    t0 = time.perf_counter()
    refused(capsys, ["hla", m, "-o", tmp_path / "o"], ["100,000 members"], root=tmp_path, within=60)
    assert time.perf_counter() - t0 < 5.0  # its directory alone takes seconds to read
    small = tmp_path / "small.npz"
    np.savez(small, a=np.zeros(3), b=np.ones(2))
    from hlaid._inputs import _member_count, load_npz
    with open(small, "rb") as fh:
        assert _member_count(fh) == 2
    assert sorted(load_npz(small)) == ["a", "b"]


@pytest.mark.parametrize("argv,expect", [
    (["demands", "{c}", "--motion", "m.npz", "--ensemble", "100001", "-o", "d.csv"], "100001 clones; expected 0"),
    (["demands", "{c}", "--motion", "m.npz", "--ensemble", "-1", "-o", "d.csv"], "-1 clones; expected 0"),
    (["predict", "{c}", "m.npz", "--ensemble", "200000", "-o", "p"], "200000 clones; expected 0"),
    (["ida", "{c}", "--heights", "1,1,1", "-o", "i"], "1 mm looks like metres (1 m = 1000 mm)"),
    (["ida", "{c}", "--heights", "3.0,3.0,3.0", "-o", "i"], "story heights are in mm; 3 mm looks like metres"),
    (["ida", "{c}", "--heights", "1000000,1000000,1000000", "-o", "i"], "a story height of 1e+06 mm"),
    (["demands", "{c}", "--motion", "m.npz", "--heights", "3,3,3", "-o", "d.csv"], "looks like metres"),
    (["export-opensees", "{c}", "--heights", "3,3,3", "-o", "m.py"], "looks like metres"),
    (["ida", "{c}", "--drift-limit", "5", "-o", "i"], "5 is 500%"),
    (["loss", "d.csv", "--drift-limit", "5", "--floor-area", "100", "-o", "l"], "a drift limit is a ratio"),
])
def test_absurd_arguments_are_refused_as_they_are_parsed(tmp_path, clone_file, argv, expect):
    """Before the clone is read or torch loads: a refusal in a fresh interpreter that never imports
    torch (``predict --ensemble`` did; ``demands --ensemble 100001`` took 3 s and 400 MB)."""
    from test_hostile_round3 import _cli
    (tmp_path / "m.npz").write_bytes(b"a measurement")
    (tmp_path / "d.csv").write_text(",1-PID-1-1\nUnits,rad\n0,0.01\n")
    before = tree(tmp_path)
    rc, err, torch_loaded = _cli(tmp_path, [a.replace("{c}", str(clone_file)) for a in argv],
                                 env={"HLAID_MAX_BOOTSTRAP": "1000000"})
    assert rc == 2 and len(err) == 1 and expect in err[0], err
    assert "HLAID_MAX" not in err[0]  # no advice a later check refuses
    assert not torch_loaded
    assert tree(tmp_path) == before


def test_a_clone_with_a_damping_ratio_of_099_is_refused(tmp_path, capsys, table1):
    from test_hostile import _clone_dict
    d = _clone_dict(table1)
    d["damping"]["ratio"] = 0.99
    c = tmp_path / "c.json"
    c.write_text(json.dumps(d))
    refused(capsys, ["export-opensees", c, "-o", tmp_path / "m.py"], ["damping.ratio = 0.99"], root=tmp_path)


# ----------------------------------------------------------------------------- absurd records
@pytest.mark.parametrize("how", ["x1000", "one floor", "one sample"])
def test_a_floor_channel_out_of_scale_with_the_ground_is_refused_naming_it(tmp_path, capsys, table1, how):
    m = _measurement(tmp_path / "m.npz", table1)
    d = dict(np.load(m))
    f = d["floor_acc"].copy()
    if how == "x1000":
        f *= 1000.0
    elif how == "one floor":
        f[:, 1] *= 1000.0
    else:
        f[700, 2] = 1e12
    np.savez(m, **{**d, "floor_acc": f})
    line = refused(capsys, ["hla", m, "-o", tmp_path / "o"], ["times the ground's peak"], root=tmp_path)
    assert str(m) in line and f"floor {3 if how == 'one sample' else 2}" in line or how == "x1000"


# ----------------------------------------------------------------------------- messages
def test_long_values_are_echoed_clipped(tmp_path, capsys, table1):
    """A YAML ``!!binary`` value of 60,000 characters, 100 negative masses: the line stays readable."""
    import base64
    cfg = tmp_path / "b.yaml"
    cfg.write_text("preprocess:\n  order: !!binary " + base64.b64encode(os.urandom(45_000)).decode() + "\n")
    line = refused(capsys, ["hla", _measurement(tmp_path / "m.npz", table1), "-o", tmp_path / "o", "--config", cfg],
                   ["order", "preprocess"], root=tmp_path)
    assert len(line) < 1200
    m = tmp_path / "neg.npz"
    t = np.arange(2000) * 0.01
    g = 2000.0 * np.sin(2 * np.pi * 1.3 * t)
    np.savez(m, dt=0.01, ground_acc=g, floor_acc=np.outer(g, np.linspace(1, 2, 100)), mass=-np.ones(100))
    line = refused(capsys, ["hla", m, "-o", tmp_path / "o"], ["mass[0] = -1 (and 99 more)"], root=tmp_path)
    assert len(line) < 300


@POSIX
@pytest.mark.parametrize("sig,code,word", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
def test_a_signal_just_after_the_command_ended_is_said(tmp_path, clone_file, sig, code, word):
    """SIGINT or SIGTERM while the interpreter shuts down (after "wrote ..."): one line, not a traceback
    or a silent death."""
    import subprocess
    import sys
    repo = Path(__file__).resolve().parents[1]
    code_text = (f"import os, signal, sys, time\nsys.argv = ['hlaid', 'export-opensees', {str(clone_file)!r}, '-o', "
                 f"'m.py']\nimport atexit\natexit.register(lambda: (os.kill(os.getpid(), signal.{sig}), "
                 "time.sleep(5)))\nfrom hlaid.cli import main\nsys.exit(main())\n")
    r = subprocess.run([sys.executable, "-c", code_text], capture_output=True, text=True, cwd=tmp_path, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(repo)})
    lines = r.stderr.strip().splitlines()
    assert r.returncode == code, r.stderr
    assert "wrote" in lines[0] and lines[-1].startswith(f"hlaid: {word} after the command ended"), lines
    assert "Traceback" not in r.stderr
    assert (tmp_path / "m.py").is_file()


@pytest.mark.parametrize("key", [True, False])
def test_a_folder_replaced_in_place_skips_only_its_own_temporary(tmp_path, monkeypatch, key):
    """A folder that cannot be renamed (a mount point) is built inside itself: its own temporary
    folder there (tagged, or untagged where there is no key) is not taken for the user's; a
    look-alike the user made is."""
    if not key:
        monkeypatch.setenv("HLAID_STATE_DIR", str(tmp_path / "none"))
        monkeypatch.setattr(_outkey, "_make", lambda root, path: None)
    out = tmp_path / "mnt"
    out.mkdir()
    monkeypatch.setattr(_outdir, "cannot_rename", lambda p: Path(p) == out)
    with atomic_directory(out, force=True, what="hlaid test") as tmp:
        assert tmp.parent == out
        (tmp / "a.json").write_text("{}")
    assert (out / "a.json").read_text() == "{}" and [p.name for p in out.iterdir() if p.name.startswith(".")] \
        == [MARKER]
    if key:
        (out / f".mnt.{os.getpid()}-0123abcd{'0' * 12}.tmp").mkdir()  # a look-alike, not tagged
        assert f"mnt.{os.getpid()}-" in (_outdir.not_ours(out) or "")
