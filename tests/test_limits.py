"""Size limits, outputs checked before work, stale temporary outputs, classifier cache integrity.

Every refused input or output is exit status 2 with one line on stderr, no traceback, and
nothing written at the destination.
"""

from __future__ import annotations

import gzip
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hlaid._fileio import STALE_AFTER_S, atomic_directory, write_json
from hlaid._inputs import check_archive
from hlaid.cli import main
from hlaid.clone import Clone
from hlaid.errors import HlaidWarning, InputError
from hlaid.identify.cache import MachineCache
from hlaid.io import read
from hlaid.limits import DEFAULTS, limit

REPO = Path(__file__).resolve().parents[1]
POC = (REPO / "configs" / "poc_3story.yaml").read_text()
HEIGHTS = [3000.0, 3000.0, 3000.0]


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def _refused(capsys, argv: list[str], *, expect: str, dest: Path) -> str:
    assert main(argv) == 2
    line = _one_line(capsys)
    assert expect in line, line
    assert not dest.exists()
    assert not [p for p in dest.parent.iterdir() if p.name.startswith(f".{dest.name}.")]
    return line


def _config(tmp_path: Path, **replace) -> Path:
    text = POC
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "cfg.yaml"
    path.write_text(text)
    return path


@pytest.fixture()
def clone_file(table1, tmp_path):
    path = tmp_path / "clone.json"
    Clone(building=table1.replace(height=HEIGHTS), provenance={"test": True}).save(path)
    return path


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _age(path: Path, seconds: float) -> None:
    t = time.time() - seconds
    os.utime(path, (t, t))


# ------------------------------------------------------------------ size limits
def test_limits_default_and_environment(monkeypatch):
    assert limit("SAMPLES") == DEFAULTS["SAMPLES"]
    monkeypatch.setenv("HLAID_MAX_SAMPLES", "5e3")
    assert limit("SAMPLES") == 5000
    monkeypatch.setenv("HLAID_MAX_SAMPLES", "lots")
    with pytest.raises(InputError, match="HLAID_MAX_SAMPLES = 'lots'; expected a number with 16 <= HLAID_MAX_SAMPLES"):
        limit("SAMPLES")


def test_simulate_rate_over_the_limit(tmp_path, capsys):
    cfg = _config(tmp_path, **{"rate_hz: 200": "rate_hz: 1e6"})
    out = tmp_path / "m.npz"
    line = _refused(capsys, ["simulate", str(cfg), "-o", str(out)], expect="rate_hz = 1000000 is out of range",
                    dest=out)
    assert "HLAID_MAX_RATE_HZ" in line


def test_simulate_samples_over_the_limit(tmp_path, capsys, monkeypatch):
    """duration x rate is checked before resampling (the rate limit raised, the sample limit not)."""
    monkeypatch.setenv("HLAID_MAX_RATE_HZ", "1e7")
    cfg = _config(tmp_path, **{"rate_hz: 200": "rate_hz: 1e6"})
    out = tmp_path / "m.npz"
    line = _refused(capsys, ["simulate", str(cfg), "-o", str(out), "-q"], expect="samples at 1e+06 Hz = ", dest=out)
    assert "exceeds the limit of 2000000 (set HLAID_MAX_SAMPLES" in line


