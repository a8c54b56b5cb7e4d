"""Hostile outputs: folders and files hlaid did not write, special files in an output's place, a
multi-file update whose last step is refused. Every case is exit 2, one line, and the sandbox's
file hashes are unchanged with nothing left behind (see ``tests/test_hostile.py`` for the rest)."""

from __future__ import annotations

import errno
import json
import os
import shutil
import stat
from pathlib import Path

import pytest
from test_hostile import HEIGHTS, _fleet_yaml, loss_run, refused, tree  # noqa: F401 (loss_run: a fixture)
from test_loss import needs_pelicun

from hlaid import _outdir
from hlaid._fileio import MARKER, atomic_directory, is_hlaid_output
from hlaid.clone import Clone

POSIX = pytest.mark.skipif(os.name != "posix", reason="FIFOs and devices of POSIX")


@pytest.fixture()
def clone_file(table1, tmp_path) -> Path:
    return Clone(building=table1.replace(height=HEIGHTS)).save(tmp_path / "clone.json")


def _measurement(tmp_path: Path) -> Path:
    m = tmp_path / "m.npz"
    m.write_bytes(b"a measurement")
    return m


# ----------------------------------------------------------------------------- fleet -o DIR
@pytest.mark.parametrize("content", ['{"format": "hlaid-fleet", "version": 1}', "{}", "", "my notes"])
def test_fleet_never_writes_into_a_folder_holding_a_fleet_json_it_did_not_write(tmp_path, capsys, content):
    """A user's folder with a file called fleet.json (hlaid's format, generic JSON, empty, text) and
    the names a fleet writes: refused, nothing overwritten, nothing deleted; --force changes nothing."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "fleet.json").write_text(content)
    (out / "report.html").write_text("<p>my report</p>")
    (out / "results.csv").write_text("a,b\n1,2\n")
    (out / "results.parquet").write_bytes(b"PAR1 mine")
    fleet = _fleet_yaml(tmp_path)
    for force in ([], ["--force"]):
        refused(capsys, ["fleet", fleet, "-o", out, *force], ["not an hlaid fleet output"], root=tmp_path, within=30)


def test_fleet_refuses_a_symlink_to_nothing_as_its_folder(tmp_path, capsys):
    (tmp_path / "f").symlink_to(tmp_path / "missing")
    refused(capsys, ["fleet", _fleet_yaml(tmp_path), "-o", tmp_path / "f"], ["symbolic link to nothing"],
            root=tmp_path, within=30)


def test_a_fleet_folder_is_recognised_by_its_signed_marker(tmp_path):
    """What a fleet wrote (a marker of "hlaid fleet" listing its files) is resumed; a file of its
    changed by the user is not."""
    from hlaid.errors import InputError
    from hlaid.fleet.engine import mark_output
    from hlaid.fleet.output import check_output
    out = tmp_path / "f"
    (out / "buildings").mkdir(parents=True)
    (out / "fleet.json").write_text("{}")
    (out / "report.html").write_text("<p>hlaid's</p>")
    mark_output(out)
    assert check_output(out, force=False) == out
    (out / "report.html").write_text("<p>hlaid's, with my notes</p>")
    with pytest.raises(InputError, match="report.html \\(changed\\)"):
        check_output(out, force=True)


# ----------------------------------------------------------------------------- special files in an output's place
@POSIX
def test_force_never_replaces_a_fifo_or_a_device(tmp_path, capsys, clone_file):
    """A FIFO or a character device where an output file goes: refused with and without --force,
    and the refusal does not suggest --force."""
    targets = [tmp_path / "pipe.csv"]
    os.mkfifo(targets[0])
    if os.geteuid() == 0:
        targets.append(tmp_path / "null")
        os.mknod(targets[1], stat.S_IFCHR | 0o600, os.makedev(1, 3))
    for t in targets:
        for force in ([], ["--force"]):
            line = refused(capsys, ["export-opensees", clone_file, "-o", t, *force], ["not a file hlaid could"],
                           root=tmp_path, within=30)
            assert "--force to" not in line
            refused(capsys, ["demands", clone_file, "--motion", "builtin:elcentro-1940-ns", "-o", t, *force],
                    ["not a file hlaid could"], root=tmp_path, within=30)
        assert not stat.S_ISREG(t.lstat().st_mode)


# ----------------------------------------------------------------------------- hlaid loss RUN: all or nothing
@needs_pelicun
def test_loss_whose_last_rename_is_refused_changes_nothing(loss_run, tmp_path, capsys, monkeypatch):  # noqa: F811
    """The file system refuses to replace report.html (EPERM, also in place): exit 2, one line, the
    run folder exactly as it was (no loss/, summary.json unchanged) and no temporary file left."""
    run = Path(shutil.copytree(loss_run, tmp_path / "run"))
    (run / "report.html").write_text("<p>the old report</p>")
    real_replace, real_copy = os.replace, shutil.copyfile

    def refuse(dst):
        if Path(dst).name == "report.html" and Path(dst).parent == run:
            raise PermissionError(errno.EPERM, "Operation not permitted", str(dst))

    def replace(src, dst, *a, **k):
        refuse(dst)
        return real_replace(src, dst, *a, **k)

    def copyfile(src, dst, *a, **k):
        refuse(dst)
        return real_copy(src, dst, *a, **k)
    monkeypatch.setattr(os, "replace", replace)
    monkeypatch.setattr(shutil, "copyfile", copyfile)
    refused(capsys, ["loss", run, "--no-curve", "--realizations", "50", "-q"], ["cannot be replaced"],
            root=tmp_path, within=300)


# ----------------------------------------------------------------------------- what a marker proves
def test_a_forged_marker_naming_the_folder_and_its_files_opens_nothing(tmp_path, capsys):
    """A marker made by hand with the folder's own device, inode, entries and their contents (but
    no signature of hlaid's key, or one made with another key) does not let --force in."""
    v = tmp_path / "F"
    (v / "chapters").mkdir(parents=True)
    (v / "chapters" / "ch1.tex").write_text("four years")
    (v / "data.csv").write_text("1,2\n")
    files = ["chapters", "chapters/ch1.tex", "data.csv"]
    body = {"format": "hlaid-output", "version": _outdir.VERSION, "command": "hlaid hla", "hlaid_version": "1",
            "written": "2026-01-01T00:00:00+0000", "folder": _outdir.identity(v), "files": files,
            "contents": {f: _outdir.content(v / f) for f in files}}
    m = _measurement(tmp_path)
    for sig in (None, "0" * 64, _outdir._sign(body, b"0" * 64)):
        (v / MARKER).write_text(json.dumps({**body, "signature": sig}))
        refused(capsys, ["hla", m, "-o", v, "--force"], ["not written there by hlaid"], root=tmp_path, within=30)
    for old in (1, 2):  # an older hlaid's marker (no contents, no signature)
        (v / MARKER).write_text(json.dumps({k: x for k, x in body.items() if k != "contents"} | {"version": old}))
        refused(capsys, ["hla", m, "-o", v, "--force"], ["not written there by hlaid"], root=tmp_path, within=30)
    assert not is_hlaid_output(v)


