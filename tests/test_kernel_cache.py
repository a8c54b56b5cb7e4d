"""The kernels' numba cache (hlaid._jitcache): a user with no usable home on an install they cannot
write still runs every command (the cache goes to a private temp folder, or is turned off), never
numba's "cannot cache function ...: no locator available"."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from test_hostile import _measurement

import hlaid
from hlaid import _jitcache

REPO = Path(__file__).resolve().parents[1]
PACKAGE = Path(hlaid.__file__).resolve().parent

READ_ONLY_INSTALL = """
import os, sys, tempfile
PACKAGE, EVERYWHERE = sys.argv[1], sys.argv[2] == "1"
_temporary_file = tempfile.TemporaryFile
def refuse(*a, dir=None, **k):  # the package (or every folder) cannot be written, as for a user on root's install
    if dir is not None and (EVERYWHERE or os.path.abspath(dir).startswith(PACKAGE)):
        raise PermissionError(13, "Permission denied", dir)
    return _temporary_file(*a, dir=dir, **k)
tempfile.TemporaryFile = refuse
from hlaid._jitcache import configure
print("cache:", configure(), flush=True)
"""


def _run(code: str, tmp: Path, *args: str, everywhere: bool = False) -> subprocess.CompletedProcess:
    home = tmp / "home"
    home.write_text("HOME names a file: no folder can be made in it\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("XDG_", "NUMBA_CACHE"))}
    env.update(HOME=str(home), TMPDIR=str(tmp / "temp"), PYTHONPATH=str(REPO))
    (tmp / "temp").mkdir()
    return subprocess.run([sys.executable, "-c", READ_ONLY_INSTALL + code, str(PACKAGE), "01"[everywhere], *args],
                          capture_output=True, text=True, env=env, cwd=tmp, timeout=600)


def test_a_user_without_home_on_a_read_only_install_runs_hla(tmp_path, table1):
    meas = _measurement(tmp_path / "meas.npz", table1)
    p = _run("from hlaid.cli import main\nsys.exit(main(sys.argv[3:]))", tmp_path, "hla", str(meas), "-o",
             str(tmp_path / "out"))
    assert p.returncode == 0, p.stderr
    assert "cache: temp" in p.stdout and "cannot cache" not in p.stderr
    private = tmp_path / "temp" / f"hlaid-numba-{os.getuid()}"
    assert oct(private.stat().st_mode & 0o777) == "0o700"
    assert any(private.rglob("halfcycles.reversals-*.nbi")), "the kernel is cached in the private folder"
    assert (tmp_path / "out" / "hla.json").is_file()


def test_nothing_writable_compiles_without_a_cache(tmp_path):
    code = ("import numpy as np\nfrom hlaid.hla.halfcycles import reversals\n"
            "print(*reversals(np.sin(np.linspace(0, 20, 400)), 0.1))")
    p = _run(code, tmp_path, everywhere=True)
    assert p.returncode == 0, p.stderr
    from hlaid.hla.halfcycles import reversals

    expected = reversals(np.sin(np.linspace(0, 20, 400)), 0.1)
    assert p.stdout.split() == ["cache:", "off", *map(str, expected)]
    assert not [p for p in (tmp_path / "temp").rglob("*") if p.is_file()], "nothing cached"


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """``configure`` run again in this process, with numba's config replaced by a recorder."""
    monkeypatch.setattr(_jitcache, "_chosen", None)
    reloads: list[str | None] = []
    fake = types.SimpleNamespace(reload_config=lambda: reloads.append(os.environ.get("NUMBA_CACHE_DIR")))
    monkeypatch.setitem(sys.modules, "numba.core.config", fake)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(_jitcache.tempfile, "tempdir", str(tmp_path))
    return reloads


def test_the_package_folder_comes_first_when_it_can_be_written(fresh, monkeypatch, tmp_path):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "file" / "x"))
    (tmp_path / "file").write_text("")
    assert _jitcache.configure() == "in-tree" and "NUMBA_CACHE_DIR" not in os.environ
    assert fresh == [None], "numba imported before hlaid reads the folder again"


def test_a_users_numba_cache_dir_is_kept(fresh, monkeypatch, tmp_path):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert _jitcache.configure() == "user" and os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")


def test_a_read_only_install_uses_the_users_cache_folder(fresh, monkeypatch, tmp_path):
    monkeypatch.setattr(_jitcache, "_PACKAGE", tmp_path / "pkg-is-a-file")
    (tmp_path / "pkg-is-a-file").write_text("")
    assert _jitcache.configure() == "cache"
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "home" / ".cache" / "hlaid" / "numba")


