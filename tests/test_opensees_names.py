"""Clone names cannot inject code into the script ``hlaid export-opensees`` writes.

``hlaid identify`` names a clone after the measurement's file name, so the name is hostile
input. Whatever it holds (quotes, ``\"\"\"``, newlines, backslashes, any unicode), the exported
script must compile, hold the name only as the string constant ``NAME``, and have exactly the
syntax tree of the script of a plain name: the name can change a value, never the code.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import needs_opensees
from hypothesis import given, settings
from hypothesis import strategies as st

from hlaid.clone import Clone
from hlaid.motions import GroundMotion
from hlaid.opensees import export_opensees, opensees_script

HOSTILE = [
    'b""";import os;os.system("touch SENTINEL");"""',
    "x'\nimport os; os.system('touch SENTINEL')\n#",
    "'''; __import__('os').system('touch SENTINEL'); '''",
    '"; exec("print(1)"); "',
    "trailing backslash \\",
    "\\\"\"\"\\n\\x00",
    "line1\r\nline2\u2028line3\x00",
    "\N{PILE OF POO} b\u00e2timent \u5efa\u7269",
    "{n}{version}{{name}}",  # format fields: the template must not be re-formatted with the name
    "",
]

FORBIDDEN_CALLS = {"eval", "exec", "compile", "__import__", "getattr", "setattr", "globals", "vars", "breakpoint",
                   "os.system", "os.popen", "os.execv", "os.execve", "os.execl", "os.spawnl", "os.remove", "os.unlink",
                   "importlib.import_module", "runpy.run_path"}
"""Calls that the model script never makes (``ops.*``, argparse, numpy and file handling only);
also any ``subprocess.*``."""


def _clone_named(table1, name: str) -> Clone:
    """A clone of Table 1 called ``name``, passed through its JSON file format."""
    d = Clone(building=table1.replace(name=name)).to_dict()
    return Clone.from_dict(json.loads(json.dumps(d)), source="<test>")


def _normalised(tree: ast.Module) -> str:
    """The script's syntax tree with the value of ``NAME`` blanked out."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["NAME"]:
            node.value = ast.Constant(value="<name>")
    return ast.dump(tree, include_attributes=False)


def _called_names(tree: ast.Module) -> set[str]:
    """Dotted names of every call (``ops.system``, ``os.replace``, ``print``)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f, parts = node.func, []
            while isinstance(f, ast.Attribute):
                parts.append(f.attr)
                f = f.value
            parts.append(f.id if isinstance(f, ast.Name) else "<expr>")
            out.add(".".join(reversed(parts)))
    return out


@pytest.fixture(scope="module")
def reference(table1):
    return _normalised(ast.parse(opensees_script(table1.replace(name="clone"))))


def _check_script(text: str, name: str, reference: str) -> None:
    compile(text, "model.py", "exec")
    tree = ast.parse(text)
    names = [n for n in tree.body
             if isinstance(n, ast.Assign) and [getattr(t, "id", None) for t in n.targets] == ["NAME"]]
    assert len(names) == 1
    assert isinstance(names[0].value, ast.Constant) and names[0].value.value == (name or "clone")
    assert _normalised(tree) == reference  # the name changed a value, not the code
    called = _called_names(tree)  # (the tree, docstring included, is the reference's: this is belt and braces)
    assert not called & FORBIDDEN_CALLS and not any(c.startswith("subprocess.") for c in called)


@settings(max_examples=200, deadline=None)
@given(name=st.text())
def test_any_name_is_only_a_string_constant(table1, reference, name):
    clone = _clone_named(table1, name)
    assert clone.building.name == name
    _check_script(opensees_script(clone), name, reference)


@settings(max_examples=50, deadline=None)
@given(name=st.lists(st.sampled_from(list("\"'\\\n\r\t#;{}()xX ") + ["\"\"\"", "'''", "\x00", "\u2028", "import os",
                                                                     "os.system('touch SENTINEL')"]),
                     max_size=20).map("".join))
def test_quote_heavy_names_are_only_a_string_constant(table1, reference, name):
    _check_script(opensees_script(_clone_named(table1, name)), name, reference)


@pytest.mark.parametrize("name", HOSTILE)
def test_hostile_names_round_trip_through_the_files(table1, reference, tmp_path, name):
    path = Clone(building=table1.replace(name=name)).save(tmp_path / "clone.json")
    script = export_opensees(path, tmp_path / "model.py")
    text = script.read_text(encoding="utf-8")
    _check_script(text, name, reference)
    ns: dict = {"__name__": "model_definition"}  # import mode: defines the model, runs nothing
    exec(compile(text, str(script), "exec"), ns)  # noqa: S102 - the point of the test
    assert ns["NAME"] == (name or "clone")
    assert not (tmp_path / "SENTINEL").exists()


@needs_opensees
@pytest.mark.parametrize("name", HOSTILE[:3])
def test_hostile_names_run_in_opensees(table1, tmp_path, name):
    from hlaid.opensees import run_opensees
    gm = GroundMotion(dt=0.01, acc=500.0 * np.sin(np.arange(200) * 0.05), name="tiny")
    res = run_opensees(_clone_named(table1, name), gm)
    assert res.ok and np.all(np.isfinite(res.peak_drift))
    script = export_opensees(_clone_named(table1, name), tmp_path / "model.py")
    rec = tmp_path / "tiny.txt"
    rec.write_text("".join(f"{0.01 * i:.2f} {0.05 * np.sin(0.05 * i):.6f}\n" for i in range(200)))
    r = subprocess.run([sys.executable, str(script), str(rec), "--units", "g", "--out", str(tmp_path / "p.json")],
                       capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "p.json").read_text())["model"] == name
    assert not (tmp_path / "SENTINEL").exists()
