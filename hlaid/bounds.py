"""Bounds of numeric fields, declared once, as metadata of the dataclass fields of a schema.

Every number a user gives hlaid (a config value, a field of a clone file) belongs to a field of
a frozen dataclass, and that field declares its range::

    @dataclass(frozen=True, kw_only=True)
    class BinsConfig:
        p_fine: float = bounded(0.1, lo=0.01, hi=1.0)
        samples: int = bounded(800, lo=20, hi="TRAINING")   # upper bound: HLAID_MAX_TRAINING

        def __post_init__(self):
            check_bounds(self)

:func:`hlaid.config.load_config` checks every such field of a YAML file before the schema is
built (``FILE:LINE: key: ... is out of range; expected ...``), and :func:`check_bounds` checks an
instance built in Python (``dataclasses.replace``, command-line overrides). A bound is finite
on both sides, so NaN, infinities, ``1e300`` and 5000-digit integers are refused wherever they
are written; the upper bound may name a limit of :mod:`hlaid.limits` instead of a number. A
field may hold one number, None, or a list/tuple of numbers (each is checked).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from .errors import InputError
from .limits import limit

KEY = "hlaid.bounds"
"""The key of a field's :class:`Bounds` in its ``metadata``."""


@dataclass(frozen=True)
class Bounds:
    """``lo <= value <= hi`` (either side open with ``lo_open``/``hi_open``), finite.

    ``hi`` may be the name of a limit of :mod:`hlaid.limits` (``"TRAINING"``: ``HLAID_MAX_TRAINING``),
    resolved when a value is checked. ``unit`` is shown in messages.
    """

    lo: float
    hi: float | str
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""

    def __post_init__(self):
        if not math.isfinite(self.lo) or (not isinstance(self.hi, str) and not math.isfinite(self.hi)):
            raise ValueError(f"bounds must be finite, got [{self.lo}, {self.hi}]")

    def upper(self) -> float:
        """``hi``, or the current value of the limit it names."""
        return limit(self.hi) if isinstance(self.hi, str) else float(self.hi)

    def contains(self, v: Any) -> bool:
        """Whether ``v`` (a number) lies within the bounds (never for NaN, infinities, booleans)."""
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return False
        if isinstance(v, float) and not math.isfinite(v):
            return False
        hi = self.upper()
        return (v > self.lo if self.lo_open else v >= self.lo) and (v < hi if self.hi_open else v <= hi)

    def text(self, name: str) -> str:
        """``"0.01 <= p_fine <= 1"`` (with the unit and, for a limit, the variable that raises it)."""
        unit = f" [{self.unit}]" if self.unit else ""
        limit = f" (set HLAID_MAX_{self.hi} to raise it)" if isinstance(self.hi, str) else ""
        return (f"{_number(self.lo)} {'<' if self.lo_open else '<='} {name} {'<' if self.hi_open else '<='} "
                f"{_number(self.upper())}{unit}{limit}")

    def offending(self, value: Any) -> tuple[int | None, Any] | None:
        """``(index, number)`` of the first number of ``value`` outside the bounds (index None for
        a single number), or None when all lie within. None and strings (the other choice of a
        field such as ``column: str | int``) are skipped."""
        if value is None:
            return None
        if hasattr(value, "ndim") and hasattr(value, "tolist"):  # a numpy array
            value = value.ravel().tolist() if value.ndim else value.item()
        if isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                if v is not None and not isinstance(v, str) and not self.contains(v):
                    return i, v
            return None
        return None if isinstance(value, str) or self.contains(value) else (None, value)

    def check(self, name: str, value: Any) -> None:
        """Raise :class:`InputError` (``name = value is out of range; expected ...``) when a number of
        ``value`` lies outside the bounds."""
        bad = self.offending(value)
        if bad is not None:
            i, v = bad
            raise InputError(self.message(name if i is None else f"{name}[{i}]", v))

    def message(self, name: str, v: Any) -> str:
        return f"{name} = {show(v)} is out of range; expected {self.text(name.rsplit('.', 1)[-1].split('[')[0])}"


SEED = Bounds(0, 2**32 - 1)
"""Bounds of a random seed (numpy's and torch's generators take any of these)."""


def show(v: Any) -> str:
    """A number for a message: huge integers by their length, floats in short form."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return repr(v) if isinstance(v, str) and len(v) <= 40 and v.isprintable() else type(v).__name__
    if isinstance(v, int) and abs(v) >= 10**15:
        return f"an integer of {len(str(abs(v)))} digits"
    return _number(v)


def _number(v: float) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e15 else f"{v:.6g}"


def bounded(default: Any = dataclasses.MISSING, *, lo: float, hi: float | str, lo_open: bool = False,
            hi_open: bool = False, unit: str = "", **kwargs) -> Any:
    """A dataclass ``field`` whose numbers must lie within ``[lo, hi]`` (see :class:`Bounds`)."""
    return with_bounds(Bounds(lo, hi, lo_open, hi_open, unit), default, **kwargs)


def with_bounds(b: Bounds, default: Any = dataclasses.MISSING, **kwargs) -> Any:
    """A dataclass ``field`` with the given :class:`Bounds` (declared once, used by several schemas)."""
    return dataclasses.field(default=default, metadata={KEY: b}, **kwargs)


def bounds_of(f: dataclasses.Field) -> Bounds | None:
    """The :class:`Bounds` of a dataclass field, or None."""
    return f.metadata.get(KEY)


def check_bounds(obj: Any, *, prefix: str = "") -> None:
    """Check every bounded field of the dataclass instance ``obj`` (an :class:`InputError` naming
    the first field out of range, as ``prefix + name``)."""
    for f in dataclasses.fields(obj):
        b = bounds_of(f)
        if b is not None:
            b.check(prefix + f.name, getattr(obj, f.name))


__all__ = ["Bounds", "SEED", "bounded", "with_bounds", "bounds_of", "check_bounds", "show", "KEY"]
