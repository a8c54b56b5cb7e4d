"""YAML configs validated against frozen dataclass schemas, with file and line in every error.

A schema is a frozen dataclass whose fields carry type annotations (numbers, strings,
booleans, ``Literal`` choices, ``X | None``, ``list[X]``/``tuple[X, ...]``, ``dict[str, X]``
and nested schemas). :func:`load_config` rejects unknown keys, wrong types and values a
schema's ``__post_init__`` refuses, each with ``FILE:LINE: key: what is wrong`` (LINE: the line
of the offending value, also inside nested blocks). Every config is read by one safe loader that
refuses YAML aliases (``*name``), so a tiny file cannot expand into a huge one.
"""

from __future__ import annotations

import dataclasses
import os
import re
import types
import typing
from typing import Any, Literal, TypeVar, Union

import yaml

from ._inputs import read_text
from .bounds import bounds_of, show
from .errors import ConfigError, InputError, kind_of, one_line
from .limits import limit

T = TypeVar("T")


class _Node:
    """A YAML value with the line it starts on (1-based); mappings also keep each key's line."""

    def __init__(self, value, line, keys=None):
        self.value, self.line, self.keys = value, line, keys or {}


def _convert(node: yaml.Node, source: str) -> _Node:
    line = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: dict[str, _Node] = {}
        keys: dict[str, int] = {}
        for k, v in node.value:
            key = k.value
            if key in out:
                raise ConfigError(f"{source}:{k.start_mark.line + 1}: key {key!r} appears twice")
            out[key] = _convert(v, source)
            keys[key] = k.start_mark.line + 1
        return _Node(out, line, keys)
    if isinstance(node, yaml.SequenceNode):
        return _Node([_convert(v, source) for v in node.value], line)
    try:
        return _Node(yaml.SafeLoader("").construct_object(node, deep=True), line)
    except ValueError:  # an integer of thousands of digits (Python refuses to convert it): the
        return _Node(_BigInt(node.value), line)  # field it is given to refuses it by name


class _BigInt(str):
    """The text of an integer too long for Python to convert (thousands of digits): a number field
    reads it as a float (inf), refused by its bounds; any other field refuses it as such."""


def _safe_loader_base() -> type:
    """``yaml.SafeLoader`` with libyaml's parser where PyYAML has it (7 times faster: a config is
    refused at its node limit in a fraction of a second) and PyYAML's own composer, which
    :class:`_NoAliasLoader` extends."""
    try:
        from yaml._yaml import CParser  # type: ignore[import-not-found,import-untyped,unused-ignore]
    except ImportError:
        return yaml.SafeLoader

    class _Fast(yaml.composer.Composer, CParser, yaml.constructor.SafeConstructor, yaml.resolver.Resolver):
        def __init__(self, stream):
            CParser.__init__(self, stream)
            yaml.composer.Composer.__init__(self)
            yaml.constructor.SafeConstructor.__init__(self)
            yaml.resolver.Resolver.__init__(self)

    return _Fast


MAX_VALUE_CHARS = 65536
"""Longest value of a config (a path, a name, a list written as text): hlaid's are far shorter."""

MAX_CONFIG_BYTES = 16 * 2**20
"""Largest config file read (the largest that :data:`HLAID_MAX_CONFIG_NODES` keys and values fill
is a few MiB): a bigger one is refused before it is read."""


