"""The user's folders hlaid keeps things in: the classifier cache and the key that signs output markers.

A ``HOME`` that is unset, empty or not an absolute path names no folder of the user (as root,
``HOME=""`` would otherwise put them in ``/.cache``): then there is none, and what needs one says so.
"""

from __future__ import annotations

import os
from pathlib import Path


def home() -> Path | None:
    """The user's home folder: ``HOME`` when it is an absolute path other than ``/``, else None."""
    h = os.environ.get("HOME")
    if h is None:
        try:
            import pwd
            h = pwd.getpwuid(os.getuid()).pw_dir
        except (ImportError, KeyError, OSError):
            return None
    if not h or not os.path.isabs(h) or os.path.abspath(h) == os.path.abspath(os.sep):
        return None
    return Path(h)


def _xdg(var: str, *under: str) -> Path | None:
    v = os.environ.get(var)
    if v and os.path.isabs(v):
        return Path(v)
    h = home()
    return h.joinpath(*under) if h is not None else None


def cache_root() -> Path | None:
    """``$XDG_CACHE_HOME/hlaid`` or ``~/.cache/hlaid``; None without a home folder."""
    base = _xdg("XDG_CACHE_HOME", ".cache")
    return base / "hlaid" if base is not None else None


def state_root() -> Path | None:
    """``HLAID_STATE_DIR``, else ``$XDG_STATE_HOME/hlaid`` or ``~/.local/state/hlaid``; None without
    a home folder."""
    v = os.environ.get("HLAID_STATE_DIR")
    if v:
        return Path(v)
    base = _xdg("XDG_STATE_HOME", ".local", "state")
    return base / "hlaid" if base is not None else None


__all__ = ["home", "cache_root", "state_root"]
