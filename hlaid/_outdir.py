"""What hlaid wrote in an output folder, and replacing a folder that cannot be renamed.

An output folder's marker (:data:`MARKER`, written last) names the command that wrote it, lists
every entry the command wrote there with what it held (size, modification time and SHA-256 of
each file, the target of each link), names the folder it was written in by its device and inode,
and is signed with a key only hlaid keeps (an HMAC-SHA256 under ``~/.local/state/hlaid/output-key``,
readable by its user alone, :func:`signing_key`). ``--force`` replaces a folder only when its
marker bears a valid signature, is that folder's own, lists every entry in it and every file still
holds what hlaid wrote (an entry that is itself such a folder, e.g. ``RUN/loss/``, counts as
hlaid's): a hand-made marker, one copied into another folder or written by an older hlaid, a file
the user put into the folder or a file the user changed stops it (:func:`not_ours` says why).

A folder that cannot be renamed (a mount point, a bind-mounted folder of a container) is replaced
in place instead (:func:`replace_contents`): what hlaid wrote there is removed and the new entries
are moved in, one by one. What killed runs left (``.NAME.PID-TOKEN.tmp``, named by
:func:`hlaid._outkey.temp_name`) is removed by the next write (:func:`remove_stale`): only names
whose token hlaid tagged, never a user's file that merely looks like one.

Every file is compared by its SHA-256 and its permissions, always (never skipped on size and
modification time): a same-size edit with its time put back, or a file made read-only, is the
user's. A file that hlaid rewrites inside one of its output folders (``hlaid loss RUN`` and
``hlaid report RUN`` rewrite ``summary.json`` and ``report.html``) is rewritten only while the
whole folder still holds what hlaid wrote (:func:`check_rewrite`).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import shutil
import stat
import time
from pathlib import Path

from . import _outkey, _progress
from ._inputs import own_files, read_json
from ._outkey import signing_key
from ._version import __version__
from .errors import InputError

MARKER = ".hlaid-output.json"
"""The file that makes a folder an output of hlaid (``--force`` may replace it)."""

VERSION = 4
"""Version of :data:`MARKER`'s content (1: no list of files, no folder identity; 2: no contents,
no signature; 3: no permissions, contents compared by size and time first)."""

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
"""A temporary output of hlaid's (:func:`hlaid._outkey.temp_name`) older than this whose process is
gone was left by a killed run; the next write of its output removes it."""


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

    That is a temporary file or folder and, when ``NAME`` itself exists, a replaced folder kept
    aside, each only when hlaid named it (its token's tag is valid, :func:`hlaid._outkey.made_here`),
    it is older than :data:`STALE_AFTER_S` and its process is no longer running.
    """
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return []
    removed = []
    now = time.time()
    base = stem(name)
    for e in entries:
        if not e.name.startswith(f".{base}."):
            continue
        made = _outkey.made_here(e.name, base)
        if made is None or (made[1] and not (parent / name).exists()):  # an old- folder may be the only copy
            continue
        try:
            young = now - e.stat(follow_symlinks=False).st_mtime < STALE_AFTER_S
            if young or _pid_alive(made[0]):
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


def live(name: str) -> bool:
    """Whether ``name`` is a temporary output of this process (being written now)."""
    made = _outkey.made_here(name, own=True)
    return made is not None and made[0] == os.getpid()


def make_temp(parent: Path, name: str, *, directory: bool = False, suffix: str = ".tmp") -> Path:
    """Create a private temporary file (or folder) for the output ``parent/name``, under a name of
    :func:`hlaid._outkey.temp_name`; returns its path."""
    for _ in range(100):
        p = parent / _outkey.temp_name(stem(name), suffix=suffix)
        try:
            if directory:
                os.mkdir(p, 0o700)
            else:
                os.close(os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o600))
        except FileExistsError:
            continue
        return p
    raise FileExistsError(f"no free temporary name in {parent}")


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


def _sign(body: dict, key: bytes) -> str:
    return _outkey.sign(body, key)


def _sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def content(path: str | os.PathLike) -> dict | None:
    """What ``path`` holds now, as :data:`MARKER` records it: ``{"size", "mtime_ns", "sha256", "mode"}``
    of a regular file, ``{"link": target}`` of a symbolic link, ``{"folder": true, "mode"}`` of a
    folder (``mode``: its permission bits); None for anything else or what cannot be read."""
    try:
        st = os.lstat(path)
        if stat.S_ISLNK(st.st_mode):
            return {"link": os.readlink(os.fspath(path))}
        if stat.S_ISDIR(st.st_mode):
            return {"folder": True, "mode": stat.S_IMODE(st.st_mode)}
        if stat.S_ISREG(st.st_mode):
            return {"size": int(st.st_size), "mtime_ns": int(st.st_mtime_ns), "sha256": _sha256(path),
                    "mode": stat.S_IMODE(st.st_mode)}
    except OSError:
        return None
    return None


