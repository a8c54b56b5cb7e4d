"""Where numba keeps the compiled kernels (``cache=True``): always somewhere writable, never an error.

numba looks for a cache folder when a kernel module is imported: ``NUMBA_CACHE_DIR``, then
``__pycache__`` beside the source, then ``~/.cache/numba``; when none can be written (a root-owned
install and a user whose ``HOME`` is missing, empty or read-only) it raises "cannot cache function
...: no locator available". :func:`configure` runs when ``hlaid`` is imported, before numba, and
picks the first of

1. ``NUMBA_CACHE_DIR`` when the user set it and it can be written;
2. ``__pycache__`` beside the kernels (numba's own default: one cache per installed tree, shared
   by every user who can write there, reused by the test run and the demo);
3. ``<user cache>/hlaid/numba`` (``$XDG_CACHE_HOME`` or ``~/.cache``, see :mod:`hlaid._userdirs`);
4. ``<temp>/hlaid-numba-<uid>``, a folder only this user owns and can read (0700);
5. none: caching is turned off (the kernels compile in each process, about a minute).

Only 3 and 4 set ``NUMBA_CACHE_DIR`` (for this process and the processes it starts).
"""

from __future__ import annotations

import os
import stat
import sys
import tempfile
from pathlib import Path

from ._userdirs import cache_root

KERNEL_PACKAGES = ("simulate", "model", "svm", "hla", "ida")
"""The subpackages whose source files hold ``cache=True`` kernels (``model``: the story law's equations,
compiled by ``simulate``; a test checks that no other does)."""

_PACKAGE = Path(__file__).resolve().parent
_chosen: str | None = None


def _writable(folder: Path) -> bool:
    """numba's own test of a cache folder: it can be made and a file written in it."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except (OSError, ValueError):
        return False
    return True


def _private(folder: Path) -> bool:
    """``folder`` is (or is made) a real folder of this user that nobody else can write or read:
    the cache holds pickled code, so a folder another user controls must not be used."""
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(folder)
    except OSError:
        return False
    if not stat.S_ISDIR(st.st_mode) or (hasattr(os, "getuid") and st.st_uid != os.getuid()):
        return False
    return not st.st_mode & 0o077 and _writable(folder)


def _candidates() -> list[tuple[str, Path | None]]:
    user = os.environ.get("NUMBA_CACHE_DIR", "")
    root = cache_root()
    uid = os.getuid() if hasattr(os, "getuid") else 0
    try:
        temp: Path | None = Path(tempfile.gettempdir()) / f"hlaid-numba-{uid}"
    except OSError:
        temp = None
    return [("user", Path(user) if user else None), ("in-tree", None),
            ("cache", root / "numba" if root is not None else None), ("temp", temp)]


def configure() -> str:
    """Choose the kernels' cache once per process (see the module's docstring) and return which:
    ``"user"``, ``"in-tree"``, ``"cache"``, ``"temp"`` or ``"off"``."""
    global _chosen
    if _chosen is not None:
        return _chosen
    for kind, folder in _candidates():
        if kind == "in-tree":
            if all(_writable(_PACKAGE / sub / "__pycache__") for sub in KERNEL_PACKAGES):
                os.environ.pop("NUMBA_CACHE_DIR", None)
                return _use(kind)
        elif folder is not None and (_private(folder) if kind == "temp" else _writable(folder)):
            os.environ["NUMBA_CACHE_DIR"] = str(folder)
            return _use(kind)
    os.environ.pop("NUMBA_CACHE_DIR", None)
    _disable_caching()
    return _use("off")


def _use(kind: str) -> str:
    global _chosen
    _chosen = kind
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba was imported before hlaid: make it read the folder again
        config.reload_config()
    return kind


def _disable_caching() -> None:
    """No folder can be written: the kernels are compiled without a cache instead of numba's error."""
    from numba.core.dispatcher import Dispatcher

    Dispatcher.enable_caching = lambda self: None  # type: ignore[method-assign]


__all__ = ["KERNEL_PACKAGES", "configure"]
