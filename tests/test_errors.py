"""One way to say each thing about errors: a foreign text goes into a message through
:func:`hlaid.errors.one_line`, and what counts as a numerical failure (fallen back from, not raised)
is :data:`hlaid.errors.NUMERICAL_FAILURES`, defined once."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hlaid
from hlaid.errors import HlaidWarning, InputError, failure_text, one_line

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


# ----------------------------------------------------------------------------- numerical failures
def _failure_definitions() -> list[str]:
    """Where a module of hlaid binds a name ending in ``FAILURES`` (a set of errors to fall back from)."""
    out = []
    for p in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Assign):
                targets = node.targets
            elif isinstance(node, ast.AnnAssign):
                targets = [node.target]
            else:
                continue
            out += [f"{p.relative_to(PACKAGE.parent)}:{node.lineno}" for t in targets
                    if isinstance(t, ast.Name) and t.id.endswith("FAILURES")]
    return out


def test_numerical_failures_are_defined_once():
    found = _failure_definitions()
    assert len(found) == 1 and found[0].startswith("hlaid/errors.py:"), found
    from hlaid.errors import NUMERICAL_FAILURES, TangentTooLargeError, UnstableTangentError
    from hlaid.identify import refiners
    from hlaid.joint import fallback

    assert refiners.NUMERICAL_FAILURES is NUMERICAL_FAILURES is fallback.NUMERICAL_FAILURES
    assert set(NUMERICAL_FAILURES) == {np.linalg.LinAlgError, FloatingPointError, ZeroDivisionError, OverflowError,
                                       UnstableTangentError, TangentTooLargeError}


def test_a_numerical_failure_falls_back_and_a_bug_is_raised():
    from hlaid.joint.fallback import run_stage

    notes: list[dict] = []
    with pytest.warns(HlaidWarning, match="a stage failed numerically"):
        assert run_stage("a stage", lambda: 1 / 0, 7, notes, used="seven") == 7
    assert notes == [{"stage": "a stage", "error": "division by zero", "used": "seven"}]
    with pytest.raises(KeyError):
        run_stage("a stage", lambda: {}["x"], 7, notes, used="seven")


def test_the_errors_module_imports_no_numpy():
    """The command line imports it to print any error; numpy comes with the first numerical failure."""
    code = ("import sys, hlaid.errors as e; before = 'numpy' in sys.modules; f = e.NUMERICAL_FAILURES; "
            "print(before, 'numpy' in sys.modules, f[0].__name__)")
    env = {**os.environ, "PYTHONPATH": str(PACKAGE.parent)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.split() == ["False", "True", "LinAlgError"]