def _unchanged(path: str | os.PathLike, rec: object) -> bool:
    """Whether ``path`` still holds what ``rec`` (see :func:`content`) says hlaid wrote: the same kind,
    permissions and, for a file, the same SHA-256 (always computed: a same-size edit with its
    modification time put back is a change)."""
    if not isinstance(rec, dict):
        return False
    try:
        st = os.lstat(path)
    except OSError:
        return False
    if "link" in rec:
        return stat.S_ISLNK(st.st_mode) and os.readlink(os.fspath(path)) == rec["link"]
    if "mode" in rec and stat.S_IMODE(st.st_mode) != rec["mode"]:
        return False
    if rec.get("folder") is True:
        return stat.S_ISDIR(st.st_mode)
    if not stat.S_ISREG(st.st_mode) or st.st_size != rec.get("size"):
        return False
    try:
        return _sha256(path) == rec.get("sha256")
    except OSError:
        return False


def marker(what: str, files: list[str], folder: str | os.PathLike, *, pending: tuple[str, ...] | set[str] = (),
           contents_of: str | os.PathLike | None = None) -> dict:
    """The content of :data:`MARKER` of ``folder`` holding ``files`` (see :func:`listing`),
    written by the command ``what``: what each entry holds (read in ``contents_of``, default
    ``folder``; an entry in ``pending`` is one the command is still writing: listed, not recorded)
    and the signature (None without a :func:`signing_key`)."""
    base = Path(contents_of if contents_of is not None else folder)
    recs = {}
    for f in files:
        if f in pending:
            continue
        rec = content(base / f)
        if rec is not None:
            recs[f] = rec
    body = {"format": "hlaid-output", "version": VERSION, "command": what, "hlaid_version": __version__,
            "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "folder": identity(folder), "files": list(files),
            "contents": recs}
    key = signing_key()
    if key is None:
        body["unsigned"] = _outkey.problem()  # said when written (:func:`warn_unsigned`), and by later refusals
    body["signature"] = _sign(body, key) if key is not None else None
    return body


def warn_unsigned(body: dict, where: str | os.PathLike) -> None:
    """Say, when an output is written, that its marker ``body`` could not be signed."""
    if body.get("signature") is None:
        _progress.warn(f"{where}: its {MARKER} is unsigned ({body.get('unsigned') or _outkey.problem()}); "
                       "--force will not replace this output")


def read_marker(folder: str | os.PathLike) -> dict | None:
    """The :data:`MARKER` of ``folder`` (a readable, regular file of hlaid's format), else None."""
    try:
        with own_files():  # hlaid's own file, no input of the run
            d = read_json(Path(folder) / MARKER)
    except InputError:
        return None
    return d if isinstance(d, dict) and d.get("format") == "hlaid-output" else None


def _signed(d: dict) -> bool:
    sig = d.get("signature")
    if d.get("version") != VERSION or not isinstance(sig, str):
        return False
    key = signing_key(create=False)
    return key is not None and hmac.compare_digest(sig, _sign(d, key))


def written_here(folder: str | os.PathLike) -> set[str] | None:
    """The entries the marker of ``folder`` lists, when the marker is the folder's own (signed by
    hlaid and written in this folder); else None."""
    d = _own_marker(folder)
    return None if d is None else {f for f in d["files"] if isinstance(f, str)}


def _own_marker(folder: str | os.PathLike) -> dict | None:
    d = read_marker(folder)
    if d is None or not isinstance(d.get("files"), list) or not isinstance(d.get("folder"), dict) \
            or not isinstance(d.get("contents"), dict) or not _signed(d):
        return None
    try:
        if d["folder"] != identity(folder):
            return None
    except OSError:
        return None
    return d


