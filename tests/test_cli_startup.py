"""The command line starts fast: building the parser and printing any help imports none of the
heavy libraries (checked by module, in a fresh interpreter; ``scripts/bench_cli.py`` times it),
and ``hlaid`` re-exports its public API lazily."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "numba", "matplotlib", "sklearn", "scipy", "dask", "distributed")

PROBE = """
import contextlib, io, json, sys
from hlaid.cli.app import build_parser, main
parser = build_parser()
parser.format_help()
for name in parser.commands:
    with contextlib.redirect_stdout(io.StringIO()):
        try:
            main([name, "--help"])
        except SystemExit:
            pass
print(json.dumps({"commands": list(parser.commands), "heavy": sorted(m for m in HEAVY if m in sys.modules)}))
"""


def _fresh(code: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=REPO, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_parser_and_every_help_import_nothing_heavy():
    out = json.loads(_fresh(f"HEAVY = {HEAVY!r}\n" + PROBE).strip().splitlines()[-1])
    assert {"simulate", "hla", "identify", "ida", "run", "demo", "fleet", "report"} <= set(out["commands"])
    assert out["heavy"] == []


def test_import_hlaid_is_light_and_names_load_on_use():
    code = (f"import sys, hlaid; light = not any(m in sys.modules for m in {HEAVY!r}); "
            "from hlaid.ida.analysis import run_ida as f; from hlaid import Building, run_ida; "
            "print(light, hlaid.run_ida is run_ida is f, Building.__module__)")
    assert _fresh(code).split() == ["True", "True", "hlaid.model.params"]


def test_subpackages_are_modules():
    """``hlaid.identify`` & co. are the subpackages, whether imported before or after the
    functions of the same stem; ``import hlaid.x.y as m`` gives the module."""
    code = ("import types, hlaid; f = hlaid.identify_clone; import hlaid.identify.pipeline as pl; "
            "import hlaid.hla, hlaid.ida, hlaid.simulate, hlaid.simulate.odeint as od; "
            "mods = [hlaid.identify, hlaid.hla, hlaid.ida, hlaid.simulate, pl, od]; "
            "print(all(isinstance(m, types.ModuleType) for m in mods), hlaid.events.identify_clone is f, "
            "hlaid.hla.run_hla is hlaid.run_hla, hlaid.simulate.simulate_response is hlaid.simulate_response, "
            "hlaid.ida.run_ida is hlaid.run_ida)")
    assert _fresh(code).split() == ["True"] * 5


WALK = """
import importlib, json, pkgutil, sys, types
import hlaid
packages = [m.name for m in pkgutil.walk_packages(hlaid.__path__, "hlaid.") if m.ispkg] + ["hlaid"]
bad = []
for name in packages:  # every public name first, then every submodule: a name must survive both orders
    pkg = importlib.import_module(name)
    for attr in getattr(pkg, "__all__", []):
        getattr(pkg, attr)
for m in pkgutil.walk_packages(hlaid.__path__, "hlaid."):
    if not m.name.endswith("__main__"):  # that one runs the command line
        importlib.import_module(m.name)
for name in packages:
    pkg = sys.modules[name]
    if type(pkg) is not types.ModuleType:
        bad.append(f"{name} is a {type(pkg).__name__}, not a plain module")
    subs = [m.name for m in pkgutil.iter_modules(pkg.__path__) if m.name != "__main__"]
    for sub in subs:
        if getattr(pkg, sub, None) is not sys.modules[f"{name}.{sub}"]:
            bad.append(f"{name}.{sub} is not the submodule")
    bad += [f"{name} exports {a!r}, the name of its submodule" for a in getattr(pkg, "__all__", []) if a in subs]
print(json.dumps(bad))
"""


def test_every_package_is_a_plain_module_and_no_name_shadows_a_submodule():
    """Walk the whole package: no module subclass, and no exported name (a function such as
    ``assess``) is the name of a submodule of its package, whichever is imported first."""
    bad = json.loads(_fresh(WALK).strip().splitlines()[-1])
    assert bad == []


def test_public_api_is_complete():
    import hlaid

    for name in hlaid.__all__:
        assert getattr(hlaid, name) is not None, name
    assert set(hlaid.__all__) <= set(dir(hlaid))
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        hlaid.nothing  # noqa: B018
    for old in ("hla", "identify", "simulate", "ida"):  # the subpackages' names are not functions
        assert old not in hlaid.__all__


def test_the_type_stub_declares_the_public_api():
    """``hlaid/__init__.pyi`` (what type checkers see) imports exactly ``_LAZY``'s names, each
    from the module ``_LAZY`` says."""
    import ast

    import hlaid

    stub = ast.parse((REPO / "hlaid" / "__init__.pyi").read_text())
    declared: dict[str, set[str]] = {}
    for node in stub.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            for a in node.names:
                assert a.asname == a.name, f"{a.name}: re-export it as 'import {a.name} as {a.name}'"
                declared.setdefault("." + (node.module or ""), set()).add(a.name)
    declared.pop(".typing", None)
    assert declared == {m: set(names) for m, names in hlaid._LAZY.items()}


def test_run_package_is_a_plain_module():
    """``hlaid.run`` loads its names on first use through a module-level ``__getattr__`` (no
    module subclass); none of its names is a submodule's, and reading a run config or a run
    summary imports nothing heavy."""
    code = (f"import pkgutil, sys, types, hlaid.run as r; cfg = r.RunConfig; s = r.RunSummary; "
            f"light = not any(m in sys.modules for m in {HEAVY!r}); f = r.build_report; "
            "import hlaid.run.report as rep, hlaid.run.loss as lo; "
            "subs = {m.name for m in pkgutil.iter_modules(r.__path__)}; "
            "print(type(r) is types.ModuleType, light, r.report is rep, r.loss is lo, f is rep.build_report, "
            "not subs & set(r.__all__), set(r.__all__) == set(r._WHERE), 'runner' in subs)")
    assert _fresh(code).split() == ["True"] * 8