class _NoAliasLoader(_safe_loader_base()):  # type: ignore[misc]
    """``yaml.SafeLoader`` that refuses aliases (``*name``, also in ``<<: *name`` merges).

    An alias repeats a node by reference, so a few hundred bytes of nested aliases ("billion
    laughs") expand into gigabytes, and an alias inside its own anchor is a cycle. hlaid
    configs are small: every value is written out. Anchors alone (``&name``) are harmless.
    """

    source = "<string>"
    nodes = 0
    max_nodes = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise ConfigError(f"{self.source}:{event.start_mark.line + 1}: YAML aliases (*name) are not allowed in "
                              "hlaid configs; write the value out in full")
        self.nodes += 1
        if self.nodes > self.max_nodes:  # a config of 200 000 keys is refused after the first 20 000
            line = self.peek_event().start_mark.line + 1
            raise ConfigError(f"{self.source}:{line}: more than {self.max_nodes} keys and values; hlaid configs are "
                              "far smaller (set HLAID_MAX_CONFIG_NODES to raise the limit)")
        if self.check_event(yaml.ScalarEvent):
            event = self.peek_event()
            if len(event.value) > MAX_VALUE_CHARS:
                raise ConfigError(f"{self.source}:{event.start_mark.line + 1}: a value of {len(event.value):,} "
                                  f"characters; a config value (a path, a name) has at most {MAX_VALUE_CHARS:,}")
        return super().compose_node(parent, index)


def compose_yaml(text: str, source: str = "<string>") -> yaml.Node | None:
    """The YAML node tree of ``text`` (None when empty), composed by the one loader every hlaid
    config goes through: safe tags only, aliases refused (:class:`_NoAliasLoader`), at most
    ``HLAID_MAX_CONFIG_NODES`` keys and values, one document."""
    loader = None
    try:
        loader = _NoAliasLoader(text)  # refuses control characters at once (yaml.reader.ReaderError)
        loader.source, loader.max_nodes = source, int(limit("CONFIG_NODES"))
        return loader.get_single_node()
    except yaml.reader.ReaderError as err:
        line = text.count("\n", 0, max(int(err.position), 0)) + 1
        what = f"the control character \\x{err.character:02x}" if isinstance(err.character, int) else "a character"
        raise ConfigError(f"{source}:{line}: invalid YAML: {what} is not allowed in a YAML file; write it as an escape "
                          "in a double-quoted string (\"\\e\") or remove it") from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"{source}:{mark.line + 1}" if mark else source
        problem = one_line(getattr(err, "problem", None) or "syntax error")
        raise ConfigError(f"{where}: invalid YAML: {problem}") from None
    except RecursionError:  # nesting thousands of levels deep
        raise ConfigError(f"{source}: invalid YAML: nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()


def parse_yaml(text: str, source: str = "<string>") -> _Node:
    """Parse YAML into line-annotated nodes; syntax errors name the file and line, and aliases
    (``*name``) are refused (see :class:`_NoAliasLoader`)."""
    root = compose_yaml(text, source)
    if root is None:
        return _Node({}, 1)
    try:
        return _convert(root, source)
    except yaml.YAMLError as err:  # e.g. a tag no safe constructor knows (!!python/object)
        mark = getattr(err, "problem_mark", None)
        where = f"{source}:{mark.line + 1}" if mark else source
        problem = one_line(getattr(err, "problem", None) or "cannot read a value")
        raise ConfigError(f"{where}: invalid YAML: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{source}: invalid YAML: nested too deeply") from None


def _type_name(tp) -> str:
    origin = typing.get_origin(tp)
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin in (list, tuple):
        return "a list"
    if origin is dict:
        return "a mapping"
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    if origin in (Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp) if a is not type(None)) + " (or null)"
    return getattr(tp, "__name__", str(tp))


