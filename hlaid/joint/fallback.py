"""A numerical stage that fails falls back, with a note: real records never stop the clone.

A clone's identification runs many numerical stages beside its main fit: the laws' candidate fits,
the prefix fits of the prequential start, the check of a sequential update, the Laplace covariance.
Any of them can fail on real data (a factorisation that loses positive definiteness in floating
point, a tangent that grows without bound, a search that leaves the model's range). Each runs
through :func:`run_stage`: a failure is said on the terminal, recorded in the clone
(``clone.fallbacks``, :class:`hlaid.record.Fallback`: the stage, the error, what was used instead) and replaced by the
stage's fallback, never an internal error.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from .. import _progress
from ..errors import NUMERICAL_FAILURES, failure_text

T = TypeVar("T")


def run_stage(stage: str, fn: Callable[[], T], fallback: Callable[[], Any] | Any, notes: list[dict] | None, *,
              used: str, extra: tuple[type[BaseException], ...] = ()) -> T | Any:
    """``fn()``; where it fails numerically (:data:`hlaid.errors.NUMERICAL_FAILURES`, and ``extra``), the
    ``fallback`` (called where callable), with a warning and a note ``{"stage", "error", "used"}``
    appended to ``notes`` (None: no note)."""
    try:
        return fn()
    except NUMERICAL_FAILURES + tuple(extra) as err:
        why = failure_text(err)
    _progress.warn(f"{stage} failed numerically ({why}); {used}")
    if notes is not None:
        notes.append({"stage": stage, "error": why, "used": used})
    return fallback() if callable(fallback) else fallback


__all__ = ["NUMERICAL_FAILURES", "failure_text", "run_stage"]
