"""Shared fixtures of the verification tests.

- ``DATA``: the real third-party data of the project (``../shared/data`` next to the repository,
  resolved from this file, never an absolute path). Tests that read it take the ``data_dir``
  fixture (or are marked ``requires_data``) and are skipped cleanly when it is absent.
- Optional tools (:func:`requires`, :func:`import_optional`): a test that needs an extra the README's
  install (``pip install -e ".[test]"``) does not bring (pelicun, quakeio, mdof, a usable OpenSeesPy,
  a headless Chromium) is skipped with its reason when it is missing, under ``CI=true`` too: CI runs
  exactly the README's install and test command.
- The shared data (``requires(..., data=True)``, :func:`skip_or_fail`, ``data_dir``): skipped when
  absent, except under ``CI=true``, where it fails (CI runs beside a copy of ``../shared``).
- The paper's proof-of-concept structure (Table 1), built from the numbers in docs/DESIGN.md
  (``tests/reference_systems.py``), not from the package's config file.
- A few real records, scaled to PGA 0.62 g and resampled to 200 Hz (the paper's case). They are
  records shipped inside hlaid, so simulation tests run without ``../shared/data``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import NoReturn

import numpy as np
import pytest
from reference_systems import table1_stories  # tests/ is on sys.path (pytest's rootdir-relative import)

from hlaid.model import Building
from hlaid.motions import GroundMotion, load_builtin

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
"""The project's shared real data (ground motions, structural responses)."""

GROUND_MOTIONS = DATA / "ground_motions"

ON_CI = os.environ.get("CI", "").lower() == "true"
"""Under ``CI=true`` missing ``../shared/data`` fails the tests that read it (a missing optional tool
never does: it is skipped everywhere)."""


def skip_or_fail(reason: str) -> NoReturn:
    """Skip the running test because the shared data is missing (``reason``); under ``CI=true`` fail it
    instead. Not for optional tools: a test without one is skipped (:func:`requires`)."""
    if ON_CI:
        pytest.fail(f"{reason} (CI=true: the shared data must be at ../shared/data)", pytrace=False)
    pytest.skip(reason)


def import_optional(name: str, extra: str = ""):
    """``pytest.importorskip(name)`` for an optional dependency (at module level: the module's tests
    are skipped, never a collection error); ``extra`` says how to install it."""
    return pytest.importorskip(name, reason=f"{name} not installed{f' ({extra})' if extra else ''}")


def requires(available: bool, reason: str, *, data: bool = False) -> pytest.MarkDecorator:
    """Marker: the test needs an optional tool (or, with ``data``, the shared data); when not
    ``available`` it is skipped with ``reason`` (the shared data's absence fails under ``CI=true``,
    see :func:`skip_or_fail`)."""
    return pytest.mark.requires(available=bool(available), reason=reason, data=data)


def _opensees_missing() -> str | None:
    """Why OpenSeesPy cannot run here (not installed, or its shared libraries missing), or None."""
    from hlaid.opensees import OpenSeesUnavailable, import_opensees

    try:
        import_opensees()
    except OpenSeesUnavailable as e:
        return str(e)
    return None


OPENSEES_MISSING = _opensees_missing()
needs_opensees = requires(OPENSEES_MISSING is None, OPENSEES_MISSING or "")
"""Marker of the tests that run OpenSeesPy."""


def pytest_runtest_setup(item: pytest.Item) -> None:
    for mark in item.iter_markers("requires"):
        if not mark.kwargs["available"]:
            if mark.kwargs.get("data", False):
                skip_or_fail(mark.kwargs["reason"])
            pytest.skip(mark.kwargs["reason"])


requires_data = requires(GROUND_MOTIONS.is_dir(), f"shared data not found at {DATA}", data=True)
"""Marker for tests that read ``../shared/data``."""