def _build(tp, node: _Node, where: str, source: str):
    v = node.value
    err = f"{source}:{node.line}: {where or 'top level'}:"
    origin = typing.get_origin(tp)
    if isinstance(v, _BigInt) and tp is not float and origin not in (Union, types.UnionType):
        raise ConfigError(f"{err} an integer of {len(v)} digits is out of range")
    if origin in (Union, types.UnionType):
        args = typing.get_args(tp)
        if v is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _build(a, node, where, source)
            except ConfigError as e:
                errors.append(e)
        if len(errors) == 1:
            raise errors[0]
        raise ConfigError(f"{err} expected {_type_name(tp)}, got {_show(v)}")
    if tp is Any:
        return _plain(node)
    if origin is Literal:
        if v not in typing.get_args(tp):
            raise ConfigError(f"{err} {_show(v)} is not allowed; expected {_type_name(tp)}")
        return v
    if tp is bool:
        if not isinstance(v, bool):
            raise ConfigError(f"{err} expected true or false, got {_show(v)}")
        return v
    if tp is int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(f"{err} expected an integer, got {_show(v)}")
        return v
    if tp is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            if isinstance(v, str):
                try:
                    return float(v)  # YAML 1.1 reads '1e4' (no dot) as a string
                except ValueError:
                    pass
            raise ConfigError(f"{err} expected a number, got {_show(v)}")
        try:
            return float(v)
        except OverflowError:  # an integer beyond any float
            raise ConfigError(f"{err} {show(v)} is out of range") from None
    if tp is str:
        if not isinstance(v, str):
            raise ConfigError(f"{err} expected a string, got {_show(v)}")
        return v
    if origin in (list, tuple):
        if not isinstance(v, list):
            raise ConfigError(f"{err} expected a list, got {_show(v)}")
        args = typing.get_args(tp)
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(v) != len(args):
                raise ConfigError(f"{err} expected a list of {len(args)} values, got {len(v)}")
            return tuple(_build(a, x, f"{where}[{i}]", source) for i, (a, x) in enumerate(zip(args, v)))
        item = args[0] if args else Any
        items = [_build(item, x, f"{where}[{i}]", source) for i, x in enumerate(v)]
        return tuple(items) if origin is tuple else items
    if origin is dict:
        if not isinstance(v, dict):
            raise ConfigError(f"{err} expected a mapping, got {_show(v)}")
        _, vt = typing.get_args(tp) or (str, Any)
        return {k: _build(vt, x, f"{where}.{k}" if where else k, source) for k, x in v.items()}
    if dataclasses.is_dataclass(tp):
        return _build_dataclass(tp, node, where, source)
    raise TypeError(f"unsupported schema type {tp!r} at {where}")


def _plain(node: _Node):
    v = node.value
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


def _show(v) -> str:
    """A value for an error message: short scalars as written, anything else by its kind (a
    long string may be a line of some unrelated file given by mistake: it is not echoed)."""
    if isinstance(v, dict):
        return "a mapping"
    if isinstance(v, list):
        return "a list"
    if isinstance(v, str) and (len(v) > 40 or not v.isprintable()):
        return f"a string of {len(v)} characters"
    return repr(v)


