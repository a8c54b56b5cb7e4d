"""Writing outputs atomically, and what an output may replace (inputs are read by :mod:`hlaid._inputs`).

Every output is built under a temporary name next to its destination and renamed into place when
complete, so a reader sees the old result or the whole new one and a failure (a full disk, Ctrl-C,
SIGTERM) leaves nothing behind. An output folder carries a marker (:data:`MARKER`) naming the hlaid
command that wrote it: ``--force`` replaces only such a folder or an empty one, and never one that
holds an input of the same run or the current folder; an output file is never an input of its run.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from . import _progress
from ._inputs import read_json, read_text
from ._version import __version__
from .errors import InputError

read_file_text = read_text
"""The old name of :func:`hlaid._inputs.read_text`."""

MARKER = ".hlaid-output.json"
"""The file that makes a folder an output of hlaid (``--force`` may replace it)."""

command = "hlaid"
"""The command writing outputs now (set by the command line, e.g. ``"hlaid hla"``), named in :data:`MARKER`."""

NO_SPACE = (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
"""``errno`` values of a full disk or an exhausted quota."""


def no_space_error(err: BaseException, path: str | os.PathLike, folder: str | os.PathLike) -> InputError | None:
    """An :class:`InputError` saying the disk is full (or the quota exhausted) when ``err``, raised
    while writing the output ``path`` in ``folder``, is such an error, else None."""
    if isinstance(err, NoSpaceError):  # of a file inside the folder being built: said of the folder
        what = err.what
    elif isinstance(err, OSError) and err.errno in NO_SPACE:
        what = "no space left on the device" if err.errno == errno.ENOSPC else "disk quota exceeded"
    elif not isinstance(err, (OSError, InputError)) and isinstance(err, Exception) and _disk_full(folder):
        what = "no space left on the device"  # a library that wraps the OSError (torch.save: RuntimeError)
    else:
        return None
    return NoSpaceError(what, path)


class NoSpaceError(InputError):
    """The disk filled up (or the quota ran out) while an output was written; nothing was left."""

    def __init__(self, what: str, path: str | os.PathLike):
        self.what = what
        super().__init__(f"{what} while writing it; nothing was written (free some space or choose another "
                         "folder)", source=str(path))


def _disk_full(folder: str | os.PathLike) -> bool:
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return False
    return st.f_bavail * st.f_frsize < 64 * 1024


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


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def check_name(path: Path) -> None:
    """Refuse an output name longer than the file system allows (before the work, not after it)."""
    parent = path.parent if str(path.parent) else Path(".")
    top = _name_max(parent if parent.is_dir() else Path("."))
    size = len(os.fsencode(path.name))
    if size > top:
        raise InputError(f"the name is {size} bytes long; the file system allows at most {top}", source=str(path))


def _stem(name: str) -> str:
    """``name`` in the temporary names of its output: shortened (with a hash, so different names stay
    different) when ``.NAME.PID-XXXXXXXX.tmp.SUFFIX`` would exceed the file system's limit."""
    raw = os.fsencode(name)
    if len(raw) <= 200:
        return name
    digest = hashlib.sha1(raw).hexdigest()[:10]
    return os.fsdecode(raw[:180]) + "~" + digest


def _real(p: str | os.PathLike) -> str:
    return os.path.realpath(os.path.abspath(p))


def _inside(child: str, folder: str) -> bool:
    return child == folder or child.startswith(folder.rstrip(os.sep) + os.sep)


def _input_paths(inputs: Iterable[str | os.PathLike | None]) -> list[str]:
    return [str(p) for p in inputs if p and not str(p).startswith("builtin")]


def check_output_file(path: str | os.PathLike, *, force: bool = False,
                      inputs: Iterable[str | os.PathLike | None] = ()) -> Path:
    """Refuse an output file that :func:`atomic_write` would refuse (an existing file without
    ``force``, a folder in its place, a missing or unwritable folder, a name too long), or that is
    one of the run's ``inputs`` (even with ``force``), so a long job fails before it runs."""
    path = Path(path)
    check_name(path)
    if path.is_dir():
        raise InputError("is a folder; expected an output file name", source=str(path))
    if os.path.lexists(path):
        real = _real(path)
        for p in _input_paths(inputs):
            if _real(p) == real or (os.path.exists(p) and os.path.samefile(p, path)):
                raise InputError(f"is an input of this run ({p}); write the output to another file "
                                 "(--force never replaces an input)", source=str(path))
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
    pat = re.compile(re.escape(f".{_stem(name)}.") + r"(?:(\d+)-\w+\.tmp.*|old-(\d+))\Z", re.S)
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
        fd, name = tempfile.mkstemp(prefix=f".{_stem(path.name)}.{os.getpid()}-", suffix=".tmp" + path.suffix[:16],
                                    dir=parent)
        os.close(fd)
        tmp = Path(name)
        write(tmp)
        os.chmod(tmp, _creation_mode())
        os.replace(tmp, path)
    except BaseException as err:  # Ctrl-C too: nothing is left behind
        full = no_space_error(err, path, parent)
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        if full is not None:
            raise full from None
        raise
    return path


def json_text(obj) -> str:
    """``obj`` as the indented JSON text hlaid writes (numpy values as numbers, paths as text)."""
    return json.dumps(obj, indent=2, default=json_default) + "\n"


def write_json(path, obj, *, force: bool = True) -> Path:
    """Atomically write ``obj`` as indented JSON."""
    return atomic_write(path, lambda tmp: tmp.write_text(json_text(obj)), force=force)


