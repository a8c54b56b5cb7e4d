"""Lazy public names of a package (PEP 562: a module-level ``__getattr__``).

A package ``__init__`` lists where each name lives::

    __getattr__, __dir__ = lazy_exports(__name__, {"run_hla": ".analysis", "HLAConfig": ".config"})

so that importing one light submodule (a config schema) does not import the heavy ones (torch,
numba, scipy) its siblings need: a bad config is refused before they load. The package stays a
plain module; no exported name may be the name of one of its submodules (a test checks), so a
submodule imported later never replaces a name.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, where: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``: name -> the (relative) module that defines it.
    A name whose module path ends in ``:module`` is that module itself."""
    def __getattr__(name: str) -> Any:
        target = where.get(name)
        if target is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, kind = target.partition(":")
        mod = importlib.import_module(module, package)
        value = mod if kind == "module" else getattr(mod, name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
