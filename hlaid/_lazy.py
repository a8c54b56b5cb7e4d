"""Packages whose public names are imported on first use (PEP 562).

A package ``__init__`` lists where each name lives and keeps a ``TYPE_CHECKING`` block of the
same imports for type checkers::

    __getattr__, __dir__ = lazy_exports(__name__, {"hla": ".analysis", "HLAConfig": ".config"})

so that importing one light submodule (a config schema) does not import the heavy ones
(torch, numba, scipy) its siblings need: a bad config is refused before they load.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable
from typing import Any, cast


class _LazyPackage(types.ModuleType):
    """A package whose exported function keeps its name when the submodule of the same name loads
    (``hlaid.uncertainty.assess`` is the function, as with an eager ``from .assess import assess``)."""

    _lazy_names: frozenset = frozenset()

    def __setattr__(self, name: str, value: Any) -> None:
        if (name in self._lazy_names and isinstance(value, types.ModuleType)
                and value.__name__ == f"{self.__name__}.{name}"):
            return
        super().__setattr__(name, value)


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

    module = sys.modules[package]
    module.__class__ = _LazyPackage
    cast(_LazyPackage, module)._lazy_names = frozenset(n for n, t in where.items() if not t.endswith(":module"))
    return __getattr__, __dir__