RECORDS = ("elcentro-1940-ns", "kocaeli-1999-dzc180", "northridge-1994-mul009")
"""Built-in real records used by the simulation tests (El Centro 1940 N-S, Kocaeli Duzce 180
(FEMA P695 FF09), Northridge Beverly Hills - Mulhol 009 (FF01))."""

PGA_G = 0.62
RATE_HZ = 200.0


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """``../shared/data``; skips the test when the folder is not there (fails under ``CI=true``)."""
    if not GROUND_MOTIONS.is_dir():
        skip_or_fail(f"shared data not found at {DATA}")
    return DATA


@pytest.fixture(scope="session")
def table1() -> Building:
    """Table 1 of the paper: 3 stories, no P-Delta, 5% Rayleigh damping on modes 1 and 2."""
    return Building.from_stories(table1_stories(), name="table1", pdelta=False)


def paper_record(name: str) -> GroundMotion:
    """A built-in record at PGA 0.62 g, resampled to 200 Hz."""
    return load_builtin(name).scaled_to_pga(PGA_G).resampled(RATE_HZ)


@pytest.fixture(scope="session")
def records() -> dict[str, GroundMotion]:
    """The :data:`RECORDS` at 0.62 g and 200 Hz, by name."""
    return {name: paper_record(name) for name in RECORDS}


def window(gm: GroundMotion, seconds: float, before_peak: float = 3.0) -> GroundMotion:
    """A ``seconds`` long piece of ``gm`` that starts ``before_peak`` s before its PGA."""
    i0 = max(0, int(np.argmax(np.abs(gm.acc))) - int(round(before_peak / gm.dt)))
    n = int(round(seconds / gm.dt)) + 1
    return GroundMotion(dt=gm.dt, acc=gm.acc[i0:i0 + n], name=f"{gm.name}[{seconds:g}s]", source=gm.source)


def random_building(rng: np.random.Generator, n: int, **overrides) -> Building:
    """A random shear building with ``n`` stories in realistic ranges.

    Periods of about 0.1-1 s per story-mode; ``p`` in the paper's range [1, 3] and ``dy`` >= 2 mm,
    where fixed-step RK4 with 4 sub-steps at 100-200 Hz is stable (see test_simulate).
    """
    fields = {
        "mass": rng.uniform(5.0, 50.0, n),
        "k0": rng.uniform(5e3, 5e4, n),
        "alpha": rng.uniform(0.0, 1.0, n),
        "p": rng.uniform(1.0, 3.0, n),
        "dy": rng.uniform(2.0, 20.0, n),
        "delta_eta": rng.uniform(0.0, 3.0, n),
    }
    fields.update(overrides)
    return Building(**fields)


def story_drift(u: np.ndarray) -> np.ndarray:
    """Inter-story drift from floor displacements ``(..., story)``."""
    return u - np.concatenate([np.zeros_like(u[..., :1]), u[..., :-1]], axis=-1)


def rel_err(a: np.ndarray, ref: np.ndarray) -> float:
    """``max|a - ref| / max|ref|`` (NaNs, i.e. samples after an element's end, ignored)."""
    return float(np.nanmax(np.abs(a - ref)) / np.nanmax(np.abs(ref)))


def pytest_collection_finish(session: pytest.Session) -> None:
    """mypy, when its test is to run, starts now in the background (see ``test_static.start``); a run
    of many tests from a fresh clone compiles the numba kernels first, in parallel processes
    (``hlaid._warmup``), instead of one after the other inside the first tests that need them."""
    if any(item.nodeid.endswith("test_static.py::test_mypy_is_clean") for item in session.items):
        import test_static

        test_static.start("mypy", test_static.MYPY_ARGS)
    if len(session.items) >= 200 and not session.config.option.collectonly:
        from hlaid import _warmup

        _warmup.warm()


def pytest_sessionfinish(session: pytest.Session) -> None:
    test_static = sys.modules.get("test_static")
    if test_static is not None:
        test_static.stop()
