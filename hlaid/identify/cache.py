"""On-disk cache of trained classifiers, keyed by everything that made them.

The key hashes the identification settings, the excitation, the noise level, the current
estimate and the class bins: the same identification run again finds its machines here and
skips the simulations and the training. Every entry carries SHA-256 checksums that are
verified on load (see :class:`MachineCache`).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from .. import _progress
from .._fileio import json_default, write_json
from .._inputs import file_sha256, own_files, read_json
from .._version import __version__
from ..errors import InputError, one_line
from ..svm import KernelSVC


def default_cache_dir() -> Path | None:
    """``HLAID_CACHE/svm``, else ``~/.cache/hlaid/svm``; None (no cache, a warning) when ``HOME`` names
    no folder (unset, empty or relative: never ``/.cache``)."""
    from .._userdirs import cache_root

    base = os.environ.get("HLAID_CACHE") or cache_root()
    if base is None:
        _progress.warn("HOME names no folder, so trained classifiers are not cached; set HLAID_CACHE or --cache "
                       "to keep them")
        return None
    return Path(base) / "svm"


def _canon(o):
    if isinstance(o, dict):
        return {str(k): _canon(v) for k, v in sorted(o.items())}
    if isinstance(o, (list, tuple)):
        return [_canon(v) for v in o]
    if isinstance(o, np.ndarray):
        return _canon(o.tolist())
    if isinstance(o, (float, np.floating)):
        return float(f"{float(o):.6g}")
    if isinstance(o, (np.integer,)):
        return int(o)
    return o


def cache_key(**parts) -> str:
    """Stable hash of JSON-able parts (floats rounded to 6 significant digits)."""
    blob = json.dumps({"version": __version__, **_canon(parts)}, sort_keys=True).encode()
    return hashlib.sha256(blob).hexdigest()[:24]


def array_digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a, dtype=np.float64).tobytes()).hexdigest()[:16]


def _clear(path: Path) -> None:
    """Remove what stands where a cache file is to be written, unless it is a regular file (a
    folder, a FIFO or a device put there would make every later store fail)."""
    if path.is_symlink() or (path.exists() and not path.is_file()):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


def _sha256_json(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()


class _Untrusted(Exception):
    """A cache entry that is there but must not be used (the message says why)."""


class MachineCache:
    """A folder of ``<key>/`` entries: ``<name>.svm`` machines and ``meta.json``.

    ``meta.json`` is written last and holds an ``integrity`` record: the entry's key and the
    SHA-256 of every machine file and of the metadata itself. :meth:`load` verifies all of it;
    an entry that fails (damaged, truncated, swapped with another key's, written by an older
    hlaid without checksums) is reported with a warning and treated as absent, so the caller
    retrains and :meth:`store` replaces it.
    """

    def __init__(self, root: str | os.PathLike | None):
        self.root = Path(root) if root else None

    def load(self, key: str):
        """``(machines, meta)``, or None when absent or when the entry fails its integrity check
        (with a warning)."""
        if self.root is None:
            return None
        d = self.root / key
        if not os.path.lexists(d / "meta.json"):
            return None
        try:
            with own_files():  # the cache's own files, rewritten by store(): no inputs of the run
                return self._verified(d, key)
        except _Untrusted as why:
            _progress.warn(f"classifier cache entry {key} failed its integrity check ({why}); retraining")
            return None

    @staticmethod
    def _verified(d: Path, key: str):
        try:  # a regular file within HLAID_MAX_FILE_MB, nested and numbered as hlaid writes it
            meta = read_json(d / "meta.json")
        except InputError as err:
            raise _Untrusted(f"meta.json is unreadable: {err.detail}") from None
        if not isinstance(meta, dict) or not isinstance(meta.get("integrity"), dict):
            raise _Untrusted("no checksums (an entry of an older hlaid, or not an hlaid cache entry)")
        seal = meta.pop("integrity")
        if seal.get("key") != key:
            raise _Untrusted(f"it holds the entry of key {str(seal.get('key'))[:40]!r}")
        if seal.get("meta_sha256") != _sha256_json(meta):
            raise _Untrusted("meta.json does not match its checksum")
        files = seal.get("files")
        if not isinstance(files, dict) or not isinstance(meta.get("machines"), list):
            raise _Untrusted("meta.json lists no machines")
        machines: dict[str, KernelSVC | None] = {}
        for name in meta["machines"]:
            if name not in files:  # stored as None (nothing trained)
                machines[name] = None
                continue
            path = d / f"{name}.svm"
            try:
                ok = file_sha256(path) == files[name]
            except InputError as err:
                raise _Untrusted(f"{path.name} is missing or unreadable: {err.detail}") from None
            if not ok:
                raise _Untrusted(f"{path.name} does not match its checksum")
            try:
                machines[name] = KernelSVC.load(path)
            except (OSError, ValueError) as err:
                raise _Untrusted(f"{path.name}: {one_line(err, 120)}") from None
        return machines, meta

    def store(self, key: str, machines: dict, meta: dict) -> None:
        if self.root is None:
            return
        d = self.root / key
        try:
            d.mkdir(parents=True, exist_ok=True)
            _clear(d / "meta.json")
            (d / "meta.json").unlink(missing_ok=True)  # an entry half rewritten is a plain miss, not a stale one
            files = {}
            for name, m in machines.items():
                if m is not None:
                    _clear(d / f"{name}.svm")
                    m.save(d / f"{name}.svm", force=True)  # replaces a stale entry's file
                    with own_files():
                        files[name] = file_sha256(d / f"{name}.svm")
            body = json.loads(json.dumps({**meta, "machines": list(machines)}, default=json_default))
            seal = {"key": key, "meta_sha256": _sha256_json(body), "files": files}
            write_json(d / "meta.json", {**body, "integrity": seal})
        except (OSError, InputError) as err:  # a read-only (or damaged) cache is not an error
            _progress.debug(f"classifier cache entry {key} not stored: {err}")
