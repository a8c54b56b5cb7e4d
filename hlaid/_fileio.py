"""Writing outputs atomically (inputs are read by :mod:`hlaid._inputs`)."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from . import _progress
from ._inputs import read_text
from .errors import InputError

read_file_text = read_text
"""The old name of :func:`hlaid._inputs.read_text`."""


def _creation_mode(directory: bool = False) -> int:
    """Permissions a plain ``open``/``mkdir`` would give (0o666 / 0o777 less the umask).

    ``tempfile`` creates private (0o600 / 0o700) entries; an output renamed into place from
    one would otherwise stay unreadable to everyone else.
    """
    umask = os.umask(0)
    os.umask(umask)
    return (0o777 if directory else 0o666) & ~umask


def check_parent(path: Path) -> Path:
    """The folder ``path`` will be written in; an InputError unless it is an existing, writable folder."""
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.exists():
        raise InputError("folder does not exist; create it first", source=str(parent))
    if not parent.is_dir():
        raise InputError("is not a folder; it cannot hold the output", source=str(parent))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError("folder is not writable", source=str(parent))
    return parent


def check_output_file(path: str | os.PathLike, *, force: bool = False) -> Path:
    """Refuse an output file that :func:`atomic_write` would refuse (an existing file without
    ``force``, a folder in its place, a missing or unwritable folder), so a long job fails before it runs."""
    path = Path(path)
    if path.is_dir():
        raise InputError("is a folder; expected an output file name", source=str(path))
    if path.exists() and not force:
        raise InputError("already exists; use --force to overwrite", source=str(path))
    check_parent(path)
    return path


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
    pat = re.compile(re.escape(f".{name}.") + r"(?:(\d+)-\w+\.tmp.*|old-(\d+))\Z", re.S)
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


def atomic_write(path: str | os.PathLike, write: Callable[[Path], object], *, force: bool = True) -> Path:
    """Write ``path`` through ``write(tmp_path)`` and rename it into place.

    The temporary file lives in the same folder, so the rename is atomic: a reader sees the
    old file or the complete new one, never a partial file; on failure nothing is left.
    """
    path = check_output_file(path, force=force)
    parent = path.parent if str(path.parent) else Path(".")
    remove_stale(parent, path.name)
    tmp = None
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}-", suffix=".tmp" + "".join(path.suffixes),
                                    dir=parent)
        os.close(fd)
        tmp = Path(name)
        write(tmp)
        os.chmod(tmp, _creation_mode())
        os.replace(tmp, path)
    except BaseException:  # Ctrl-C too: nothing is left behind
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    return path


def write_json(path, obj, *, force: bool = True) -> Path:
    """Atomically write ``obj`` as indented JSON."""
    def w(tmp: Path):
        tmp.write_text(json.dumps(obj, indent=2, default=json_default) + "\n")
    return atomic_write(path, w, force=force)


def write_npz(path, arrays: dict, *, force: bool = True) -> Path:
    """Atomically write a compressed NPZ."""
    def w(tmp: Path):
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
    return atomic_write(path, w, force=force)


def json_default(o):
    """``json.dumps`` ``default=``: numpy arrays and scalars as lists and numbers, paths as text."""
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def check_output_folder(path: str | os.PathLike, *, force: bool = False) -> Path:
    """Refuse an output folder that :func:`atomic_directory` would refuse (a file, a non-empty
    folder without ``force``, a missing or unwritable parent), so a long job fails before it runs."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError("exists and is not a folder", source=str(path))
    if path.exists() and any(path.iterdir()) and not force:
        raise InputError("output folder exists and is not empty; use --force to replace it", source=str(path))
    check_parent(path)
    return path


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike, *, force: bool = False) -> Iterator[Path]:
    """Build an output folder in a temporary sibling and move it into place on success.

    With ``force`` an existing folder is replaced only once the new one is complete; without
    it an existing, non-empty folder is an error. On failure the temporary folder is removed
    and the existing folder, if any, is untouched.
    """
    path = check_output_folder(path, force=force)
    parent = path.parent if str(path.parent) else Path(".")
    remove_stale(parent, path.name)
    tmp = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.{os.getpid()}-", suffix=".tmp", dir=parent))
        yield tmp
        os.chmod(tmp, _creation_mode(directory=True))
    except BaseException:  # Ctrl-C too: nothing is left behind
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.old-{os.getpid()}")
        os.replace(path, old)
    os.replace(tmp, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
