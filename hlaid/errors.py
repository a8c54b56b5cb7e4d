"""Exceptions that carry a one-line message for the user.

Library code raises :class:`InputError` (a ``ValueError``) for anything the user can fix:
a malformed file, an out-of-range parameter, an unknown config key. The command line turns
it into a single line on stderr and exit status 2; anything else is an internal error
(exit status 1).
"""

from __future__ import annotations

import re
import unicodedata
from typing import TYPE_CHECKING

_BIDI = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def _escaped(ch: str) -> str:
    if ch in _BIDI or unicodedata.category(ch) in ("Cc", "Cs"):
        code = ord(ch)
        return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"
    return ch


def escape_controls(text) -> str:
    """``text`` with control characters (C0, C1, DEL), lone surrogates (undecodable bytes of a
    file name) and bidirectional overrides written as ``\\x1b``-style escapes, so that a file
    name such as ``'\\x1b]0;...\\x07'`` cannot retitle, clear or reorder the user's terminal."""
    text = str(text)
    if text.isprintable() and text.isascii():
        return text
    return "".join(_escaped(ch) for ch in text)


def one_line(text, limit: int | None = None) -> str:
    """``text`` as one line: runs of whitespace (newlines included) become one space, cut to its
    first ``limit`` characters (None: whole), and control characters are escaped
    (:func:`escape_controls`). The one way hlaid writes an error (or any text it did not write
    itself) into a message."""
    return escape_controls(" ".join(str(text).split())[:limit])


MESSAGE_MAX = 800
"""Characters of an error message (beyond its source): a longer one (a value of 60,000 characters, a
list of 100 masses echoed) keeps its beginning and its end (:func:`clipped`)."""


def clipped(text: str, limit: int = MESSAGE_MAX) -> str:
    """``text`` within ``limit`` characters: its beginning and its last 200 (where the advice is), the
    characters between counted."""
    if len(text) <= limit:
        return text
    tail = min(200, limit // 4)
    head = limit - tail - 40
    return f"{text[:head]} ... ({len(text) - head - tail:,} characters left out) ... {text[-tail:]}"


def failure_text(err: BaseException) -> str:
    """An error in one line of at most 200 characters (its type's name where it says nothing)."""
    return one_line(err, 200) or type(err).__name__


class InputError(ValueError):
    """Bad user input. ``str(err)`` is one line naming the file or field and what is wrong
    (control characters escaped: it may quote a hostile file name)."""

    def __init__(self, message: str, *, source: str | None = None):
        message = clipped(one_line(message))  # always one line, of a readable length
        self.source = source
        self.detail = message
        """The message without the source."""
        super().__init__(f"{escape_controls(source)}: {message}" if source else message)


class ConfigError(InputError):
    """A configuration file that does not match its schema."""


class NotIdentifiableError(InputError):
    """The record does not hold enough information to identify what was asked."""


class UnstableTangentError(InputError):
    """The replay's tangent-linear model grows without bound along the trajectory (a building far
    from the data, or one whose linearisation is unstable): the errors-in-variables weighting
    (``refine.method: eiv``) cannot be formed there."""


class TangentTooLargeError(InputError):
    """The replay's ground tangent would need more memory than the errors-in-variables weighting
    is allowed (``refine.tangent_max_mb``; its time grows alike): least squares is used instead."""


if TYPE_CHECKING:
    NUMERICAL_FAILURES: tuple[type[BaseException], ...]
    """What a numerical stage may fail with, and fall back from with a note (a factorisation that
    loses positive definiteness, an overflow, a division by zero, a replay tangent that grows
    without bound or is too large to form); anything else is a bug and is raised. Made on first
    use (it names numpy's ``LinAlgError``: importing this module imports no numpy)."""
else:
    def __getattr__(name: str):
        if name == "NUMERICAL_FAILURES":
            import numpy as np

            value = (np.linalg.LinAlgError, FloatingPointError, ZeroDivisionError, OverflowError,
                     UnstableTangentError, TangentTooLargeError)
            globals()[name] = value
            return value
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class HlaidWarning(UserWarning):
    """Legal but suspicious input (an unusual sample rate, a skipped record file, ...); the
    command line shows each as one ``warning: ...`` line on stderr."""


_LABEL = re.compile(r"[A-Za-z0-9_ .()\[\]/^*%+-]{1,32}")


def quotable(text) -> bool:
    """Whether ``text`` read from a file (a column or channel name) may be quoted in an error.

    Messages say what is wrong and where (line, column, field) but do not echo file contents: the
    file may be some unrelated one given by mistake (a line of a password file must not end up
    in a terminal or a log). A short, plain label such as ``acc (g)`` is still quoted.
    """
    return isinstance(text, str) and _LABEL.fullmatch(text) is not None


def column_label(names, j: int) -> str:
    """``column 3 ('acc (g)')``, or ``column 3`` when the name is not :func:`quotable`."""
    name = names[j] if 0 <= j < len(names) else None
    return f"column {j + 1} ({name!r})" if quotable(name) else f"column {j + 1}"


def columns_text(names) -> str:
    """The column names of a file for an error message (unquotable ones by number)."""
    return ", ".join(n if quotable(n) else f"column {j + 1}" for j, n in enumerate(names))


def kind_of(v, *, none: str = "null") -> str:
    """What a parsed JSON/YAML value is (never the value: it may be long or not ours to echo)."""
    if v is None:
        return none
    if isinstance(v, bool):
        return "true or false"
    if isinstance(v, (int, float)):
        return "a number"
    kinds: dict[type, str] = {str: "a string", list: "a list", dict: "a mapping"}
    return kinds.get(type(v), type(v).__name__)
