"""Writing outputs atomically, and what an output may replace (inputs are read by :mod:`hlaid._inputs`).

Every output is built under a temporary name next to its destination and renamed into place when
complete, so a reader sees the old result or the whole new one and a failure (a full disk, Ctrl-C,
SIGTERM) leaves nothing behind. An output folder carries a marker (:data:`MARKER`) naming the hlaid
command that wrote it, the entries it wrote and the folder it wrote them in (:mod:`hlaid._outdir`):
``--force`` replaces only such a folder holding nothing else, or an empty one, and never one that
holds an input of the same run or the current folder; an output file is never an input of its run.
The inputs of the run are those named to the command and every file it has read since
(:func:`hlaid._inputs.run_inputs`: also the files a config names). A folder that cannot be renamed
(a mount point) is replaced in place, entry by entry.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import stat
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from . import _outdir, _outkey
from ._inputs import input_named, read_text, run_inputs
from ._outdir import MARKER, remove_stale
from ._outdir import STALE_AFTER_S as STALE_AFTER_S  # where it was defined before
from ._outdir import stem as _stem
from .errors import InputError

read_file_text = read_text
"""The old name of :func:`hlaid._inputs.read_text`."""

command = "hlaid"
"""The command writing outputs now (set by the command line, e.g. ``"hlaid hla"``), named in :data:`MARKER`."""

NO_SPACE = (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
"""``errno`` values of a full disk or an exhausted quota."""

NO_RENAME = (errno.EBUSY, errno.EXDEV, errno.EPERM, errno.EACCES, errno.ENOTEMPTY, errno.EEXIST, errno.EINVAL)
"""``errno`` values of a rename refused where writing works (a mount point, a bind mount, a
sticky folder): the output is then written in place."""


def no_space_error(err: BaseException, path: str | os.PathLike, folder: str | os.PathLike) -> InputError | None:
    """An :class:`InputError` saying the disk is full (or the quota exhausted) when ``err``, raised
    while writing the output ``path`` in ``folder``, is such an error, else None."""
    if isinstance(err, NoSpaceError):  # of a file inside the folder being built: said of the folder
        what = err.what
    elif isinstance(err, OSError) and err.errno in NO_SPACE:
        what = "no space left on the device" if err.errno == errno.ENOSPC else "disk quota exceeded"
    elif isinstance(err, OSError) and err.errno == errno.EFBIG:
        what = "the file-size limit of this process (ulimit -f) was reached"
    elif isinstance(err, Exception) and not isinstance(err, InputError) and "File too large" in str(err):
        what = "the file-size limit of this process (ulimit -f) was reached"  # wrapped by a library
    elif not isinstance(err, (OSError, InputError)) and isinstance(err, Exception) and _disk_full(folder):
        what = "no space left on the device"  # a library that wraps the OSError (torch.save: RuntimeError)
    else:
        return None
    return NoSpaceError(what, path)


class NoSpaceError(InputError):
    """The disk filled up (or the quota ran out) while an output was written; nothing was left."""

    def __init__(self, what: str, path: str | os.PathLike):
        self.what = what
        advice = "raise the limit" if "ulimit" in what else "free some space or choose another folder"
        super().__init__(f"{what} while writing it; nothing was written ({advice})", source=str(path))


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
    """Refuse a path with a name longer than the file system allows, in any of its components, or
    longer than the system allows a path (before the work, not after it)."""
    folder = path.parent if str(path.parent) else Path(".")
    while not os.path.isdir(folder) and folder != folder.parent:  # isdir: False for a name too long, no error
        folder = folder.parent
    top = _name_max(folder if os.path.isdir(folder) else Path("."))
    for part in path.parts:
        size = len(os.fsencode(part))
        if size > top and part != path.anchor:
            what = "the name" if part == path.name else f"a folder name in it ({size} bytes)"
            raise InputError(f"{what} is {size} bytes long; the file system allows at most {top}"
                             if part == path.name else f"{what} is longer than the file system allows ({top} bytes)",
                             source=_short(path))
    whole = len(os.fsencode(os.path.abspath(path)))
    if whole > 4000:
        raise InputError(f"the path is {whole} bytes long; the system allows at most 4096", source=_short(path))


def _short(path: Path) -> str:
    text = str(path)
    return text if len(text) <= 300 else text[:140] + "..." + text[-140:]


def _real(p: str | os.PathLike) -> str:
    return os.path.realpath(os.path.abspath(p))


def _inside(child: str, folder: str) -> bool:
    return child == folder or child.startswith(folder.rstrip(os.sep) + os.sep)


def _input_paths(inputs: Iterable[str | os.PathLike | None]) -> list[str]:
    return [str(p) for p in inputs if p and not str(p).startswith("builtin")]


def _same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    if _real(a) == _real(b):
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


FS_IOC_GETFLAGS = 0x80086601
"""Linux's ioctl reading a file's attributes (``lsattr``); FS_IMMUTABLE_FL 0x10, FS_APPEND_FL 0x20."""


def _locked(path: str | os.PathLike) -> bool:
    """Whether ``path`` is immutable or append-only (``chattr +i`` / ``+a``): no one, root
    included, may replace or remove it (Linux; False elsewhere or where it cannot be told)."""
    if not hasattr(os, "O_NOFOLLOW"):
        return False
    try:
        import array
        import fcntl
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0))
    except (ImportError, OSError):
        return False
    try:
        buf = array.array("l", [0])
        fcntl.ioctl(fd, FS_IOC_GETFLAGS, buf, True)
        return bool(buf[0] & 0x30)
    except OSError:
        return False
    finally:
        os.close(fd)


def locked_entries(folder: str | os.PathLike, limit: int = 10000) -> list[str]:
    """Entries under ``folder`` (itself included, as ".") that are immutable or append-only, or
    inside such a folder: what a replacement could not remove."""
    out = []
    root = Path(folder)
    for n, (dirpath, dirnames, filenames) in enumerate(os.walk(root)):
        for name in [".", *dirnames, *filenames] if n == 0 else [*dirnames, *filenames]:
            p = Path(dirpath) / name if name != "." else root
            if _locked(p):
                out.append(p.relative_to(root).as_posix())
        if n > limit:
            break
    return out


def _kind(path: Path) -> str | None:
    """What ``path`` is when it is neither a regular file nor a symbolic link (a device, a FIFO, a
    socket), else None."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode) or stat.S_ISDIR(mode):
        return None
    return {stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device", stat.S_IFIFO: "a FIFO (named pipe)",
            stat.S_IFSOCK: "a socket"}.get(stat.S_IFMT(mode), "a special file")


