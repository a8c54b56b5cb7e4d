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
``HLAID_MAX_CONFIG_NODES`` 20000       keys and values of one YAML config (a config of 200 000
                                       keys is refused in a fraction of a second)
``HLAID_MAX_INVENTORY``    10000       component rows of a loss inventory CSV
=========================  ==========  =========================================================

A value over its limit is an :class:`~hlaid.errors.InputError` (one line naming the value,
the limit and the variable; exit status 2 on the command line). Only regular files are read:
a device, a FIFO or a socket is refused before any byte is read.
"""

from __future__ import annotations

import os

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
    "CONFIG_NODES": 20_000,
    "INVENTORY": 10_000,
}
"""Default limits by name; ``HLAID_MAX_<NAME>`` overrides each."""

RANGES: dict[str, tuple[float, float]] = {
    "FILE_MB": (1e-4, 2**20),
    "SAMPLES": (16, 1e10),
    "RATE_HZ": (5, 1e8),
    "STORIES": (1, 10_000),
    "IDA_LEVELS": (2, 1e6),
    "IDA_RECORDS": (1, 1e6),
    "BOOTSTRAP": (1, 1e8),
    "TRAINING": (20, 1e7),
    "TANGENT_MB": (1, 2**20),
    "CONFIG_NODES": (100, 1e8),
    "INVENTORY": (1, 1e8),
}
"""What each ``HLAID_MAX_<NAME>`` may be set to, ``(lowest, highest)``: a limit, however raised, stays finite."""

PREFIX = "HLAID_MAX_"


def limit(name: str) -> float:
    """The limit ``name`` (a key of :data:`DEFAULTS`): ``HLAID_MAX_<NAME>`` when set, else the default.
    A value that is no number or lies outside :data:`RANGES` is an :class:`InputError` naming the variable."""
    var = f"{PREFIX}{name}"
    text = os.environ.get(var, "").strip()
    if not text:
        return DEFAULTS[name]
    try:
        value = float(text) if len(text) < 400 else float("nan")
    except ValueError:
        value = float("nan")
    lo, hi = RANGES[name]
    if not lo <= value <= hi:  # NaN too
        shown = repr(text) if len(text) <= 40 and text.isprintable() else f"a value of {len(text)} characters"
        raise InputError(f"environment variable {var} = {shown}; expected a number with "
                         f"{_show(lo)} <= {var} <= {_show(hi)}")
    return value


def check_environment() -> list[str]:
    """Check every ``HLAID_MAX_*`` variable that is set (an :class:`InputError` naming the first bad
    one); returns the names of set variables that are no limit (typos such as ``HLAID_MAX_SAMPLE``)."""
    for name in DEFAULTS:
        limit(name)
    return sorted(k for k in os.environ if k.startswith(PREFIX) and k[len(PREFIX):] not in DEFAULTS)


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


__all__ = ["DEFAULTS", "RANGES", "limit", "check_environment", "check_count", "max_file_bytes", "file_limit_text"]
