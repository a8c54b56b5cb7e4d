"""Reading text files (plain or gzip) and writing outputs atomically."""

from __future__ import annotations

import contextlib
import gzip
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from .errors import InputError


def read_text(path: str | os.PathLike) -> str:
    """Text of a file, transparently gunzipped; a clear error for missing or binary files."""
    p = Path(path)
    if not p.exists():
        raise InputError("file not found", source=str(p))
    if p.is_dir():
        raise InputError("is a folder; expected a file", source=str(p))
    try:
        raw = p.read_bytes()
        if raw[:2] == b"\x1f\x8b":
            raw = gzip.decompress(raw)
    except (OSError, EOFError) as err:
        raise InputError(f"cannot read: {err}", source=str(p)) from None
    if b"\x00" in raw[:4096]:
        raise InputError("is a binary file; expected text", source=str(p))
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _creation_mode(directory: bool = False) -> int:
    """Permissions a plain ``open``/``mkdir`` would give (0o666 / 0o777 less the umask).

    ``tempfile`` creates private (0o600 / 0o700) entries; an output renamed into place from
    one would otherwise stay unreadable to everyone else.
    """
    umask = os.umask(0)
    os.umask(umask)
    return (0o777 if directory else 0o666) & ~umask


def _check_target(path: Path, force: bool) -> None:
    if path.exists() and not force:
        raise InputError("already exists; use --force to overwrite", source=str(path))
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.exists():
        raise InputError("output folder does not exist", source=str(parent))
    if not os.access(parent, os.W_OK):
        raise InputError("output folder is not writable", source=str(parent))


def atomic_write(path: str | os.PathLike, write: Callable[[Path], None], *, force: bool = True) -> Path:
    """Write ``path`` through ``write(tmp_path)`` and rename it into place.

    The temporary file lives in the same folder, so the rename is atomic: a reader sees the
    old file or the complete new one, never a partial file; on failure nothing is left.
    """
    path = Path(path)
    _check_target(path, force)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + "".join(path.suffixes),
                               dir=path.parent if str(path.parent) else ".")
    os.close(fd)
    tmp = Path(tmp)
    try:
        write(tmp)
        os.chmod(tmp, _creation_mode())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_json(path, obj, *, force: bool = True) -> Path:
    """Atomically write ``obj`` as indented JSON."""
    def w(tmp: Path):
        tmp.write_text(json.dumps(obj, indent=2, default=_json_default) + "\n")
    return atomic_write(path, w, force=force)


def write_npz(path, arrays: dict, *, force: bool = True) -> Path:
    """Atomically write a compressed NPZ."""
    def w(tmp: Path):
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
    return atomic_write(path, w, force=force)


def _json_default(o):
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
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.exists():
        raise InputError("parent folder does not exist", source=str(parent))
    if not os.access(parent, os.W_OK):
        raise InputError("output folder is not writable", source=str(parent))
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
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent))
    try:
        yield tmp
        os.chmod(tmp, _creation_mode(directory=True))
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.old-{os.getpid()}")
        os.replace(path, old)
    os.replace(tmp, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