def check_output_file(path: str | os.PathLike, *, force: bool = False,
                      inputs: Iterable[str | os.PathLike | None] = ()) -> Path:
    """Refuse an output file that :func:`atomic_write` would refuse (an existing file or link without
    ``force``, a folder in its place, a missing or unwritable folder, a name too long), or that is
    one of the run's ``inputs`` or a file the run has read (even with ``force``), so a long job
    fails before it runs."""
    path = Path(path)
    check_name(path)
    if path.is_dir():
        raise InputError("is a folder; expected an output file name", source=str(path))
    if os.path.lexists(path):
        read = input_named(path)
        named = [p for p in _input_paths(inputs) if _same_file(p, path)]
        if named or read:
            raise InputError(f"is an input of this run ({named[0] if named else read}); write the output to another "
                             "file (--force never replaces an input)", source=str(path))
        kind = _kind(path)
        if kind is not None:
            raise InputError(f"exists and is {kind}, not a file hlaid could have written; hlaid never replaces one "
                             "(choose another output name)", source=str(path))
        if not force:
            what = "exists as a symbolic link; use --force to replace it" if path.is_symlink() else \
                "already exists; use --force to overwrite"
            raise InputError(what, source=str(path))
        if not path.is_symlink() and _locked(path):
            raise InputError("is immutable or append-only (chattr +i/+a): it cannot be replaced; remove the "
                             "attribute or choose another output name", source=str(path))
        _outdir.check_rewrite(path)  # a file of an output folder of hlaid that the user changed: theirs
    check_parent(path)
    _outdir.signing_key()  # a key file unsafe to use is refused now, not after the work
    return path