@pytest.mark.parametrize("edit", ["append", "redraw", "same-size"])
def test_force_keeps_a_file_hlaid_wrote_that_the_user_changed(tmp_path, capsys, edit):
    """Notes appended to hla.json, a redrawn loops.png, a same-size edit: --force refuses, naming it."""
    out = tmp_path / "out"
    with atomic_directory(out, what="hlaid hla") as tmp:
        (tmp / "hla.json").write_text('{"k0": 1}')
        (tmp / "loops.png").write_bytes(b"png of hlaid")
    assert is_hlaid_output(out)
    if edit == "append":
        with open(out / "hla.json", "a") as fh:
            fh.write("\nmy notes")
        name = "hla.json"
    elif edit == "redraw":
        (out / "loops.png").write_bytes(b"my own drawing, longer")
        name = "loops.png"
    else:
        st = (out / "hla.json").stat()
        (out / "hla.json").write_text('{"k0": 2}')
        os.utime(out / "hla.json", ns=(st.st_atime_ns, st.st_mtime_ns + 1))
        name = "hla.json"
    line = refused(capsys, ["hla", _measurement(tmp_path), "-o", out, "--force"], [f"{name} (changed)"],
                   root=tmp_path, within=30)
    assert "1 entry" in line
    # touched but unchanged: still hlaid's
    os.utime(out / "hla.json")
    if edit != "append" and edit != "same-size":
        (out / "loops.png").write_bytes(b"png of hlaid")
        assert _outdir.not_ours(out) is None


def test_the_marker_records_what_each_file_holds(tmp_path):
    out = tmp_path / "out"
    with atomic_directory(out, what="hlaid test") as tmp:
        (tmp / "a.json").write_text("{}")
        (tmp / "sub").mkdir()
        (tmp / "sub" / "link").symlink_to("../a.json")
    mark = json.loads((out / MARKER).read_text())
    assert mark["version"] == _outdir.VERSION == 4 and len(mark["signature"]) == 64
    assert mark["contents"]["a.json"]["size"] == 2
    assert mark["contents"]["a.json"]["sha256"] == "44136fa355b3678a1146ad16f7e8649e94fb4fc21fe77e8310c060f61caaff8a"
    assert mark["contents"]["sub/link"] == {"link": "../a.json"} and mark["contents"]["sub"]["folder"] is True
    mark["command"] = "hlaid edited"  # any edit breaks the signature
    (out / MARKER).write_text(json.dumps(mark))
    assert not is_hlaid_output(out)


def test_without_a_home_markers_are_unsigned_and_open_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("HLAID_STATE_DIR", raising=False)
    monkeypatch.delenv("XDG_STATE_HOME", raising=False)
    monkeypatch.setenv("HOME", "")
    out = tmp_path / "out"
    with atomic_directory(out, what="hlaid test") as tmp:
        (tmp / "a.json").write_text("{}")
    assert json.loads((out / MARKER).read_text())["signature"] is None
    refused(capsys, ["hla", _measurement(tmp_path), "-o", out, "--force"], ["its .hlaid-output.json is unsigned"],
            root=tmp_path, within=30)


def test_a_file_hlaid_rewrites_in_its_own_output_stays_hlaids(tmp_path):
    """``hlaid report`` / ``hlaid loss`` rewrite report.html and summary.json of a run folder: the
    marker records the new contents, so --force may still replace the folder."""
    from hlaid._fileio import atomic_files, write_json
    out = tmp_path / "run"
    with atomic_directory(out, what="hlaid run") as tmp:
        (tmp / "summary.json").write_text("{}")
        (tmp / "report.html").write_text("<p>old</p>")
        (tmp / "figures").mkdir()
        (tmp / "figures" / "a.png").write_bytes(b"png")
    write_json(out / "summary.json", {"loss": 1})
    with atomic_files() as stage:
        stage(out / "report.html", lambda p: p.write_text("<p>new, longer</p>"))
        stage(out / "figures" / "a.png", lambda p: p.write_bytes(b"png redrawn"))
    assert _outdir.not_ours(out) is None
    (out / "report.html").write_text("<p>the user's</p>")
    assert "report.html (changed)" in _outdir.not_ours(out)
