"""Messages of the library: ``logging.getLogger("hlaid")`` and :mod:`warnings`.

The library logs progress lines at INFO and details at DEBUG, and warns (:class:`hlaid.errors.HlaidWarning`)
about legal but suspicious input; it prints nothing itself. An application chooses what is shown:
the command line calls :func:`set_verbosity` (``-q``/``-v``) and :func:`cli_warnings`, which put
every message on stderr as one plain line (warnings as ``warning: ...``).
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
import warnings
from collections.abc import Iterable, Iterator, Sized
from typing import TypeVar

from . import _interrupt
from .errors import HlaidWarning, escape_controls

T = TypeVar("T")

LOGGER = logging.getLogger("hlaid")
"""The package's logger; modules log through it (progress at INFO, details at DEBUG)."""

LEVELS = {0: logging.WARNING, 1: logging.INFO, 2: logging.DEBUG}
"""Verbosity (0 quiet, 1 normal, 2 verbose) -> logging level."""


class _Escaping(logging.Formatter):
    """The message alone as one line, control characters (newlines too) escaped: a file name quoted
    in a progress line or a warning can neither drive the terminal nor start a line of its own
    (``-o $'out\\nhlaid hla: error: ...'`` must not print a fake error). A message of several lines
    is logged line by line."""

    def format(self, record: logging.LogRecord) -> str:
        return escape_controls(super().format(record))


class _StderrHandler(logging.StreamHandler):
    """Plain message lines on the *current* ``sys.stderr`` (which tests and pipes may replace)."""

    def __init__(self) -> None:
        super().__init__()
        self.setFormatter(_Escaping("%(message)s"))

    def emit(self, record: logging.LogRecord) -> None:
        end_line()
        super().emit(record)

    @property  # type: ignore[override]
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


def set_verbosity(level: int) -> None:
    """Show the package's messages on stderr: 0 warnings only, 1 progress, 2 details.

    For applications (the command line, scripts); installs one plain stderr handler on the
    ``hlaid`` logger (messages do not propagate to the root logger then).
    """
    if not any(isinstance(h, _StderrHandler) for h in LOGGER.handlers):
        LOGGER.addHandler(_StderrHandler())
    LOGGER.setLevel(LEVELS[max(0, min(2, int(level)))])
    LOGGER.propagate = False


def verbosity() -> int:
    """The current verbosity (0, 1, 2) of the ``hlaid`` logger."""
    level = LOGGER.getEffectiveLevel()
    return 2 if level <= logging.DEBUG else 1 if level <= logging.INFO else 0


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    LOGGER.warning(f"warning: {message}")


@contextlib.contextmanager
def cli_warnings() -> Iterator[None]:
    """Within the block, each :class:`HlaidWarning` is shown as one ``warning: ...`` line (every
    time, through the logger); other warnings keep Python's defaults."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", HlaidWarning)
        default = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, HlaidWarning):
                _show_warning(message, category, filename, lineno)
            else:
                default(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


def info(msg: str) -> None:
    """A progress message (INFO); also where a dropped Ctrl-C is raised again (:mod:`hlaid._interrupt`)."""
    _interrupt.check()
    LOGGER.info(msg)


def debug(msg: str) -> None:
    """A detail (DEBUG)."""
    _interrupt.check()
    LOGGER.debug(msg)


def warn(msg: str, *, stacklevel: int = 2) -> None:
    """Warn about legal but suspicious input (:class:`HlaidWarning`, attributed to the caller)."""
    warnings.warn(msg, HlaidWarning, stacklevel=stacklevel + 1)


def progress(items: Iterable[T], total: int | None = None, desc: str = "") -> Iterator[T]:
    """Iterate with a one-line progress bar on stderr (when progress is logged and stderr is a
    terminal; when details are logged to a file or pipe, only the closing ``done in`` line, so no
    line is left unfinished there for another message to run into)."""
    total = total if total is not None else (len(items) if isinstance(items, Sized) else None)
    level = verbosity()
    tty = sys.stderr.isatty()
    show = LOGGER.hasHandlers() and level >= 1 and (tty or level >= 2)
    t0 = time.perf_counter()
    for i, item in enumerate(items):
        _interrupt.check()
        yield item
        if show and total and tty:
            done = i + 1
            frac = done / total
            eta = (time.perf_counter() - t0) / done * (total - done)
            bar = "#" * int(24 * frac)
            print(f"\r{desc} [{bar:<24}] {done}/{total} eta {eta:5.1f}s", end="", file=sys.stderr, flush=True)
            _bar.open = True
    if show and total:
        print(f"\r{desc} done in {time.perf_counter() - t0:.1f} s" + " " * 30, file=sys.stderr, flush=True)
        _bar.open = False


class _Bar:
    open = False
    """Whether a progress bar line on stderr awaits its end of line."""


_bar = _Bar()


def end_line() -> None:
    """End a progress bar line left open (by an interruption or an error), so that the next
    message starts a line of its own."""
    if _bar.open:
        _bar.open = False
        print(file=sys.stderr, flush=True)
