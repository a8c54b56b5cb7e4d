"""The key that signs hlaid's output markers, and the names of hlaid's temporary outputs.

The key (32 random bytes, hex) is ``output-key`` in :func:`hlaid._userdirs.state_root`, a regular
file of the user's own, readable and writable by that user alone (mode 0600, made so on first
use). Anything else in its place is refused, with one line saying how to fix it, before any work:
a link, a folder or a FIFO (never opened: checked with ``lstat`` and opened non-blocking without
following links), a file of another user, or one that group or others may read or write (anyone
who read it could sign a marker that lets ``--force`` delete a folder of the user).

A temporary output is named ``.NAME.PID-RRRRRRRRSSSSSSSSSSSS.tmp[SUFFIX]`` (a replaced folder kept
aside: ``.NAME.old-PID-RRRRRRRRSSSSSSSSSSSS``): ``R`` a random token, ``S`` its tag, an HMAC of
NAME, PID and the token under the key (:func:`temp_name`). Only a name whose tag is valid was made
by hlaid, and only such names are ever swept as leftovers of a killed run (:func:`made_here`): a
user's ``.run1.old-2024/`` or ``.model.py.1234-draft.tmp`` never is. Without a key the tag is
absent and nothing is swept.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import re
import secrets
import stat
from pathlib import Path

from .errors import InputError

_problem: str | None = None
"""Why the last :func:`signing_key` found no key to use (None: it found one)."""


def _refuse(path: Path, what: str, fix: str) -> InputError:
    return InputError(f"hlaid's output key {what}; {fix}", source=str(path))


def _check(path: Path, st: os.stat_result) -> None:
    """Refuse a key file that is not a regular file of this user's, private to that user."""
    remove = f"remove it (rm {path}); hlaid makes a new one (outputs signed with the old one are then no longer " \
             "replaced by --force)"
    if stat.S_ISLNK(st.st_mode):
        raise _refuse(path, "is a symbolic link, not a file of yours", remove)
    if stat.S_ISDIR(st.st_mode):
        raise _refuse(path, "is a folder", f"remove it (rmdir {path}); hlaid makes a new key")
    if not stat.S_ISREG(st.st_mode):
        raise _refuse(path, "is not a regular file (a FIFO, socket or device)", remove)
    if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        raise _refuse(path, f"belongs to another user (uid {st.st_uid})", remove)
    if os.name == "posix" and st.st_mode & 0o077:
        raise _refuse(path, f"may be read or written by others (mode {stat.S_IMODE(st.st_mode):04o}): anyone who read "
                            "it can sign an output that --force then deletes", remove)


