"""What hlaid wrote in an output folder, and replacing a folder that cannot be renamed.

An output folder's marker (:data:`MARKER`, written last) names the command that wrote it, lists
every entry the command wrote there, and names the folder it was written in by its device and
inode. ``--force`` replaces a folder only when its marker is that folder's own and lists every
entry in it (an entry that is itself such a folder, e.g. ``RUN/loss/``, counts as hlaid's): a
hand-made marker, one copied into another folder or written by an hlaid that kept no list, or a
file the user put into the folder, stops it (:func:`not_ours` says why).

A folder that cannot be renamed (a mount point, a bind-mounted folder of a container) is replaced
in place instead (:func:`replace_contents`): what hlaid wrote there is removed and the new entries
are moved in, one by one. What killed runs left (``.NAME.PID-*.tmp``) is removed by the next write
(:func:`remove_stale`).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import stat
import time
from pathlib import Path

from . import _progress
from ._inputs import own_files, read_json
from ._version import __version__
from .errors import InputError

MARKER = ".hlaid-output.json"
"""The file that makes a folder an output of hlaid (``--force`` may replace it)."""

VERSION = 2
"""Version of :data:`MARKER`'s content (1: no list of files, no folder identity)."""

SHOWN = 3
"""Entries named in a refusal (the rest are counted)."""


def stem(name: str) -> str:
    """``name`` in the temporary names of its output: shortened (with a hash, so different names stay
    different) when ``.NAME.PID-XXXXXXXX.tmp.SUFFIX`` would exceed the file system's limit."""
    raw = os.fsencode(name)
    if len(raw) <= 200:
        return name
    digest = hashlib.sha1(raw).hexdigest()[:10]
    return os.fsdecode(raw[:180]) + "~" + digest


STALE_AFTER_S = 3600.0
"""A temporary output (``.NAME.PID-*.tmp``) older than this whose process is gone was left by a
killed run; the next write of ``NAME`` removes it."""


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid() or os.name == "nt":  # os.kill on Windows would terminate the process
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. another user's process
        return True
    return True


def remove_stale(parent: Path, name: str) -> list[str]:
    """Remove what killed runs left while writing ``parent/name``; returns the names removed.

    That is ``.NAME.PID-*.tmp*`` (a temporary file or folder) and, when ``NAME`` itself exists,
    ``.NAME.old-PID`` (a replaced folder), each only when older than :data:`STALE_AFTER_S` and
    its process ``PID`` is no longer running.
    """
    pat = re.compile(re.escape(f".{stem(name)}.") + r"(?:(\d+)-\w+\.tmp.*|old-(\d+))\Z", re.S)
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return []
    removed = []
    now = time.time()
    for e in entries:
        m = pat.match(e.name)
        if not m or (m.group(2) and not (parent / name).exists()):  # an old- folder may be the only copy
            continue
        try:
            young = now - e.stat(follow_symlinks=False).st_mtime < STALE_AFTER_S
            if young or _pid_alive(int(m.group(1) or m.group(2))):
                continue
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(e.path)
            else:
                os.unlink(e.path)
        except OSError:
            continue
        removed.append(e.name)
    if removed:
        _progress.debug(f"removed {len(removed)} stale temporary output(s) in {parent}: {', '.join(removed)}")
    return removed


def identity(folder: str | os.PathLike) -> dict:
    """``{"device": ..., "inode": ...}`` of ``folder`` (kept by a rename, changed by a copy)."""
    st = os.stat(folder)
    return {"device": int(st.st_dev), "inode": int(st.st_ino)}


def listing(folder: str | os.PathLike, skip: tuple[str, ...] = ()) -> list[str]:
    """Every entry under ``folder`` as a relative POSIX path, links not followed, without the
    :data:`MARKER` at its top and the top-level names in ``skip``."""
    root = Path(folder)
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        rel = Path(dirpath).relative_to(root)
        if rel == Path("."):
            dirnames[:] = [d for d in dirnames if d not in skip]
            filenames = [f for f in filenames if f not in skip and f != MARKER]
        out += [(rel / n).as_posix() for n in dirnames + filenames]
    return sorted(out)


