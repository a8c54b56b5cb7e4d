"""Progress and messages on stderr, honouring the command line's --quiet / --verbose."""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")

VERBOSITY = 1
"""0 quiet, 1 normal, 2 verbose. Set by the command line; the library default is normal."""


def set_verbosity(level: int) -> None:
    global VERBOSITY
    VERBOSITY = int(level)


def info(msg: str) -> None:
    """A progress message (suppressed by --quiet)."""
    if VERBOSITY >= 1:
        print(msg, file=sys.stderr, flush=True)


def debug(msg: str) -> None:
    """A detail shown with --verbose."""
    if VERBOSITY >= 2:
        print(msg, file=sys.stderr, flush=True)


def warn(msg: str) -> None:
    """A warning (always shown)."""
    print(f"warning: {msg}", file=sys.stderr, flush=True)


def progress(items: Iterable[T], total: int | None = None, desc: str = "") -> Iterator[T]:
    """Iterate with a one-line progress bar on stderr (only when stderr is a terminal or verbose)."""
    total = total if total is not None else (len(items) if hasattr(items, "__len__") else None)
    show = VERBOSITY >= 1 and (sys.stderr.isatty() or VERBOSITY >= 2)
    t0 = time.perf_counter()
    for i, item in enumerate(items):
        yield item
        if show and total:
            done = i + 1
            frac = done / total
            eta = (time.perf_counter() - t0) / done * (total - done)
            bar = "#" * int(24 * frac)
            print(f"\r{desc} [{bar:<24}] {done}/{total} eta {eta:5.1f}s", end="", file=sys.stderr, flush=True)
    if show and total:
        print(f"\r{desc} done in {time.perf_counter() - t0:.1f} s" + " " * 30, file=sys.stderr, flush=True)
