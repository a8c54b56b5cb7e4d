"""On-disk cache of trained classifiers, keyed by everything that made them.

The key hashes the identification settings, the excitation, the noise level, the current
estimate and the class bins: the same identification run again finds its machines here and
skips the simulations and the training.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from .. import __version__
from .._fileio import write_json
from ..svm import KernelSVC


def default_cache_dir() -> Path:
    base = os.environ.get("HLAID_CACHE") or os.path.join(os.environ.get("XDG_CACHE_HOME") or
                                                          os.path.expanduser("~/.cache"), "hlaid")
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


class MachineCache:
    """A folder of ``<key>/`` entries: ``<name>.svm`` machines and ``meta.json``."""

    def __init__(self, root: str | os.PathLike | None):
        self.root = Path(root) if root else None

    def load(self, key: str):
        """``(machines, meta)`` or None when absent or unreadable."""
        if self.root is None:
            return None
        d = self.root / key
        try:
            meta = json.loads((d / "meta.json").read_text())
            machines = {name: (KernelSVC.load(d / f"{name}.svm") if (d / f"{name}.svm").exists() else None)
                        for name in meta["machines"]}
        except (OSError, ValueError, KeyError):
            return None
        return machines, meta

    def store(self, key: str, machines: dict, meta: dict) -> None:
        if self.root is None:
            return
        d = self.root / key
        try:
            d.mkdir(parents=True, exist_ok=True)
            for name, m in machines.items():
                if m is not None:
                    m.save(d / f"{name}.svm")
            write_json(d / "meta.json", {**meta, "machines": list(machines)})
        except OSError:  # a read-only cache is not an error
            pass
