"""Record suites (e.g. for IDA): a folder of AT2/text files, the built-in suite, or a list of files.

An unreadable record is skipped with a warning that lists every skipped file and why;
nothing is skipped silently, and a set that ends up empty is an error.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from .. import _progress
from ..errors import InputError
from ..limits import check_count
from ..motions.builtin import SUITE, builtin_suite
from ..motions.record import GroundMotion
from .motion import read_record

__all__ = ["RECORD_SUFFIXES", "RecordSpec", "read_records", "as_motions", "is_record_file"]

RECORD_SUFFIXES = (".at2", ".txt", ".dat", ".acc", ".csv")
"""File endings taken as records in a folder (optionally followed by ``.gz``)."""

RecordSpec = str | os.PathLike | GroundMotion


def is_record_file(p: Path) -> bool:
    """Whether ``p`` is a visible file whose name ends in one of :data:`RECORD_SUFFIXES`."""
    name = p.name.lower().removesuffix(".gz")
    return p.is_file() and not p.name.startswith(".") and name.endswith(RECORD_SUFFIXES)


def _expand(spec) -> tuple[list, str | None]:
    """Record candidates of one spec and, for a folder, its path (for messages)."""
    if isinstance(spec, GroundMotion):
        return [spec], None
    s = str(spec)
    if s == SUITE:
        return list(builtin_suite()), None
    if s.startswith("builtin:"):
        return [s], None
    p = Path(s)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if is_record_file(f))
        if not files:
            raise InputError(f"no record files in the folder (expected names ending in "
                             f"{', '.join(RECORD_SUFFIXES)}, optionally .gz)", source=s)
        return files, s
    if not p.exists():
        raise InputError("record file or folder not found", source=s)
    return [p], None


def read_records(records: RecordSpec | Sequence[RecordSpec], *, units: str | None = None,
                 dt: float | None = None) -> list[GroundMotion]:
    """Read a record set (what ``hlaid.io.read(records, kind="records")`` does).

    Parameters
    ----------
    records : a folder, ``"builtin-suite"``, ``"builtin:NAME"``, a file, a
        :class:`~hlaid.motions.GroundMotion`, or a list of these
    units, dt : passed to the text readers (AT2 files state their own)

    Returns
    -------
    list of GroundMotion with unique names (a clash gets ``-2``, ``-3``, ... appended)
    """
    specs = [records] if isinstance(records, (str, os.PathLike, GroundMotion)) else list(records)
    if not specs:
        raise InputError("no records given")
    motions: list[GroundMotion] = []
    skipped: list[str] = []
    expanded = [_expand(spec)[0] for spec in specs]
    check_count(sum(len(items) for items in expanded), "IDA_RECORDS", "records")  # before reading any
    for items in expanded:
        for item in items:
            if isinstance(item, GroundMotion):
                motions.append(item)
                continue
            try:
                motions.append(read_record(item, units=units, dt=dt))
            except InputError as err:
                skipped.append(f"{item} ({str(err).removeprefix(f'{item}: ')})")
    if skipped:
        _progress.warn(f"skipped {len(skipped)} unreadable record(s): " + "; ".join(skipped))
    if not motions:
        raise InputError(f"none of the {len(skipped)} record file(s) could be read; see the warning above"
                         if skipped else "no records given")
    return _unique_names(motions)


def as_motions(records, *, units: str | None = None, dt: float | None = None) -> list[GroundMotion]:
    """``records`` as a list of :class:`~hlaid.motions.GroundMotion`: kept as given when they
    already are motions (one or a non-empty sequence), else read with :func:`read_records`."""
    motions = records if _all_motions(records) else read_records(records, units=units, dt=dt)
    return [motions] if isinstance(motions, GroundMotion) else list(motions)


def _all_motions(records) -> bool:
    if isinstance(records, GroundMotion):
        return True
    if isinstance(records, (str, Path, os.PathLike)):
        return False
    try:
        return len(records) > 0 and all(isinstance(m, GroundMotion) for m in records)
    except TypeError:
        return False


def _unique_names(motions: list[GroundMotion]) -> list[GroundMotion]:
    import dataclasses
    seen: dict[str, int] = {}
    out = []
    for m in motions:
        name = m.name or "record"
        k = seen.get(name, 0) + 1
        seen[name] = k
        out.append(m if k == 1 and m.name else dataclasses.replace(m, name=name if k == 1 else f"{name}-{k}"))
    return out
