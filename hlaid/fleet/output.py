"""The output folder of a fleet: what makes a folder one, and whether a folder may be used.

Light (no dask, torch or scipy), so that ``hlaid fleet`` refuses a bad output before they load.
"""

from __future__ import annotations

from pathlib import Path

from .._fileio import check_name, check_parent
from ..errors import InputError

MARKER = "fleet.json"
"""The file that makes a folder an hlaid fleet output (a rerun resumes it)."""


def check_output(out: Path, *, force: bool) -> Path:
    """Refuse an output folder that cannot be (re)used: a file, a folder that is neither empty nor a
    fleet output (``--force`` does not change that: a fleet writes into its folder, and must not
    overwrite someone else's ``report.html``), a missing or unwritable parent, a name too long."""
    out = Path(out)
    check_name(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", source=str(out))
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).is_file():
        raise InputError("is not empty and is not an hlaid fleet output (--force does not write into another "
                         "program's folder); choose an empty or new folder", source=str(out))
    if not out.exists():
        check_parent(out)
    return out


__all__ = ["MARKER", "check_output"]
