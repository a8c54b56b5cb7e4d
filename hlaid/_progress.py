"""Messages of the library: ``logging.getLogger("hlaid")`` and :mod:`warnings`.

The library logs progress lines at INFO and details at DEBUG, and warns (:class:`hlaid.errors.HlaidWarning`)
about legal but suspicious input; it prints nothing itself. An application chooses what is shown:
the command line calls :func:`set_verbosity` (``-q``/``-v``) and :func:`cli_warnings`, which put
every message on stderr as one plain line (warnings as ``warning: ...``); a Python user calls
:func:`verbose` (``hlaid.verbose()``).

Long work is a :class:`Stage` (:func:`stage`, :func:`progress`): a progress bar with its counts and
elapsed time while it runs, drawn only on a terminal, and one closing line when it ends (the only
line where stderr is a pipe or a file).
"""

from __future__ import annotations

import contextlib
import logging
import shutil
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
        _bar.clear()  # a bar line in progress is erased, the message printed, the bar drawn again below it
        super().emit(record)
        _bar.draw(force=True)

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


def step(msg: str) -> None:
    """A step of the work: a progress line (INFO) at the top level, a detail (DEBUG) inside a
    :class:`Stage` (whose closing line sums it up), so a command prints one line per stage."""
    (debug if nested() else info)(msg)


def debug(msg: str) -> None:
    """A detail (DEBUG)."""
    _interrupt.check()
    LOGGER.debug(msg)


def warn(msg: str, *, stacklevel: int = 2) -> None:
    """Warn about legal but suspicious input (:class:`HlaidWarning`, attributed to the caller)."""
    warnings.warn(msg, HlaidWarning, stacklevel=stacklevel + 1)


def verbose(level: int = 1) -> None:
    """Show hlaid's progress on stderr from Python (a script, a notebook, the REPL): ``level`` 1
    progress bars (on a terminal) and one line per finished stage, 2 details too, 0 warnings only.

    The library prints nothing unless asked: ``hlaid.verbose()`` is the one call that asks (the same
    messages as the command line's). To route the messages elsewhere, configure
    ``logging.getLogger("hlaid")`` yourself instead (progress at INFO, details at DEBUG)."""
    set_verbosity(level)


def _clock(seconds: float) -> str:
    s = int(seconds)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60:02d}:{s % 60:02d}"


class Stage:
    """One long stage of work, with a count of its steps.

    On a terminal (stderr a tty, hlaid's stderr handler installed by :func:`set_verbosity`, progress
    shown) a bar line ``desc [#####-----] 12/40 evaluations 00:13<00:16 note`` is redrawn in place
    (at most ten times a second); other messages are printed above it. When the stage ends, one
    line ``desc: 40 evaluations in 13.2 s; note`` is logged at INFO: on the terminal it replaces the
    bar, elsewhere (a pipe, a log file) it is the stage's only line. A stage left by an exception
    logs nothing; its bar line is ended where it stopped. Stages nest: the innermost one is drawn,
    and the closing line of a stage inside another is a detail (DEBUG; see :func:`nested`).

    Use as a context manager (:func:`stage`), or through :func:`progress` for a loop.
    """

    def __init__(self, desc: str, total: int | None = None, *, unit: str = "") -> None:
        self.desc, self.total, self.unit = desc, total, unit
        self.n = 0
        self.note = ""
        self.summary: str | None = None
        self.t0 = time.perf_counter()
        self._drawn_at = 0.0

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def __enter__(self) -> Stage:
        _interrupt.check()
        self.t0 = time.perf_counter()
        _bar.stack.append(self)
        _bar.draw(force=True)
        return self

    def update(self, n: int = 1, note: str | None = None) -> None:
        """``n`` more steps done (``note``: a short status shown after the counts)."""
        _interrupt.check()
        self.n += n
        if note is not None:
            self.note = note
        if _bar.stack and _bar.stack[-1] is self:
            _bar.draw()

    def set_note(self, note: str) -> None:
        self.update(0, note)

    def done(self, summary: str) -> None:
        """What the closing line says after the counts and time (default: the last note)."""
        self.summary = summary

    def line(self, width: int) -> str:
        """The bar line, at most ``width`` characters."""
        unit = f" {self.unit}" if self.unit else ""
        el = self.elapsed
        if self.total:
            frac = min(1.0, self.n / self.total)
            fill = int(round(20 * frac))
            eta = el / self.n * max(0, self.total - self.n) if self.n else None
            clock = _clock(el) + ("<" + _clock(eta) if eta is not None else "")
            text = f"{self.desc} [{'#' * fill}{'-' * (20 - fill)}] {self.n}/{self.total}{unit} {clock}"
        else:
            text = f"{self.desc} {self.n}{unit} {_clock(el)}"
        if self.note:
            text += f" {self.note}"
        return escape_controls(text)[: max(10, width - 1)]

    def closing(self) -> str:
        count = f"{self.n}/{self.total}" if self.total and self.n != self.total else f"{self.n}"
        unit = f" {self.unit}" if self.unit else ""
        steps = f"{count}{unit} in " if self.unit else ""
        tail = self.summary if self.summary is not None else self.note
        return f"{self.desc}: {steps}{self.elapsed:.1f} s" + (f"; {tail}" if tail else "")

    def __exit__(self, exc_type, exc, tb) -> None:
        failed = exc_type is not None and not issubclass(exc_type, GeneratorExit)  # a loop left early ends it
        _bar.remove(self, failed=failed)
        if not failed:  # one line per stage; a stage inside another is summed up by the outer one's line
            (debug if _bar.stack else info)(self.closing())
        elif _bar.stack:
            _bar.draw(force=True)