def atomic_write(path: str | os.PathLike, write: Callable[[Path], object], *, force: bool = True) -> Path:
    """Write ``path`` through ``write(tmp_path)`` and rename it into place.

    The temporary file lives in the same folder, so the rename is atomic: a reader sees the
    old file or the complete new one, never a partial file; on failure nothing is left.
    """
    path = check_output_file(path, force=force)
    parent = path.parent if str(path.parent) else Path(".")
    remove_stale(parent, path.name)
    tmp, placing = None, False
    try:
        tmp = _outdir.make_temp(parent, path.name, suffix=".tmp" + path.suffix[:16])
        write(tmp)
        os.chmod(tmp, _creation_mode())
        check_output_file(path, force=force)  # a file read by the work since (a record of a folder) stays
        placing = True
        _put(tmp, path)
        _outdir.rerecord(path)  # a file of an hlaid output folder rewritten by hlaid stays hlaid's
    except BaseException as err:  # Ctrl-C too: nothing is left behind
        full = no_space_error(err, path, parent)
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        if full is not None:
            raise full from None
        if placing and isinstance(err, OSError):
            raise InputError(f"cannot be replaced ({err.strerror or err}); nothing was written", source=str(path)) \
                from None
        raise
    return path


def json_text(obj) -> str:
    """``obj`` as the indented JSON text hlaid writes (numpy values as numbers, paths as text)."""
    return json.dumps(obj, indent=2, default=json_default) + "\n"


def _put(tmp: Path, path: Path) -> None:
    """Rename ``tmp`` onto ``path``; where the rename is refused (a bind-mounted file) copy it into
    ``path`` instead."""
    try:
        os.replace(tmp, path)
    except OSError as err:
        if err.errno not in NO_RENAME or path.is_dir() or path.is_symlink() or not path.exists():
            raise
        shutil.copyfile(tmp, path)
        tmp.unlink()


def write_json(path, obj, *, force: bool = True) -> Path:
    """Atomically write ``obj`` as indented JSON."""
    return atomic_write(path, lambda tmp: tmp.write_text(json_text(obj)), force=force)


