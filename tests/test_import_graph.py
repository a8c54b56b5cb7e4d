"""No import cycle among hlaid's modules.

Every module's imports are read with ``ast``, wherever they stand: at module level, inside
functions (the imports that hide a cycle from Python until the function runs) and under
``if TYPE_CHECKING:``. Relative imports are resolved; ``from pkg import name`` is an import of
the submodule ``pkg.name`` where there is one, else of the package itself (its ``__init__``,
which re-exports the name and imports what it re-exports). Importing ``a.b.c`` runs the
``__init__`` of ``a`` and ``a.b`` first, so those are edges too, except the packages the
importing module itself lives in (already running; a name imported from one of them is an
edge). A cycle in this graph is printed.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import hlaid

ROOT = Path(hlaid.__file__).parent


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _ancestors(dotted: str) -> list[str]:
    parts = dotted.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def from_module(node: ast.ImportFrom, package: str) -> str:
    """The absolute module of ``from <module> import ...`` written in ``package``."""
    if not node.level:
        return node.module or ""
    base = package.split(".")
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports_of(source: str, module: str, is_package: bool, known: set[str]) -> set[str]:
    """The hlaid modules that importing ``module`` (source text ``source``) may import."""
    package = module if is_package else module.rpartition(".")[0]
    targets: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            parent = from_module(node, package)
            for a in node.names:
                sub = f"{parent}.{a.name}"
                targets.add(sub if sub in known else parent)
    inside = set(_ancestors(module)) | {module}
    out: set[str] = set()
    for t in targets:
        while t and t not in known:  # an attribute path: the module that holds it
            t = t.rpartition(".")[0]
        if not t:
            continue
        out.update(m for m in _ancestors(t) if m in known and m not in inside)
        if t != module:  # an explicit import of an enclosing package's __init__ counts
            out.add(t)
    return out


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    files = {_module_name(p): p for p in sorted(root.rglob("*.py"))}
    known = set(files)
    return {m: imports_of(p.read_text(), m, p.name == "__init__.py", known) for m, p in files.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as ``[a, b, ..., a]``, or None (iterative depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    for start in sorted(graph):
        if state.get(start):
            continue
        path, stack = [start], [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph.get(nxt, ()))))
    return None


def test_no_import_cycle_among_hlaid_modules():
    graph = import_graph()
    assert len(graph) > 100 and "hlaid.identify.pipeline" in graph
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


KNOWN = {"hlaid", "hlaid.a", "hlaid.a.x", "hlaid.a.y", "hlaid.b", "hlaid.b.z", "hlaid.c"}


@pytest.mark.parametrize("module,is_package,source,expected", [
    ("hlaid.a.x", False, "from .y import f", {"hlaid.a.y"}),
    ("hlaid.a.x", False, "from . import y", {"hlaid.a.y"}),
    ("hlaid.a.x", False, "from ..b import g", {"hlaid.b"}),                 # a re-export: the package
    ("hlaid.a.x", False, "from ..b.z import g", {"hlaid.b", "hlaid.b.z"}),  # the package's __init__ runs first
    ("hlaid.a.x", False, "def f():\n    from ..c import h\n", {"hlaid.c"}),
    ("hlaid.a.x", False, "if TYPE_CHECKING:\n    from hlaid.c import T\n", {"hlaid.c"}),
    ("hlaid.a.x", False, "from .. import __version__", {"hlaid"}),
    ("hlaid.a", True, "from .x import f", {"hlaid.a.x"}),
    ("hlaid.a.x", False, "import hlaid.b.z.thing\nimport numpy", {"hlaid.b", "hlaid.b.z"}),
])
def test_imports_are_read_as_python_runs_them(module, is_package, source, expected):
    assert imports_of(source, module, is_package, KNOWN) == expected


def test_a_cycle_is_found_and_printed():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def _module_level_imports(path: Path) -> set[str]:
    """Absolute names imported at a module's top level (not in functions, not under TYPE_CHECKING)."""
    tree = ast.parse(path.read_text())
    package = _module_name(path) if path.name == "__init__.py" else _module_name(path).rpartition(".")[0]
    out: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = from_module(node, package)
            out.update([base] + [f"{base}.{a.name}" for a in node.names])
    return out


@pytest.mark.parametrize("module,reaches", [("hlaid.identify.config", "hlaid.identify.refiners"),
                                            ("hlaid.hla.config", "hlaid.errors")])
def test_config_modules_import_nothing_heavy(module, reaches):
    """A config module and every hlaid module it imports at its top level, transitively (the
    packages' ``__init__`` aside), import neither torch, numba nor scipy at their top level: a bad
    config can be refused before the heavy libraries load."""
    files = {_module_name(p): p for p in ROOT.rglob("*.py")}
    seen, todo, heavy = set(), [module], []
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        for name in _module_level_imports(files[m]):
            if name.split(".")[0] in ("torch", "numba", "scipy"):
                heavy.append(f"{m} imports {name}")
            elif name in files and not files[name].name == "__init__.py":
                todo.append(name)
    assert reaches in seen and not heavy, heavy