def drawing() -> bool:
    """Whether progress bars are drawn (stderr a terminal, progress shown through hlaid's handler)."""
    return _bar.shown()


def nested() -> bool:
    """Whether a :class:`Stage` is in progress: work inside it logs its own lines as details (DEBUG)."""
    return bool(_bar.stack)


def stage(desc: str, total: int | None = None, *, unit: str = "") -> Stage:
    """A :class:`Stage` of ``total`` steps (None: unknown) counted in ``unit``::

        with _progress.stage("[identify] replay fit", 40, unit="evaluations") as st:
            ...
            st.update(1, note=f"cost {cost:.4g}")
    """
    return Stage(desc, total, unit=unit)


def progress(items: Iterable[T], total: int | None = None, desc: str = "", unit: str = "") -> Iterator[T]:
    """Iterate over ``items`` as one :class:`Stage` named ``desc`` (a bar on a terminal, one closing
    line)."""
    total = total if total is not None else (len(items) if isinstance(items, Sized) else None)
    with Stage(desc, total, unit=unit) as st:
        for item in items:
            _interrupt.check()
            yield item
            st.update()


class _Bar:
    """The stages in progress (innermost last) and the bar line on stderr."""

    def __init__(self) -> None:
        self.stack: list[Stage] = []
        self.open = False
        """Whether a bar line on stderr awaits its end (is drawn)."""

    @staticmethod
    def shown() -> bool:
        """Bars are drawn on a terminal, through hlaid's own stderr handler, when progress is shown."""
        return (LOGGER.isEnabledFor(logging.INFO) and any(isinstance(h, _StderrHandler) for h in LOGGER.handlers)
                and _isatty())

    def draw(self, force: bool = False) -> None:
        if not self.stack or not self.shown():
            return
        st = self.stack[-1]
        now = time.perf_counter()
        if not force and now - st._drawn_at < 0.1 and not (st.total and st.n >= st.total):
            return
        st._drawn_at = now
        width = shutil.get_terminal_size((100, 24)).columns
        sys.stderr.write("\r" + st.line(width) + "\x1b[K")
        sys.stderr.flush()
        self.open = True

    def clear(self) -> None:
        """Erase the bar line (a message is about to be printed in its place)."""
        if self.open:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
            self.open = False

    def remove(self, st: Stage, failed: bool) -> None:
        if st in self.stack:
            self.stack.remove(st)
        if failed:
            end_line()
        else:
            self.clear()


def _isatty() -> bool:
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # replaced or closed
        return False


_bar = _Bar()


def end_line() -> None:
    """End a progress bar line left open (by an interruption or an error) where it stopped, so that
    the next message starts a line of its own."""
    if _bar.open:
        _bar.open = False
        print(file=sys.stderr, flush=True)