@contextlib.contextmanager
def atomic_files() -> Iterator[Callable[[str | os.PathLike, Callable[[Path], object]], Path]]:
    """Replace several files together: ``stage(path, write)`` writes each through ``write(tmp)``
    under a temporary name beside it; when the block ends without an error every one is renamed
    into place, on an error (Ctrl-C too) none is and the temporary files are removed. The work
    that may fail goes inside the block, so a failure leaves every file as it was."""
    staged: list[tuple[Path, Path]] = []

    def stage(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
        path = check_output_file(path, force=True)
        parent = path.parent if str(path.parent) else Path(".")
        fd, name = tempfile.mkstemp(prefix=f".{_stem(path.name)}.{os.getpid()}-", suffix=".tmp", dir=parent)
        os.close(fd)
        staged.append((Path(name), path))
        try:
            write(Path(name))
            os.chmod(name, _creation_mode())
        except BaseException as err:
            full = no_space_error(err, path, parent)
            if full is not None:
                raise full from None
            raise
        return path

    try:
        yield stage
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    for tmp, path in staged:
        os.replace(tmp, path)


def write_npz(path, arrays: dict, *, force: bool = True) -> Path:
    """Atomically write a compressed NPZ."""
    def w(tmp: Path):
        with open(tmp, "wb") as fh:
            import numpy as np
            np.savez_compressed(fh, **arrays)
    return atomic_write(path, w, force=force)


def json_default(o):
    """``json.dumps`` ``default=``: numpy arrays and scalars as lists and numbers, paths as text."""
    import numpy as np  # loaded already by whoever built the arrays
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def is_hlaid_output(folder: str | os.PathLike) -> bool:
    """Whether ``folder`` carries the :data:`MARKER` of an hlaid command (a readable, regular file)."""
    try:
        d = read_json(Path(folder) / MARKER)
    except InputError:
        return False
    return isinstance(d, dict) and d.get("format") == "hlaid-output"


def marker(what: str | None = None) -> dict:
    """The content of :data:`MARKER`: which hlaid command wrote the folder, and when."""
    return {"format": "hlaid-output", "version": 1, "command": what or command, "hlaid_version": __version__,
            "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}


def check_output_folder(path: str | os.PathLike, *, force: bool = False,
                        inputs: Iterable[str | os.PathLike | None] = ()) -> Path:
    """Refuse an output folder that :func:`atomic_directory` would refuse, so a long job fails
    before it runs: a file in its place, a missing or unwritable parent, a name too long; a folder
    that holds one of the run's ``inputs`` or the current folder; a non-empty folder without
    ``force``, or with ``force`` one that is not an hlaid output (no :data:`MARKER`)."""
    path = Path(path)
    check_name(path)
    if path.exists() and not path.is_dir():
        raise InputError("exists and is not a folder", source=str(path))
    if path.is_dir():
        real = _real(path)
        for p in _input_paths(inputs):
            if _inside(_real(p), real):
                raise InputError(f"holds {p}, an input of this run; choose another output folder (--force never "
                                 "replaces an input)", source=str(path))
        if _inside(_real("."), real):
            raise InputError("holds the current folder; choose another output folder", source=str(path))
        if any(path.iterdir()):
            if not force:
                raise InputError("output folder exists and is not empty; use --force to replace it", source=str(path))
            if not is_hlaid_output(path):
                raise InputError(f"is not an output folder of hlaid (it has no {MARKER}): --force replaces only a "
                                 "folder hlaid wrote, or an empty one; move its contents away or choose another "
                                 "folder", source=str(path))
    check_parent(path)
    return path


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike, *, force: bool = False,
                     inputs: Iterable[str | os.PathLike | None] = (), what: str | None = None) -> Iterator[Path]:
    """Build an output folder in a temporary sibling and move it into place on success.

    The folder gets a :data:`MARKER` naming the command that wrote it (``what``, default
    :data:`command`). With ``force`` an existing folder is replaced only when
    :func:`check_output_folder` allows it (an hlaid output holding none of ``inputs``, or an empty
    folder), checked before and again after the work, and only once the new one is complete;
    without it an existing, non-empty folder is an error. On failure the temporary folder is
    removed and the existing folder, if any, is untouched. A symlink in ``path``'s place is
    replaced by the folder; what it pointed to is left alone.
    """
    inputs = list(inputs)
    path = check_output_folder(path, force=force, inputs=inputs)
    parent = path.parent if str(path.parent) else Path(".")
    remove_stale(parent, path.name)
    tmp = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{_stem(path.name)}.{os.getpid()}-", suffix=".tmp", dir=parent))
        yield tmp
        write_json(tmp / MARKER, marker(what))
        os.chmod(tmp, _creation_mode(directory=True))
        check_output_folder(path, force=force, inputs=inputs)  # what is there now may differ from before the work
    except BaseException as err:  # Ctrl-C too: nothing is left behind
        full = no_space_error(err, path, parent)
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        if full is not None:
            raise full from None
        raise
    old = None
    if os.path.lexists(path):
        old = path.with_name(f".{_stem(path.name)}.old-{os.getpid()}")
        os.replace(path, old)
    os.replace(tmp, path)
    if old is not None:
        if old.is_symlink() or not old.is_dir():
            old.unlink(missing_ok=True)
        else:
            shutil.rmtree(old, ignore_errors=True)
