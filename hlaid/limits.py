"""Size limits, checked before hlaid reads or allocates anything large.

A typo such as ``rate_hz: 1e6``, a path to an endless device, or ``n_levels: 100000000``
would otherwise end in a ``MemoryError`` or a run of hours. Every limit is far above real
use and can be raised (or lowered) with an environment variable:

=========================  ==========  =========================================================
variable                   default     what it limits
=========================  ==========  =========================================================
``HLAID_MAX_FILE_MB``      512         size of an input file [MiB] (after gunzip for ``.gz``)
``HLAID_MAX_SAMPLES``      2000000     samples of one record (measured, read or resampled)
``HLAID_MAX_RATE_HZ``      10000       sample rate of a simulated measurement [Hz]
``HLAID_MAX_STORIES``      100         stories of a building (floor channels of a measurement)
``HLAID_MAX_IDA_LEVELS``   1000        IM levels per record: ``n_levels``, ``levels``,
                                       ``max_hunt``, ``max_fill``
``HLAID_MAX_IDA_RECORDS``  1000        ground motion records of one IDA
``HLAID_MAX_BOOTSTRAP``    100000      bootstrap resamples of a fragility interval
``HLAID_MAX_TRAINING``     20000       training samples per story and classifier pass
                                       (``training.samples``)
``HLAID_MAX_TANGENT_MB``   4096        memory of the ground tangent of ``refine.method: eiv``
                                       [MiB] (samples x lags x floors, 4 copies)
=========================  ==========  =========================================================

A value over its limit is an :class:`~hlaid.errors.InputError` (one line naming the value,
the limit and the variable; exit status 2 on the command line). Only regular files are read:
a device, a FIFO or a socket is refused before any byte is read.
"""

from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path

from .errors import InputError

DEFAULTS: dict[str, float] = {
    "FILE_MB": 512,
    "SAMPLES": 2_000_000,
    "RATE_HZ": 10_000,
    "STORIES": 100,
    "IDA_LEVELS": 1000,
    "IDA_RECORDS": 1000,
    "BOOTSTRAP": 100_000,
    "TRAINING": 20_000,
    "TANGENT_MB": 4096,
}
"""Default limits by name; ``HLAID_MAX_<NAME>`` overrides each."""


def limit(name: str) -> float:
    """The limit ``name`` (a key of :data:`DEFAULTS`): ``HLAID_MAX_<NAME>`` when set, else the default."""
    var = f"HLAID_MAX_{name}"
    text = os.environ.get(var, "").strip()
    if not text:
        return DEFAULTS[name]
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise InputError(f"environment variable {var} = {text!r}; expected a positive number")
    return value


def check_count(value: float, name: str, what: str, *, source: str | None = None) -> None:
    """Raise InputError when ``value`` (a count or rate described by ``what``) exceeds limit ``name``."""
    top = limit(name)
    if value > top:
        raise InputError(f"{what} = {_show(value)} exceeds the limit of {_show(top)} "
                         f"(set HLAID_MAX_{name} to raise it)", source=source)


def _show(v: float) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e15 else f"{v:.6g}"


def max_file_bytes() -> int:
    """The largest input file hlaid reads, in bytes."""
    return int(limit("FILE_MB") * 2**20)


def file_limit_text() -> str:
    """``"the limit of 512 MiB (set HLAID_MAX_FILE_MB to raise it)"``, for messages."""
    return f"the limit of {_show(limit('FILE_MB'))} MiB (set HLAID_MAX_FILE_MB to raise it)"


def check_readable_file(path: str | os.PathLike) -> int:
    """Refuse anything but a regular file within the size limit, before reading it; returns its size.

    A missing path or a folder is left to the caller's own message.
    """
    p = Path(path)
    try:
        st = p.stat()
    except OSError:
        return 0
    if stat.S_ISDIR(st.st_mode):
        return 0
    if not stat.S_ISREG(st.st_mode):
        kind = ("a character device" if stat.S_ISCHR(st.st_mode) else "a block device" if stat.S_ISBLK(st.st_mode)
                else "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                else "a special file")
        raise InputError(f"is {kind}; expected a regular file", source=str(p))
    top = max_file_bytes()
    if st.st_size > top:
        raise InputError(f"is {st.st_size / 2**20:.3g} MiB, over {file_limit_text()}", source=str(p))
    return int(st.st_size)


def check_archive(path: str | os.PathLike) -> None:
    """Refuse a zip archive (an NPZ) whose members inflate past ``HLAID_MAX_FILE_MB``, before
    inflating any; an unreadable archive is left to the reader's own message."""
    try:
        with zipfile.ZipFile(path) as zf:
            total = sum(info.file_size for info in zf.infolist())
    except (zipfile.BadZipFile, OSError, ValueError):
        return
    top = max_file_bytes()
    if total > top:
        raise InputError(f"inflates to {total / 2**20:.3g} MiB, over {file_limit_text()}", source=str(path))


__all__ = ["DEFAULTS", "limit", "check_count", "check_readable_file", "check_archive", "max_file_bytes",
           "file_limit_text"]
