"""The output folder of a fleet: what makes a folder one, and whether a folder may be used.

Light (no dask, torch or scipy), so that ``hlaid fleet`` refuses a bad output before they load.
"""

from __future__ import annotations

import os
from pathlib import Path

from .._fileio import check_name, check_parent
from .._outdir import not_ours, read_marker
from ..errors import InputError

MARKER = "fleet.json"
"""The file that makes a folder an hlaid fleet output (a rerun resumes it)."""


def check_output(out: Path, *, force: bool) -> Path:
    """Refuse an output folder that cannot be (re)used: a file, a folder that is neither empty nor a
    fleet output (``--force`` does not change that: a fleet writes into its folder, and must not
    overwrite someone else's ``report.html``), a missing or unwritable parent, a name too long.

    A fleet output is a folder whose signed output marker (:mod:`hlaid._outdir`) was written there
    by ``hlaid fleet`` and lists every entry in it, each file still holding what the fleet wrote: a
    ``fleet.json`` alone proves nothing (anyone may have a file of that name)."""
    out = Path(out)
    check_name(out)
    if os.path.islink(out) and not out.exists():
        raise InputError("is a symbolic link to nothing; remove the link or choose another folder", source=str(out))
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", source=str(out))
    if out.is_dir() and any(out.iterdir()):
        why = not_ours(out)
        mark = read_marker(out)
        if why is None and (mark or {}).get("command") != "hlaid fleet":
            why = f"was written by {str((mark or {}).get('command'))[:40]!r}"
        if why is not None:
            raise InputError(f"is not empty and is not an hlaid fleet output: the folder {why}; "
                             "--force does not write into another folder: choose an empty or new folder",
                             source=str(out))
    if not out.exists():
        check_parent(out)
    return out


__all__ = ["MARKER", "check_output"]
