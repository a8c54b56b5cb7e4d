"""Layout rules that hold for the whole package, checked by walking its source with ``ast``.

A private name (``_x``: a function, a constant or a module) belongs to the package that defines
it: other modules of that package may import it, modules of other packages may not (they use
a public name). The top-level private modules of hlaid (``hlaid._fileio``, ``hlaid._progress``,
...) are the package-wide plumbing and may be imported as modules from anywhere in hlaid; the
private names inside them may not.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from test_import_graph import from_module

import hlaid

ROOT = Path(hlaid.__file__).parent

ALLOWED_FILES: set[str] = set()  # files exempt from the rule (none)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _is_package(dotted: str) -> bool:
    return (ROOT.parent.joinpath(*dotted.split(".")) / "__init__.py").is_file()


def _package_of(path: Path) -> str:
    """The package a module belongs to (a package's ``__init__`` belongs to the package itself)."""
    name = _module_name(path)
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _owner(prefix: str) -> str:
    """The package a name found under the dotted ``prefix`` belongs to."""
    return prefix if _is_package(prefix) else prefix.rpartition(".")[0]


def _plumbing(prefix: str, name: str) -> bool:
    return prefix == "hlaid" and (ROOT / f"{name}.py").is_file()


def _violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    package = _package_of(path)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            module = from_module(node, package)
            dotted = [module + "." + a.name for a in node.names]
        elif isinstance(node, ast.Import):
            dotted = [a.name for a in node.names]
        else:
            continue
        for full in dotted:
            parts = full.split(".")
            if parts[0] != "hlaid":
                continue
            for i in range(1, len(parts)):
                prefix = ".".join(parts[:i])
                if _private(parts[i]) and not _plumbing(prefix, parts[i]) and _owner(prefix) != package:
                    out.append(f"{_module_name(path)}:{node.lineno} imports {full} (private to {_owner(prefix)})")
    return out


def _modules() -> list[Path]:
    return sorted(p for p in ROOT.rglob("*.py") if p.relative_to(ROOT).as_posix() not in ALLOWED_FILES)


def test_no_private_name_is_imported_from_another_package():
    bad = [v for p in _modules() for v in _violations(p)]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("source,ok", [
    ("from ..hla.preprocess import _sos", False),          # a private function of another package
    ("from ..model import _equations as eq", False),       # a private module of another package
    ("from ..model._equations import ENERGY_SCALE", False),  # a name inside one
    ("from .._fileio import _json_default", False),        # a private name inside the plumbing
    ("from .. import _progress", True),                    # the plumbing itself
    ("from .._fileio import write_json", True),
    ("from . import _space as sp", True),                  # same package
    ("from .refine import _filt", True),
    ("import hlaid.hla.analysis", True),
    ("from hlaid.hla.analysis import _masses", False),
])
def test_the_rule_on_examples(tmp_path, monkeypatch, source, ok):
    """The checker itself, on one import placed in hlaid/identify/."""
    fake = ROOT / "identify" / "example_module.py"
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: source if self == fake else "")
    assert (not _violations(fake)) == ok
