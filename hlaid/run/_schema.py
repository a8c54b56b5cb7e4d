"""Typed JSON blocks: frozen dataclasses read from and written to JSON by their own annotations.

A :class:`Block`'s fields say what each key holds: ``float``, ``int``, ``str``, ``bool``, ``Any``,
``X | None``, ``tuple[X, ...]`` (a list), ``tuple[X, Y]`` (a list of exactly two), ``dict[str, X]``
and other blocks. :meth:`Block.from_dict` checks a mapping against them, each error one line
naming the file and the field's dotted path, never quoting the value; keys a block does not
declare are ignored, a field with a default may be absent. Two rules go in ``Annotated``:
:data:`NONEMPTY` (a list with at least one item) and :data:`NUMBER_KEYS` (a mapping whose keys
read as numbers). A :class:`Document` also keeps the whole mapping it was read from.
"""

from __future__ import annotations

import dataclasses
import numbers
import types
import typing
from collections.abc import Mapping
from typing import Annotated, Any, Union

from ..errors import InputError, kind_of

NONEMPTY = "a non-empty list"
"""``Annotated`` rule: the list has at least one item."""

NUMBER_KEYS = "a mapping whose keys are numbers"
"""``Annotated`` rule: every key of the mapping reads as a number."""


@dataclasses.dataclass(frozen=True)
class _Where:
    """What an error names: the file, its source (a folder), and the dotted path of the field."""

    file: str
    source: str | None
    path: str = ""

    def at(self, key: str | int) -> _Where:
        if isinstance(key, int):
            return dataclasses.replace(self, path=f"{self.path}[{key}]")
        return dataclasses.replace(self, path=f"{self.path}.{key}" if self.path else key)

    def fail(self, what: str) -> typing.NoReturn:
        raise InputError(f"{self.file}: field {self.path or 'top level'} {what}", source=self.source)

    def expect(self, what: str, v) -> typing.NoReturn:
        self.fail(f"must be {what}, got {kind_of(v)}")


_SCALARS: dict[type, tuple[str, type]] = {float: ("a number", numbers.Real), int: ("an integer", numbers.Integral),
                                          str: ("a string", str), bool: ("true or false", bool)}


def _read(tp, v, where: _Where):
    """``v`` checked against the annotation ``tp`` (lists become tuples, blocks are built)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is Annotated:
        value = _read(args[0], v, where)
        for rule in args[1:]:
            _check_rule(rule, value, where)
        return value
    if origin in (Union, types.UnionType):
        if v is None and type(None) in args:
            return None
        (inner,) = (a for a in args if a is not type(None))
        return _read(inner, v, where)
    if tp is Any:
        return v
    if isinstance(tp, type) and issubclass(tp, Block):
        if not isinstance(v, Mapping):
            where.expect("a mapping", v)
        return tp._read_block(v, where)
    if origin is tuple:
        if not isinstance(v, (list, tuple)):
            where.expect("a list", v)
        if args[-1] is not Ellipsis:
            if len(v) != len(args):
                where.expect(f"a list of {len(args)} values", v)
            return tuple(_read(a, x, where.at(i)) for i, (a, x) in enumerate(zip(args, v)))
        return tuple(_read(args[0], x, where.at(i)) for i, x in enumerate(v))
    if origin is dict:
        if not isinstance(v, Mapping):
            where.expect("a mapping", v)
        return {k: _read(args[1], x, where.at(str(k))) for k, x in v.items()}
    what, kind = _SCALARS[tp]
    if not isinstance(v, kind) or (tp is not bool and isinstance(v, bool)):
        where.expect(what, v)
    return v if type(v) in (int, float, str, bool) else tp(v)  # a numpy scalar as the Python one


def _check_rule(rule: str, value, where: _Where) -> None:
    if rule == NONEMPTY and not value:
        where.fail("is empty")
    if rule == NUMBER_KEYS:
        for k in value:
            try:
                float(k)
            except ValueError:
                where.fail("has a key that is not a number")


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    """The resolved annotations of a block's fields (once per class)."""
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls, include_extras=True)
    return _HINTS[cls]


def _plain(v):
    """A JSON-able value of a field (blocks as mappings, tuples as lists)."""
    if isinstance(v, Block):
        return v.to_dict()
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


class Block:
    """Base of a frozen dataclass read from JSON by its annotations (see the module docstring)."""

    @classmethod
    def from_dict(cls, d: Mapping, *, file: str, source: str | None = None, path: str = ""):
        """The block of mapping ``d``, checked; an :class:`InputError` names ``file``, ``source`` and
        the field (``path``: where ``d`` sits in the file)."""
        where = _Where(file, source, path)
        if not isinstance(d, Mapping):
            where.expect("a mapping", d)
        return cls._read_block(d, where)

    @classmethod
    def _read_block(cls, d: Mapping, where: _Where):
        hints = _hints(cls)
        kwargs = {}
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if f.metadata.get("whole"):
                kwargs[f.name] = dict(d)
            elif f.name in d:
                kwargs[f.name] = _read(hints[f.name], d[f.name], where.at(f.name))
            elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                where.at(f.name).fail("is missing")
        return cls(**kwargs)

    def to_dict(self) -> dict:
        """The JSON-able mapping (the fields in their order)."""
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)  # type: ignore[arg-type]
                if not f.metadata.get("whole")}


@dataclasses.dataclass(frozen=True, kw_only=True)
class Document(Block):
    """A block that keeps the mapping it was read from (``document``, written back whole by
    :meth:`to_dict`) beside the typed view of it its fields give: a document another part of hlaid
    writes, of which a reader needs a few fields."""

    document: dict[str, Any] = dataclasses.field(metadata={"whole": True}, repr=False, compare=False)

    def to_dict(self) -> dict:
        return dict(self.document)


__all__ = ["Block", "Document", "NONEMPTY", "NUMBER_KEYS"]