def test_simulate_too_many_stories(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HLAID_MAX_STORIES", "2")
    out = tmp_path / "m.npz"
    _refused(capsys, ["simulate", str(_config(tmp_path)), "-o", str(out)], expect="stories = 3 exceeds", dest=out)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_motion_from_an_endless_device(tmp_path, capsys):
    cfg = _config(tmp_path, **{'file: "builtin:elcentro-1940-ns"': "file: /dev/zero, dt: 0.01, units: g"})
    out = tmp_path / "m.npz"
    _refused(capsys, ["simulate", str(cfg), "-o", str(out), "-q"],
             expect="/dev/zero: is a character device; expected a regular file", dest=out)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_motion_from_a_fifo_does_not_block(tmp_path, capsys):
    os.mkfifo(tmp_path / "pipe.txt")
    cfg = _config(tmp_path, **{'file: "builtin:elcentro-1940-ns"': "file: pipe.txt, dt: 0.01, units: g"})
    out = tmp_path / "m.npz"
    _refused(capsys, ["simulate", str(cfg), "-o", str(out), "-q"], expect="is a FIFO (named pipe)", dest=out)


def test_measurement_file_over_the_size_limit(tmp_path, capsys, monkeypatch):
    meas = tmp_path / "meas.csv"
    meas.write_text("# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n" + "0,1,1\n" * 1000)
    monkeypatch.setenv("HLAID_MAX_FILE_MB", "0.001")
    out = tmp_path / "c.json"
    line = _refused(capsys, ["identify", str(meas), "-o", str(out)],
                    expect=f"{meas}: is 0.00576 MiB, over the limit of 0.001 MiB", dest=out)
    assert "HLAID_MAX_FILE_MB" in line


def test_gzip_and_npz_are_limited_by_their_inflated_size(tmp_path, monkeypatch):
    monkeypatch.setenv("HLAID_MAX_FILE_MB", "0.05")
    rec = tmp_path / "rec.txt.gz"
    rec.write_bytes(gzip.compress(b"# dt=0.01 units: g\n" + b"0.0\n" * 100_000))
    assert rec.stat().st_size < 2**20 * 0.05
    with pytest.raises(InputError, match="holds more than the limit of 0.05 MiB"):
        read(rec, "motion")
    npz = tmp_path / "m.npz"
    np.savez_compressed(npz, ground_acc=np.zeros(100_000))
    with pytest.raises(InputError, match="inflates to 0.763 MiB, over the limit of 0.05 MiB"):
        check_archive(npz)


@pytest.mark.parametrize("args, expect", [
    (["--bootstrap", "100000000"], "bootstrap = 100000000 is out of range; expected 0 <= bootstrap <= 100000 "
                                   "(set HLAID_MAX_BOOTSTRAP"),
    (["--n-levels", "100000000"], "n_levels = 100000000 is out of range; expected 2 <= n_levels <= 1000 "
                                  "(set HLAID_MAX_IDA_LEVELS"),
    (["--levels", "0:1e9:1e-3"], "--levels 0:1e9:1e-3: number of values = "),
])
def test_ida_counts_over_the_limit(clone_file, tmp_path, capsys, args, expect):
    out = tmp_path / "ida"
    t = time.perf_counter()
    _refused(capsys, ["ida", str(clone_file), "--records", "builtin:elcentro-1940-ns", *args, "-o", str(out)],
             expect=expect, dest=out)
    assert time.perf_counter() - t < 10


def test_ida_config_counts_over_the_limit(clone_file, tmp_path, capsys):
    cfg = tmp_path / "ida.yaml"
    cfg.write_text("records: builtin:elcentro-1940-ns\nmax_hunt: 100000000\n")
    out = tmp_path / "ida"
    _refused(capsys, ["ida", str(clone_file), "--config", str(cfg), "-o", str(out)],
             expect=f"{cfg}:2: max_hunt = 100000000 is out of range", dest=out)


def test_ida_too_many_records(clone_file, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HLAID_MAX_IDA_RECORDS", "3")
    out = tmp_path / "ida"
    _refused(capsys, ["ida", str(clone_file), "--records", "builtin-suite", "-o", str(out)],
             expect="records = 10 exceeds the limit of 3", dest=out)


# ------------------------------------------------------------------ outputs checked first
@pytest.mark.parametrize("argv", [
    ["identify", "{missing}", "-o", "{dest}"],
    ["simulate", "{missing}", "-o", "{dest}"],
    ["export-opensees", "{missing}", "-o", "{dest}"],
    ["hla", "{missing}", "-o", "{dest}"],
    ["ida", "{missing}", "-o", "{dest}"],
    ["run", "{missing}", "-o", "{dest}"],
    ["demo", "--out", "{dest}"],
])
def test_missing_output_folder_is_reported_before_any_work(tmp_path, capsys, argv):
    """The input does not even exist: the output error comes first, so no work was done."""
    dest = tmp_path / "no-such-folder" / "out"
    argv = [a.format(missing=tmp_path / "missing-input", dest=dest) for a in argv]
    assert main(argv) == 2
    line = _one_line(capsys)
    assert f"{dest.parent}: folder does not exist; create it first" in line, line
    assert not dest.parent.exists()


@pytest.mark.parametrize("command", ["identify", "simulate"])
def test_file_output_that_is_a_folder_or_under_a_file(tmp_path, capsys, command):
    (tmp_path / "d").mkdir()
    (tmp_path / "f").write_text("precious")
    assert main([command, "x", "-o", str(tmp_path / "d"), "--force"]) == 2
    assert "d: is a folder; expected an output file name" in _one_line(capsys)
    assert main([command, "x", "-o", str(tmp_path / "f" / "c.json")]) == 2
    assert "f: is not a folder; it cannot hold the output" in _one_line(capsys)
    assert (tmp_path / "f").read_text() == "precious"


def test_folder_output_that_is_a_file(tmp_path, capsys):
    (tmp_path / "f").write_text("precious")
    assert main(["hla", "x", "-o", str(tmp_path / "f"), "--force"]) == 2
    assert "f: exists and is not a folder" in _one_line(capsys)
    assert (tmp_path / "f").read_text() == "precious"


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root may write anywhere")
def test_unwritable_output_folder(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["identify", "x", "-o", str(ro / "c.json")]) == 2
        assert "ro: folder is not writable" in _one_line(capsys)
    finally:
        ro.chmod(0o755)


# ------------------------------------------------------------------ leftovers
def test_interrupted_writers_leave_nothing(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with atomic_directory(tmp_path / "out") as tmp:
            (tmp / "half.json").write_text("{")
            raise KeyboardInterrupt
    from hlaid._fileio import atomic_write

    def interrupted(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "c.json", interrupted)
    assert list(tmp_path.iterdir()) == []


def test_stale_temporary_outputs_are_removed_on_the_next_write(tmp_path):
    from hlaid import _outkey
    dead, alive = _dead_pid(), os.getpid()

    def tagged(stem: str, pid: int, token: str) -> str:  # a name hlaid made (see hlaid._outkey.temp_name)
        return f"{pid}-{token}{_outkey._tag(stem, pid, token, _outkey.signing_key())}"
    stale_file = tmp_path / f".c.json.{tagged('c.json', dead, 'abc12300')}.tmp.json"
    stale_dir = tmp_path / f".out.{tagged('out', dead, '0f2a4b5c')}.tmp"
    recent = tmp_path / f".c.json.{tagged('c.json', dead, 'dddd0000')}.tmp.json"
    running = tmp_path / f".c.json.{tagged('c.json', alive, 'eeee0000')}.tmp.json"
    other = tmp_path / f".other.json.{tagged('other.json', dead, 'ffff0000')}.tmp.json"
    old_copy = tmp_path / f".out.old-{tagged('out', dead, '01234567')}"
    for p in (stale_file, recent, running, other):
        p.write_text("partial")
    for d in (stale_dir, old_copy):
        d.mkdir()
        (d / "x.json").write_text("{}")
    for p in (stale_file, stale_dir, running, other, old_copy):
        _age(p, STALE_AFTER_S + 60)
    write_json(tmp_path / "c.json", {"a": 1})
    assert not stale_file.exists()
    assert recent.exists() and running.exists() and other.exists()  # young, alive, or another name
    with atomic_directory(tmp_path / "out") as tmp:
        (tmp / "r.json").write_text("{}")
    assert not stale_dir.exists()
    assert old_copy.exists()  # out/ did not exist when the write began: it may be the only copy
    with atomic_directory(tmp_path / "out", force=True) as tmp:
        (tmp / "r.json").write_text("{}")
    assert not old_copy.exists()


# ------------------------------------------------------------------ classifier cache
@pytest.fixture(scope="module")
def machine():
    from hlaid.svm import KernelSVC
    rng = np.random.default_rng(0)
    X = rng.normal(size=(30, 2))
    return KernelSVC().fit(X, (X[:, 0] > 0).astype(int))


def test_cache_round_trip(tmp_path, machine, capsys):
    c = MachineCache(tmp_path)
    c.store("k1", {"a": machine, "b": None}, {"stats": {"a": {"acc": 0.75}}})
    machines, meta = c.load("k1")
    assert machines["b"] is None and machines["a"].predict([[1.0, 0.0]]).tolist() == [1]
    assert meta["stats"] == {"a": {"acc": 0.75}} and "integrity" not in meta
    assert c.load("absent") is None
    assert capsys.readouterr().err == ""  # a plain miss is silent


def _damage_svm(d: Path) -> None:
    p = d / "a.svm"
    raw = bytearray(p.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    p.write_bytes(bytes(raw))


def _swap_meta(d: Path) -> None:
    shutil.copy(d.parent / "k2" / "meta.json", d / "meta.json")


def _swap_svm(d: Path) -> None:
    shutil.copy(d.parent / "k2" / "a.svm", d / "a.svm")


def _edit_meta(d: Path) -> None:
    meta = json.loads((d / "meta.json").read_text())
    meta["stats"] = {"a": {"acc": 1.0}}
    (d / "meta.json").write_text(json.dumps(meta))


def _strip_integrity(d: Path) -> None:
    meta = json.loads((d / "meta.json").read_text())
    del meta["integrity"]
    (d / "meta.json").write_text(json.dumps(meta))


@pytest.mark.parametrize("damage, why", [
    (_damage_svm, "a.svm does not match its checksum"),
    (lambda d: (d / "a.svm").unlink(), "a.svm is missing or unreadable"),
    (_swap_meta, "it holds the entry of key 'k2'"),
    (_swap_svm, "a.svm does not match its checksum"),
    (_edit_meta, "meta.json does not match its checksum"),
    (lambda d: (d / "meta.json").write_text('{"machines": ['), "meta.json is unreadable"),
    (_strip_integrity, "no checksums"),
])
def test_cache_entry_failing_its_check_is_reported_and_retrained(tmp_path, machine, capsys, damage, why):
    from hlaid.svm import KernelSVC
    c = MachineCache(tmp_path)
    other = KernelSVC(C=10.0).fit(np.array([[0.0, 0], [1, 1], [0, 1], [1, 0]]), [0, 1, 0, 1])
    c.store("k1", {"a": machine}, {"stats": {}})
    c.store("k2", {"a": other}, {"stats": {"x": 1}})
    damage(tmp_path / "k1")
    with pytest.warns(HlaidWarning) as seen:
        assert c.load("k1") is None
    err = [str(w.message) for w in seen]
    assert len(err) == 1 and why in err[0], err
    assert err[0].startswith("classifier cache entry k1 failed its integrity check (")
    assert err[0].endswith("; retraining")
    assert capsys.readouterr().err == ""  # the library prints nothing itself
    c.store("k1", {"a": machine}, {"stats": {}})  # the retrained machines replace the entry
    assert c.load("k1") is not None


@pytest.mark.parametrize("block, message", [
    ({"training": {"samples": 100_000_000}}, "HLAID_MAX_TRAINING"),
    ({"training": {"crossover_hz": 1000.0}}, "crossover_hz"),
    ({"svm": {"n_bags": 10_000}}, "n_bags"),
    ({"refine": {"restart_ratio": 0.0}}, "restart_ratio"),
    ({"refine": {"restart_ratio": 1e400}}, "restart_ratio"),
    ({"refine": {"method": "tangent"}}, "'eiv', 'least_squares', 'none'"),
    ({"refine": {"method": "__import__('os').system('x')"}}, "refine.method"),
    ({"refine": {"tangent_max_mb": 1e400}}, "tangent_max_mb"),
    ({"refine": {"tangent_max_mb": float("nan")}}, "tangent_max_mb"),
    ({"refine": {"tangent_max_mb": 0.0}}, "tangent_max_mb"),
])
def test_identify_training_sizes_are_bounded(block, message):
    """Path-driven training allocates samples x time per story: its sizes are checked on load."""
    from hlaid.config import config_from_dict
    from hlaid.errors import InputError
    from hlaid.identify import IdentifyConfig

    with pytest.raises(InputError, match=message):
        config_from_dict(IdentifyConfig, block)