def _build_dataclass(cls, node: _Node, where: str, source: str, base=None):
    """``cls`` from a mapping; keys it does not give take ``base``'s values where given (a nested
    section's: the default of the enclosing schema for it), else the field defaults."""
    if not isinstance(node.value, dict):
        if not where:  # the whole file: perhaps not a config at all, so quote none of it
            got = kind_of(node.value, none='an empty document')
            raise ConfigError(f"{source}:{node.line}: top level: expected a mapping, got {got} "
                              "(settings are 'key: value' lines); is this an hlaid YAML config?")
        raise ConfigError(f"{source}:{node.line}: {where}: expected a mapping, got {_show(node.value)}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    keys = node.keys
    kwargs = {}
    for key, sub in node.value.items():
        path = f"{where}.{key}" if where else str(key)
        if key not in fields:
            raise ConfigError(f"{source}:{keys.get(key, node.line)}: unknown key {path!r}; "
                              f"expected one of: {', '.join(fields)}")
        inner = _section_default(fields[key], base)
        if inner is not None and dataclasses.is_dataclass(hints[key]) and isinstance(sub.value, dict):
            kwargs[key] = _build_dataclass(hints[key], sub, path, source, base=inner)
        else:
            kwargs[key] = _build(hints[key], sub, path, source)
        _check_field(fields[key], kwargs[key], sub, path, source)
    if base is not None:
        kwargs.update({k: getattr(base, k) for k in fields if k not in kwargs})
    missing = [k for k, f in fields.items()
               if k not in kwargs and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    if missing:
        raise ConfigError(f"{source}:{node.line}: {where or 'top level'}: missing key(s) {', '.join(missing)}")
    try:
        return cls(**kwargs)
    except InputError as e:
        key = _key_named_in(str(e), node.value)
        line = node.value[key].line if key is not None else node.line
        raise ConfigError(f"{source}:{line}: {where or 'top level'}: {e}") from None


def _section_default(f: dataclasses.Field, base):
    """The default of a nested section (a dataclass-valued field): ``base``'s value of it, else
    the field's ``default_factory`` product; None for any other field."""
    value = getattr(base, f.name) if base is not None else (
        f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
    return value if dataclasses.is_dataclass(value) and not isinstance(value, type) else None


def _check_field(f: dataclasses.Field, value, node: _Node, path: str, source: str) -> None:
    """The field's bounds (:mod:`hlaid.bounds`), checked with the line of the offending value."""
    b = bounds_of(f)
    bad = None if b is None else b.offending(value)
    if b is not None and bad is not None:
        i, v = bad
        line = node.value[i].line if i is not None and isinstance(node.value, list) else node.line
        raise ConfigError(f"{source}:{line}: {b.message(path if i is None else f'{path}[{i}]', v)}")


def _key_named_in(message: str, values: dict) -> str | None:
    """The key of ``values`` that ``message`` (a schema's ``__post_init__`` error such as
    ``"n_levels = 1; expected ..."``) names first, so the error points at that value's line."""
    best = None
    for key in values:
        m = re.search(rf"(?<![\w-]){re.escape(str(key))}(?![\w-])", message)
        if m and (best is None or m.start() < best[0]):
            best = (m.start(), key)
    return None if best is None else best[1]


class _NoAliasDumper(yaml.SafeDumper):
    """Writes a value used twice in full (the loader refuses aliases)."""

    def ignore_aliases(self, data):
        return True


def config_from_dict(cls: type[T], data: dict, source: str = "<dict>") -> T:
    """Validate a plain mapping against schema ``cls`` (as :func:`load_config` does a file)."""
    text = yaml.dump(data, Dumper=_NoAliasDumper, sort_keys=False)
    return _build_dataclass(cls, parse_yaml(text, source), "", source)


def load_yaml(path: str | os.PathLike) -> _Node:
    """The line-annotated YAML tree of a config file (see :func:`parse_yaml`)."""
    source = str(path)
    if not os.path.lexists(source):
        raise ConfigError("config file not found", source=source)
    try:
        size = os.stat(source).st_size
    except OSError:
        size = 0
    if size > MAX_CONFIG_BYTES:
        raise ConfigError(f"is {size / 2**20:.3g} MiB; a config is at most {MAX_CONFIG_BYTES // 2**20} MiB (hlaid "
                          "configs are a few KiB: data belong in the files they name)", source=source)
    return parse_yaml(read_text(source), source)  # a regular file within HLAID_MAX_FILE_MB (hlaid._inputs)


def config_from_node(cls: type[T], node: _Node, source: str, where: str = "") -> T:
    """Validate a node of :func:`load_yaml` (``where``: its dotted key, e.g. ``"ida"``) against
    schema ``cls``; errors give the line of the offending value in ``source``."""
    return _build_dataclass(cls, node, where, source)


def load_config(path: str | os.PathLike, cls: type[T]) -> T:
    """Load and validate a YAML file against the dataclass schema ``cls``."""
    return _build_dataclass(cls, load_yaml(path), "", str(path))


def config_to_dict(cfg) -> dict:
    """A plain (YAML/JSON-able) mapping of a config dataclass."""
    def conv(v):
        if dataclasses.is_dataclass(v):
            return {f.name: conv(getattr(v, f.name)) for f in dataclasses.fields(v)}
        if isinstance(v, (list, tuple)):
            return [conv(x) for x in v]
        if isinstance(v, dict):
            return {k: conv(x) for k, x in v.items()}
        return v
    return conv(cfg)
