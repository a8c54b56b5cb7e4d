"""Compile the slow numba kernels ahead, in parallel processes, when their cache is empty.

A fresh install compiles its kernels the first time a command needs them, one after the other:
about 130 s of CPU for what ``hlaid demo`` uses, 45 s of it the path drive of the identification's
training (:func:`hlaid.simulate.path._drive`). :func:`warm` compiles them in three processes at
once (the path drive; the replay, tangent and collapse kernels; the kernel machines' solver, as
the main process and as a pool worker run it) on tiny problems that call them with the argument
types of the real work, and waits; numba's cache (:mod:`hlaid._jitcache`) then hands them to the
command. With the cache already filled it does nothing (it looks for the kernels' index files,
without importing numba)."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

from . import _jitcache

GROUPS = ("path", "replay", "svm")
"""The processes :func:`warm` starts, each compiling the kernels of :func:`_compile`."""

_KERNELS = (("simulate", "path._drive"), ("simulate", "sensitivity.integrate_tangent"),
            ("simulate", "_kernel.integrate"), ("simulate", "_kernel.integrate_collapse"),
            ("svm", "_solver._solve_serial"))
"""(subpackage, module.function) of the kernels whose index files say the cache is filled."""


def _cache_folder(sub: str) -> Path:
    folder = _jitcache._PACKAGE / sub
    user = os.environ.get("NUMBA_CACHE_DIR")
    if not user:
        return folder / "__pycache__"
    path = os.path.abspath(folder)  # numba's UserProvidedCacheLocator: parent name + SHA-1 of the path
    return Path(user) / f"{os.path.basename(path)}_{hashlib.sha1(path.encode()).hexdigest()}"


def is_cold() -> bool:
    """Whether a kernel of :data:`_KERNELS` has no cache index yet (caching on)."""
    if _jitcache.configure() == "off":
        return False
    return any(not any(_cache_folder(sub).glob(f"{name}-*.nbi")) for sub, name in _KERNELS)


def warm(timeout: float = 900.0) -> bool:
    """Compile the kernels in :data:`GROUPS` processes at once when the cache is cold and the machine
    has 2 or more cores; returns whether it ran. A process that fails leaves its kernels to be
    compiled where they are first used, as without this."""
    if (os.cpu_count() or 1) < 2 or not is_cold():
        return False
    procs = [subprocess.Popen([sys.executable, "-m", "hlaid._warmup", g], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL) for g in GROUPS]
    try:
        for p in procs:
            p.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        pass
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    return True


def _compile(group: str) -> None:
    """Call the ``group``'s kernels on tiny problems (their types as in the real work)."""
    import numpy as np

    if group == "path":
        from .simulate.path import drive_story

        x = 5.0 * np.sin(np.linspace(0.0, 6.0, 60))[None]
        drive_story(x, k0=[2e4, 1.5e4], alpha=[0.2, 0.1], p=[2.0, 1.5], dy=[5.0, 4.0], delta_eta=[0.5, 0.5],
                    mass=100.0, dt=0.01, velocity=np.gradient(x, 0.01, axis=1))
        return
    if group == "svm":
        import numba

        from .svm import KernelSVC

        rng = np.random.default_rng(0)
        X, y = rng.normal(size=(30, 3)), np.repeat([0, 1, 2], 10)
        KernelSVC().fit(X, y)  # the problems in parallel (the main process)
        numba.set_num_threads(1)  # and one after the other (as a pool worker solves them)
        KernelSVC().fit(X, y)
        return
    from .hla.halfcycles import reversals
    from .ida import response_spectrum
    from .model import Building
    from .motions import GroundMotion
    from .simulate import sensitivity, simulate_response
    from .simulate.tangent import ground_tangent

    gm = GroundMotion(dt=0.01, acc=2000.0 * np.sin(np.linspace(0.0, 12.0, 120)), name="warm-up")
    b = Building(mass=np.full(2, 100.0), k0=np.full(2, 2e4), alpha=np.full(2, 0.2), p=np.full(2, 2.0),
                 dy=np.full(2, 5.0), delta_eta=np.full(2, 0.5), height=np.full(2, 3000.0))
    simulate_response(b, gm)
    simulate_response(b.replace(collapse="steel-mrf"), gm)
    with sensitivity.linearised():
        simulate_response([b, b.replace(k0=np.full(2, 2.1e4))], gm, outputs="acc")
    ground_tangent(b, gm, lags=10)
    reversals(np.sin(np.linspace(0.0, 20.0, 200)), 0.1)
    response_spectrum(gm, [0.5, 1.0])


if __name__ == "__main__":
    _compile(sys.argv[1])