def not_ours(folder: str | os.PathLike, skip: tuple[str, ...] = ()) -> str | None:
    """Why ``folder`` is not an output hlaid may replace (None: it is): no marker, a marker that is
    not the folder's own (unsigned, forged, copied), entries the marker does not list, or files
    that no longer hold what hlaid wrote (top-level names in ``skip`` are left out: the temporary
    folder of a run in progress)."""
    d = read_marker(folder)
    if d is None:
        return f"is not an output folder of hlaid (it has no {MARKER})"
    own = _own_marker(folder)
    if own is None:
        if d.get("signature") is None and isinstance(d.get("unsigned"), str):
            return (f"is not an output hlaid may replace: its {MARKER} is unsigned (no key could be used when it was "
                    f"written: {d['unsigned'][:200]})")
        why = "made by hand, copied from another folder, edited, or written by an older hlaid"
        if signing_key(create=False) is None:
            why = f"no key to check it with: {_outkey.problem()}"
        return f"is not an output folder of hlaid: its {MARKER} was not written there by hlaid ({why})"
    files = {f for f in own["files"] if isinstance(f, str)}
    foreign = _foreign(Path(folder), files, own["contents"], skip)
    if foreign:
        shown = ", ".join(foreign[:SHOWN]) + (f" and {len(foreign) - SHOWN} more" if len(foreign) > SHOWN else "")
        return (f"holds {len(foreign)} entr{'y' if len(foreign) == 1 else 'ies'} hlaid did not write there or that "
                f"changed since ({shown})")
    return None


def _foreign(root: Path, files: set[str], recs: dict, skip: tuple[str, ...]) -> list[str]:
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
            if rel == Path(".") and (e.name in skip or e.name == MARKER) or live(e.name):
                continue
            is_dir = e.is_dir(follow_symlinks=False)
            if name in files:
                if name in recs and not _unchanged(e.path, recs[name]):
                    if not (is_dir and not_ours(e.path) is None):
                        out.append(name + ("/" if is_dir else "") + " (changed)")
                elif is_dir:
                    stack.append(rel / e.name)
            elif not (is_dir and not_ours(e.path) is None):  # a folder hlaid wrote later (RUN/loss/) is hlaid's
                out.append(name + ("/" if is_dir else ""))
    return out


def rerecord(path: str | os.PathLike, levels: int = 4) -> None:
    """After hlaid rewrote the file ``path`` inside one of its output folders (``hlaid report`` and
    ``hlaid loss`` rewrite a run folder's ``report.html`` and ``summary.json``): record its new
    contents in that folder's marker, re-signed, so the folder stays hlaid's. Nothing where no
    folder up to ``levels`` above holds a valid marker that records ``path``."""
    path = Path(path)
    if path.name == MARKER:
        return
    folder = path.parent
    for _ in range(levels):
        try:
            rel = path.relative_to(folder).as_posix()
        except ValueError:
            return
        if os.path.lexists(folder / MARKER):
            d = _own_marker(folder)
            if d is None or rel not in d["contents"]:
                return
            key = signing_key(create=False)
            rec = content(path)
            if key is None or rec is None:
                return
            d["contents"][rel] = rec
            d["signature"] = _sign(d, key)
            _write_marker(folder, d)
            return
        if folder.parent == folder:
            return
        folder = folder.parent


def _write_marker(folder: Path, body: dict) -> None:
    """Replace ``folder``'s :data:`MARKER` by ``body`` atomically (a temporary file renamed over it)."""
    name = make_temp(folder, MARKER)
    try:
        with open(name, "w") as fh:
            fh.write(json.dumps(body, indent=2) + "\n")
        mode = os.stat(folder / MARKER).st_mode & 0o777 if os.path.exists(folder / MARKER) else 0o644
        os.chmod(name, mode)
        os.replace(name, folder / MARKER)
    except BaseException:
        name.unlink(missing_ok=True)
        raise


def check_rewrite(path: str | os.PathLike, levels: int = 4) -> None:
    """Refuse to rewrite the existing file ``path`` inside an output folder of hlaid (a folder up to
    ``levels`` above with a :data:`MARKER` listing it) unless that folder still holds only what hlaid
    wrote (:func:`not_ours`): the user's edit to one of its files, a file added or made read-only
    makes the folder the user's, and nothing in it is touched."""
    path = Path(os.path.abspath(path))
    if not os.path.lexists(path) or path.name == MARKER:
        return
    folder = path.parent
    for _ in range(levels):
        rel = os.path.relpath(path, folder).replace(os.sep, "/")
        if os.path.lexists(folder / MARKER):
            d = read_marker(folder)
            if d is None or rel not in (d.get("files") or []):
                return
            why = not_ours(folder)
            if why is not None:
                raise InputError(f"{why}: hlaid rewrites a file of its output folder only while the folder holds what "
                                 f"hlaid wrote; nothing was changed (copy the folder and work on the copy, or "
                                 "move your changes out)", source=str(folder))
            return
        if folder.parent == folder:
            return
        folder = folder.parent


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


__all__ = ["MARKER", "VERSION", "STALE_AFTER_S", "stem", "remove_stale", "live", "make_temp", "identity", "listing",
           "marker", "warn_unsigned", "signing_key", "content", "rerecord", "check_rewrite",
           "read_marker", "written_here", "not_ours", "cannot_rename", "replace_contents"]