class Staged:
    """The ``stage`` of :func:`atomic_files`: ``stage(path, write)`` stages a file; ``then(done, undo)``
    registers what to do once every file is in place (``done``) or, should one of them fail,
    to put back what was already changed (``undo``): an output folder placed before the files
    (:func:`atomic_directory`'s ``with_files``)."""

    def __init__(self):
        self.files: list[tuple[Path, Path]] = []
        self.done: list[Callable[[], object]] = []
        self.undo: list[Callable[[], object]] = []

    def __call__(self, path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
        path = check_output_file(path, force=True)
        parent = path.parent if str(path.parent) else Path(".")
        name = _outdir.make_temp(parent, path.name)
        self.files.append((name, path))
        try:
            write(Path(name))
            os.chmod(name, _creation_mode())
        except BaseException as err:
            full = no_space_error(err, path, parent)
            if full is not None:
                raise full from None
            raise
        return path

    def then(self, done: Callable[[], object], undo: Callable[[], object]) -> None:
        self.done.append(done)
        self.undo.append(undo)


@contextlib.contextmanager
def atomic_files() -> Iterator[Staged]:
    """Replace several files together: ``stage(path, write)`` writes each through ``write(tmp)``
    under a temporary name beside it; when the block ends without an error every one is renamed
    into place, on an error (Ctrl-C too) none is and the temporary files are removed. Should a
    rename fail half-way (refused by the file system), the files already replaced are put back
    from copies kept until then, what :meth:`Staged.then` registered is undone, and nothing is
    left behind: all or nothing. The work that may fail goes inside the block."""
    stage = Staged()
    try:
        yield stage
    except BaseException:
        for tmp, _ in stage.files:
            tmp.unlink(missing_ok=True)
        _run(stage.undo)
        raise
    kept: list[tuple[Path, Path | None]] = []  # (path, its old content's copy or None: there was none)
    try:
        for tmp, path in stage.files:
            kept.append((path, _keep(path)))
            _put(tmp, path)
    except BaseException as err:
        for path, old in reversed(kept):
            with contextlib.suppress(OSError):
                if old is None:
                    path.unlink(missing_ok=True)
                    continue
                try:
                    os.replace(old, path)
                except OSError:
                    shutil.copyfile(old, path)
        for tmp, _ in stage.files:
            tmp.unlink(missing_ok=True)
        for _, old in kept:
            if old is not None:
                old.unlink(missing_ok=True)
        _run(stage.undo)
        full = no_space_error(err, kept[-1][0], kept[-1][0].parent) if kept else None
        if full is not None:
            raise full from None
        if isinstance(err, OSError) and kept:
            raise InputError(f"cannot be replaced ({err.strerror or err}); nothing was changed, the outputs written "
                             "with it are as they were", source=str(kept[-1][0])) from None
        raise
    for _, old in kept:
        if old is not None:
            old.unlink(missing_ok=True)
    _run(stage.done)
    for _, path in stage.files:
        _outdir.rerecord(path)


def _run(fns: list[Callable[[], object]]) -> None:
    for fn in reversed(fns):
        with contextlib.suppress(OSError):
            fn()


def _keep(path: Path) -> Path | None:
    """A copy of the existing file ``path`` beside it, or None."""
    if not os.path.lexists(path):
        return None
    parent = path.parent if str(path.parent) else Path(".")
    old = _outdir.make_temp(parent, path.name)
    try:  # a copy, not a hard link: a file whose rename is refused is rewritten in place (its inode)
        if os.path.islink(path):
            old.unlink()
            os.symlink(os.readlink(path), old)
        else:
            shutil.copy2(path, old)
    except BaseException:
        old.unlink(missing_ok=True)
        raise
    return old


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
    """Whether ``folder`` carries a :data:`MARKER` written there by hlaid (not made by hand, copied
    in, or written by an hlaid that kept no list of its files)."""
    return _outdir.written_here(folder) is not None


def marker(what: str | None, folder: str | os.PathLike, *, skip: tuple[str, ...] = ()) -> dict:
    """The content of :data:`MARKER` of ``folder`` as it is now: the command that wrote it
    (``what``, default :data:`command`), every entry in it (but ``skip``) and its identity."""
    return _outdir.marker(what or command, _outdir.listing(folder, skip), folder)


def check_output_folder(path: str | os.PathLike, *, force: bool = False,
                        inputs: Iterable[str | os.PathLike | None] = ()) -> Path:
    """Refuse an output folder that :func:`atomic_directory` would refuse, so a long job fails
    before it runs: a file in its place, a missing or unwritable parent (of a folder that can be
    renamed), a name too long; a folder that holds one of the run's ``inputs``, a file the run has
    read, or the current folder; a non-empty folder without ``force``, or with ``force`` one that
    :func:`hlaid._outdir.not_ours` refuses (no marker of its own, or entries hlaid did not write)."""
    path = Path(path)
    check_name(path)
    if path.exists() and not path.is_dir():
        raise InputError("exists and is not a folder", source=str(path))
    if path.is_symlink() and not path.exists() and not force:
        raise InputError("exists as a symbolic link (to nothing); use --force to replace the link", source=str(path))
    if path.is_dir():
        real = _real(path)
        for p in [*_input_paths(inputs), *run_inputs()]:
            if _inside(_real(p), real):
                raise InputError(f"holds {p}, an input of this run; choose another output folder (--force never "
                                 "replaces an input)", source=str(path))
        if _inside(_real("."), real):
            raise InputError("holds the current folder; choose another output folder", source=str(path))
        skip = tuple(e.name for e in os.scandir(path) if _outdir.live(e.name))  # this run's, inside a mount point
        if any(e.name not in skip for e in os.scandir(path)):
            if not force:
                raise InputError("output folder exists and is not empty; use --force to replace it", source=str(path))
            why = _outdir.not_ours(path, skip)
            if why is not None:
                raise InputError(f"{why}: --force replaces only a folder hlaid wrote, holding only what hlaid wrote "
                                 "there, or an empty one; move its contents away or choose another folder",
                                 source=str(path))
        if force:
            locked = locked_entries(path)
            if locked:
                raise InputError(f"holds {len(locked)} entr{'y' if len(locked) == 1 else 'ies'} that cannot be removed "
                                 f"(immutable or append-only, chattr: {', '.join(locked[:3])}); remove the attribute "
                                 "or choose another folder", source=str(path))
        if _outdir.cannot_rename(path):
            if not os.access(path, os.W_OK | os.X_OK):
                raise InputError("folder is not writable", source=str(path))
            _outdir.signing_key()
            return path
    check_parent(path)
    _outdir.signing_key()  # a key file unsafe to use is refused now, not after the work
    return path


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike, *, force: bool = False,
                     inputs: Iterable[str | os.PathLike | None] = (), what: str | None = None,
                     with_files: Staged | None = None) -> Iterator[Path]:
    """Build an output folder in a temporary sibling and move it into place on success.

    The folder gets a :data:`MARKER` naming the command that wrote it (``what``, default
    :data:`command`), what it wrote and the folder. With ``force`` an existing folder is replaced
    only when :func:`check_output_folder` allows it (an hlaid output holding nothing else and none
    of ``inputs``, or an empty folder), checked before and again after the work, and only once the
    new one is complete; without it an existing, non-empty folder is an error. On failure the
    temporary folder is removed and the existing folder, if any, is untouched. A symlink in
    ``path``'s place is replaced by the folder; what it pointed to is left alone. A folder that
    cannot be renamed (a mount point) is built inside itself and replaced in place, entry by
    entry (:func:`hlaid._outdir.replace_contents`); so is one whose rename fails at the end.

    ``with_files`` (the ``stage`` of an enclosing :func:`atomic_files`): the folder is one of a
    set of outputs replaced together; the folder it replaces is kept aside until the files are in
    place too, and put back should one of them fail (a folder replaced in place is not).
    """
    inputs = list(inputs)
    path = check_output_folder(path, force=force, inputs=inputs)
    parent = path.parent if str(path.parent) else Path(".")
    in_place = _outdir.cannot_rename(path)
    home = path if in_place else parent
    remove_stale(home, path.name)
    tmp, placing = None, False
    try:
        tmp = _outdir.make_temp(home, path.name, directory=True)
        yield tmp
        os.chmod(tmp, _creation_mode(directory=True))
        check_output_folder(path, force=force, inputs=inputs)  # what is there now may differ from before
        placing, files = True, _outdir.listing(tmp)
        body = _outdir.marker(what or command, files, tmp)
        if in_place or not _renamed(tmp, path, body, with_files):
            _outdir.replace_contents(path, tmp)
            write_json(path / MARKER, body := _outdir.marker(what or command, files, path))
        tmp = None
        _outdir.warn_unsigned(body, path)
    except BaseException as err:  # Ctrl-C too: nothing is left behind
        full = no_space_error(err, path, parent)
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        if full is not None:
            raise full from None
        if placing and isinstance(err, OSError):
            raise InputError(f"cannot be put in place ({err.strerror or err})", source=str(path)) from None
        raise