def _read(path: Path) -> bytes | None:
    """The key in ``path`` (checked by :func:`_check` before it is opened), None when absent."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    _check(path, st)
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)
    try:
        now = os.fstat(fd)
        if (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino):  # swapped between the check and the open
            _check(path, now)
            raise _refuse(path, "changed while it was opened", "run the command again")
        _check(path, now)
        raw = os.read(fd, 200).strip()
    finally:
        os.close(fd)
    return raw


def signing_key(create: bool = True) -> bytes | None:
    """The key that signs output markers (made, mode 0600, where there is none and ``create``), or None
    where there is no state folder (no home) or it cannot be read or written (:func:`problem` says
    why): markers are then unsigned and ``--force`` does not replace what they mark. An
    :class:`InputError` for a key file that is unsafe to use (:func:`_check`)."""
    global _problem
    from ._userdirs import state_root

    root = state_root()
    if root is None:
        _problem = "HOME names no folder, and neither HLAID_STATE_DIR nor XDG_STATE_HOME is set"
        return None
    path = root / "output-key"
    for _ in range(2):
        try:
            raw = _read(path)
        except InputError:
            raise
        except OSError as err:
            _problem = f"{path} cannot be read: {err.strerror or err}"
            return None
        if raw is not None:
            if len(raw) == 64 and all(c in b"0123456789abcdef" for c in raw):
                _problem = None
                return raw
            _problem = f"{path} holds no key hlaid wrote (remove it; hlaid makes a new one)"
            return None
        if not create:
            _problem = f"there is no key ({path})"
            return None
        _make(root, path)
    return None


def _make(root: Path, path: Path) -> None:
    global _problem
    tmp = root / f".output-key.{os.getpid()}-{secrets.token_hex(4)}.tmp"
    try:
        root.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.write(fd, secrets.token_hex(32).encode() + b"\n")
        finally:
            os.close(fd)
        os.link(tmp, path)  # complete or absent: another process never reads half a key
    except FileExistsError:
        pass  # another process made it meanwhile: read that one
    except OSError as err:
        _problem = f"{root} is not writable ({err.strerror or err})"
    finally:
        tmp.unlink(missing_ok=True)


def problem() -> str:
    """Why no key could be used (after :func:`signing_key` returned None)."""
    return _problem or "no key could be used"


def sign(body: dict, key: bytes) -> str:
    """The HMAC-SHA256 of ``body`` (without its ``signature``) under ``key``, hex."""
    text = json.dumps({k: v for k, v in body.items() if k != "signature"}, sort_keys=True, separators=(",", ":"))
    return hmac.new(key, text.encode(), hashlib.sha256).hexdigest()


def _tag(stem: str, pid: int, token: str, key: bytes | None) -> str | None:
    if key is None:
        return None
    return hmac.new(key, f"tmp\0{stem}\0{pid}\0{token}".encode(errors="surrogateescape"),
                    hashlib.sha256).hexdigest()[:12]


def temp_name(stem: str, *, old: bool = False, suffix: str = ".tmp") -> str:
    """A fresh name for a temporary output of ``stem`` (a random token and its tag, :mod:`this
    module <hlaid._outkey>`): ``.STEM.PID-TOKENTAG.tmp`` + ``suffix`` minus ``.tmp``, or with ``old`` the
    name a replaced folder is kept under, ``.STEM.old-PID-TOKENTAG``."""
    token = secrets.token_hex(4)
    try:
        key = signing_key()
    except InputError:
        key = None  # refused before the work by the output checks; here the name merely stays unswept
    tag = _tag(stem, os.getpid(), token, key) or UNTAGGED
    if old:
        return f".{stem}.old-{os.getpid()}-{token}{tag}"
    return f".{stem}.{os.getpid()}-{token}{tag}{suffix}"


UNTAGGED = "untagged0000"
"""The tag of a temporary name made without a key: never swept, skipped only by its own process."""

_NAME = re.compile(r"\.(?P<stem>.+)\.(?:(?P<pid>\d+)-(?P<tok>[0-9a-f]{8})(?P<tag>[0-9a-f]{12}|untagged0000)\.tmp.*|"
                   r"old-(?P<opid>\d+)-(?P<otok>[0-9a-f]{8})(?P<otag>[0-9a-f]{12}|untagged0000))\Z", re.S)


def made_here(name: str, stem: str | None = None, *, own: bool = False) -> tuple[int, bool] | None:
    """``(pid, is_old)`` of a temporary name hlaid made (:func:`temp_name`, its tag valid under this
    user's key; of ``stem`` where given), else None: a name of the user's, however it looks. With
    ``own``, also an untagged name of this process (made without a key)."""
    m = _NAME.match(name)
    if m is None or (stem is not None and m["stem"] != stem):
        return None
    old = m["opid"] is not None
    pid, tok, tag = (m["opid"], m["otok"], m["otag"]) if old else (m["pid"], m["tok"], m["tag"])
    if tag == UNTAGGED:
        return (int(pid), old) if own and int(pid) == os.getpid() else None
    try:
        key = signing_key(create=False)
    except InputError:
        return None
    want = _tag(m["stem"], int(pid), tok, key)
    if want is None or not hmac.compare_digest(want, tag):
        return None
    return int(pid), old


__all__ = ["signing_key", "problem", "sign", "temp_name", "made_here"]
