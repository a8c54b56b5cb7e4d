"""One way to put a foreign text into a message: :func:`hlaid.errors.one_line`."""

from __future__ import annotations

import re
from pathlib import Path

import hlaid
from hlaid.errors import InputError, failure_text, one_line

PACKAGE = Path(hlaid.__file__).parent

BY_HAND = re.compile(r"""(['"]) \1\.join\(.*\.split\(\)\)""")
"""``" ".join(str(x).split())``: the one-line text written again beside :func:`one_line`."""


def test_one_line_joins_cuts_and_escapes():
    assert one_line("a\n  b\tc\r\n") == "a b c"
    assert one_line("x" * 50 + "\n" + "y" * 50, 60) == "x" * 50 + " " + "y" * 9
    assert one_line("title \x1b]0;owned\x07 end") == "title \\x1b]0;owned\\x07 end"
    assert one_line(OSError("disk\nfull"), 4) == "disk"


def test_failure_text_names_a_silent_error_by_its_type():
    assert failure_text(ZeroDivisionError()) == "ZeroDivisionError"
    assert failure_text(ValueError("bad\n" + "z" * 300)) == "bad " + "z" * 196
    assert str(InputError("two\nlines", source="f.csv")) == "f.csv: two lines"


def test_the_one_line_text_is_written_once():
    """Every module writes an error into a message with :func:`one_line`, not by hand."""
    found = [f"{p.relative_to(PACKAGE.parent)}:{n}" for p in sorted(PACKAGE.rglob("*.py"))
             if p.name != "errors.py" or p.parent != PACKAGE
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if BY_HAND.search(line)]
    assert found == [], f"one line written by hand (use hlaid.errors.one_line): {found}"


def test_the_pattern_sees_the_hand_written_forms():
    assert BY_HAND.search("""why = " ".join(str(err).split())[:200]""")
    assert BY_HAND.search("""f"({' '.join(str(err).split())[:80]})\"""")
    assert BY_HAND.search("""p = " ".join(str(getattr(err, "problem", None) or "x").split())""")