def _renamed(tmp: Path, path: Path, body: dict, with_files: Staged | None = None) -> bool:
    """Put the complete folder ``tmp`` in ``path``'s place by renames, its marker ``body`` written
    first; False (nothing changed, no marker) where a rename is refused: ``path`` is a mount point."""
    write_json(tmp / MARKER, body)
    old = None
    if os.path.lexists(path):
        old = path.with_name(_outkey.temp_name(_stem(path.name), old=True))
        try:
            os.replace(path, old)
        except OSError as err:
            if err.errno not in NO_RENAME or not path.is_dir() or path.is_symlink():
                raise
            (tmp / MARKER).unlink()
            return False
    try:
        os.replace(tmp, path)
    except OSError:
        if old is not None:
            os.replace(old, path)  # the existing folder back where it was
        raise
    def drop(p: Path | None) -> None:
        if p is None:
            return
        if p.is_symlink() or not p.is_dir():
            p.unlink(missing_ok=True)
        else:
            shutil.rmtree(p, ignore_errors=True)

    if with_files is None:
        drop(old)
        return True

    def undo() -> None:  # the new folder out, the old one back
        gone = path.with_name(_outkey.temp_name(_stem(path.name)))
        os.replace(path, gone)
        if old is not None:
            os.replace(old, path)
        drop(gone)
    with_files.then(lambda: drop(old), undo)
    return True