def test_a_temp_folder_another_user_can_write_is_not_used(fresh, monkeypatch, tmp_path):
    monkeypatch.setattr(_jitcache, "_PACKAGE", tmp_path / "pkg-is-a-file")
    (tmp_path / "pkg-is-a-file").write_text("")
    monkeypatch.setenv("HOME", "")
    monkeypatch.setattr(_jitcache, "_disable_caching", lambda: fresh.append("off"))
    shared = tmp_path / f"hlaid-numba-{os.getuid()}"
    shared.mkdir()
    shared.chmod(0o777)
    assert _jitcache.configure() == "off" and "off" in fresh
    shared.chmod(0o700)
    monkeypatch.setattr(_jitcache, "_chosen", None)
    assert _jitcache.configure() == "temp" and os.environ["NUMBA_CACHE_DIR"] == str(shared)


def test_every_cached_kernel_lives_where_the_package_folder_is_checked():
    import importlib
    import inspect

    from numba.core.caching import NullCache
    from numba.core.dispatcher import Dispatcher

    for name in ("simulate._kernel", "simulate.path", "simulate.tangent", "simulate.sensitivity", "hla.halfcycles",
                 "svm._solver", "svm._batch", "ida._spectrum"):
        importlib.import_module(f"hlaid.{name}")
    cached = {Path(inspect.getfile(d.py_func)).resolve().relative_to(PACKAGE).parts[0]
              for m in list(sys.modules.values()) if getattr(m, "__name__", "").startswith("hlaid.")
              for d in vars(m).values() if isinstance(d, Dispatcher) and not isinstance(d._cache, NullCache)}
    sources = {p.relative_to(PACKAGE).parts[0] for p in PACKAGE.rglob("*.py")
               if re.search(r"njit\([^)]*cache\s*=\s*True", p.read_text())}
    assert {"model", "simulate"} <= cached and sources <= set(_jitcache.KERNEL_PACKAGES)
    assert cached <= set(_jitcache.KERNEL_PACKAGES), cached


# ---------------------------------------------------------------------------- kernels compiled ahead
def test_the_warm_up_finds_numbas_own_cache_folders(monkeypatch, tmp_path):
    from numba.core import config
    from numba.core.caching import UserProvidedCacheLocator

    from hlaid import _warmup
    from hlaid.simulate import path

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path))
    loc = UserProvidedCacheLocator(path._drive.py_func, path.__file__)
    assert _warmup._cache_folder("simulate") == Path(loc.get_cache_path())
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert _warmup._cache_folder("simulate") == Path(path.__file__).parent / "__pycache__"


def test_the_warm_up_runs_only_on_a_cold_cache(monkeypatch, tmp_path):
    from hlaid import _warmup

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(_jitcache, "_chosen", "user")
    assert _warmup.is_cold()
    started = []
    monkeypatch.setattr(_warmup.subprocess, "Popen", lambda *a, **k: started.append(a) or subprocess.run(["true"]))
    for sub, name in _warmup._KERNELS:
        folder = _warmup._cache_folder(sub)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"{name}-12.py311.nbi").write_bytes(b"")
    assert not _warmup.is_cold() and not _warmup.warm() and not started
    monkeypatch.setattr(_jitcache, "_chosen", "off")
    (folder / f"{name}-12.py311.nbi").unlink()
    assert not _warmup.is_cold(), "no cache, nothing to warm"


@pytest.mark.slow  # compiles every kernel from an empty cache (about 100 s of CPU)
def test_the_warm_up_compiles_what_the_demo_uses(tmp_path):
    """After the warm-up the demo's pipeline compiles no kernel: the tiny problems call them with the
    argument types of the real work."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / "nb"), HLAID_CACHE=str(tmp_path / "svm"), PYTHONPATH=str(REPO))
    code = ("from hlaid import _warmup\nassert _warmup.warm()\nfrom numba.core import event\nn = []\n"
            "class L(event.Listener):\n    def on_start(self, ev): pass\n"
            "    def on_end(self, ev): n.append(ev.data['dispatcher'].py_func.__qualname__)\n"
            "event.register('numba:compile', L())\nfrom hlaid.demo import run_demo\nrun_demo('out')\nprint(n)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path,
                       timeout=1800)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.strip().splitlines()[-1] == "[]"