def marker(what: str, files: list[str], folder: str | os.PathLike) -> dict:
    """The content of :data:`MARKER` of ``folder`` holding ``files`` (see :func:`listing`),
    written by the command ``what``."""
    return {"format": "hlaid-output", "version": VERSION, "command": what, "hlaid_version": __version__,
            "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "folder": identity(folder), "files": list(files)}


def read_marker(folder: str | os.PathLike) -> dict | None:
    """The :data:`MARKER` of ``folder`` (a readable, regular file of hlaid's format), else None."""
    try:
        with own_files():  # hlaid's own file, no input of the run
            d = read_json(Path(folder) / MARKER)
    except InputError:
        return None
    return d if isinstance(d, dict) and d.get("format") == "hlaid-output" else None


def written_here(folder: str | os.PathLike) -> set[str] | None:
    """The entries the marker of ``folder`` lists, when the marker is the folder's own (written
    there by an hlaid that lists its files); else None."""
    d = read_marker(folder)
    if d is None or not isinstance(d.get("files"), list) or not isinstance(d.get("folder"), dict):
        return None
    try:
        if d["folder"] != identity(folder):
            return None
    except OSError:
        return None
    return {f for f in d["files"] if isinstance(f, str)}


def not_ours(folder: str | os.PathLike, skip: tuple[str, ...] = ()) -> str | None:
    """Why ``folder`` is not an output hlaid may replace (None: it is): no marker, a marker that is
    not the folder's own, or entries the marker does not list (top-level names in ``skip`` are
    left out: the temporary folder of a run in progress)."""
    d = read_marker(folder)
    if d is None:
        return f"is not an output folder of hlaid (it has no {MARKER})"
    files = written_here(folder)
    if files is None:
        return (f"is not an output folder of hlaid: its {MARKER} was not written there by hlaid (made by hand, copied "
                "from another folder, or written by an hlaid that kept no list of its files)")
    foreign = _foreign(Path(folder), files, skip)
    if foreign:
        shown = ", ".join(foreign[:SHOWN]) + (f" and {len(foreign) - SHOWN} more" if len(foreign) > SHOWN else "")
        return f"holds {len(foreign)} entr{'y' if len(foreign) == 1 else 'ies'} hlaid did not write there ({shown})"
    return None


def _foreign(root: Path, files: set[str], skip: tuple[str, ...]) -> list[str]:
    out = []
    stack = [Path(".")]
    while stack:
        rel = stack.pop()
        try:
            entries = sorted(os.scandir(root / rel), key=lambda e: e.name)
        except OSError as err:
            out.append(f"{rel.as_posix()} (unreadable: {err.strerror})")
            continue
        for e in entries:
            name = (rel / e.name).as_posix()
            if rel == Path(".") and (e.name in skip or e.name == MARKER):
                continue
            is_dir = e.is_dir(follow_symlinks=False)
            if name in files:
                if is_dir:
                    stack.append(rel / e.name)
            elif not (is_dir and not_ours(e.path) is None):  # a folder hlaid wrote later (RUN/loss/) is hlaid's
                out.append(name + ("/" if is_dir else ""))
    return out


def cannot_rename(path: Path) -> bool:
    """Whether the existing folder ``path`` cannot be replaced by a rename: a mount point (also a
    bind mount: another device than its parent's)."""
    try:
        if path.is_symlink() or not path.is_dir():
            return False
        if os.path.ismount(path):
            return True
        parent = path.parent if str(path.parent) else Path(".")
        return os.stat(path).st_dev != os.stat(parent).st_dev
    except OSError:
        return False


def replace_contents(path: Path, new: Path) -> None:
    """Replace what hlaid wrote in the folder ``path`` (checked by :func:`not_ours` before) by the
    entries of the folder ``new`` (removed after), in place: its marker first, then the entries
    it lists, then the new entries moved in (renamed on one file system, copied across two). The
    caller writes the new marker last. Anything the old marker did not list stays."""
    files = written_here(path) or set()
    ours, kept = [], set()
    for e in os.scandir(path):
        full = Path(e.path)
        if full == new or e.name == MARKER:
            continue
        if e.name in files or (e.is_dir(follow_symlinks=False) and not_ours(full) is None):
            ours.append(full)
        else:
            kept.add(e.name)
    clash = sorted(kept & {e.name for e in os.scandir(new)})
    if clash:
        raise InputError(f"holds {', '.join(clash[:SHOWN])}, which hlaid did not write there; move it away or "
                         "choose another folder", source=str(path))
    (path / MARKER).unlink(missing_ok=True)
    for full in ours:
        _remove(full)
    for e in sorted(os.scandir(new), key=lambda e: e.name):
        if e.name != MARKER:
            shutil.move(e.path, path / e.name)
    shutil.rmtree(new, ignore_errors=True)


def _remove(p: Path) -> None:
    if stat.S_ISDIR(os.lstat(p).st_mode):
        shutil.rmtree(p)
    else:
        p.unlink()


__all__ = ["MARKER", "VERSION", "STALE_AFTER_S", "stem", "remove_stale", "identity", "listing", "marker",
           "read_marker", "written_here", "not_ours", "cannot_rename", "replace_contents"]
