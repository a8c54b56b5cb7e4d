"""Lint (ruff) and types (mypy) as tests, so that they run with every ``python -m pytest``.

Both read their configuration from ``pyproject.toml``: ruff E, F, I, B, UP at 120 columns over
``hlaid``, ``tests`` and ``scripts``; mypy over every module of ``hlaid``, with no baseline of
ignored modules left, so any error fails. A missing
tool skips the test, except under ``CI=true``, where it fails.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

def _tool(name: str) -> list[str]:
    """Command line that runs ``name`` (its executable, else ``python -m name``); skips or, under CI, fails."""
    exe = shutil.which(name)
    if exe:
        return [exe]
    probe = subprocess.run([sys.executable, "-m", name, "--version"], capture_output=True, text=True, check=False)
    if probe.returncode == 0:
        return [sys.executable, "-m", name]
    if os.environ.get("CI") == "true":
        pytest.fail(f"{name} is not installed (CI=true): pip install -e '.[test]'")
    pytest.skip(f"{name} is not installed")


_STARTED: dict[str, subprocess.Popen] = {}
"""Checks started ahead by :func:`start` (the test run's collection), by tool name."""

MYPY_ARGS: list[str] = []
"""mypy's arguments: the configuration is pyproject's; its incremental cache is ``.mypy_cache``
(git-ignored): about a minute from a fresh clone, seconds once the cache is there."""


def start(name: str, args: list[str]) -> None:
    """Start ``name args`` now, in the background at a lower priority, for :func:`_check` to collect:
    mypy's minute runs on the second core while the other tests run on the first."""
    if name not in _STARTED and (shutil.which(name) or _tool_module(name)):
        nice = ["nice", "-n", "5"] if shutil.which("nice") else []
        _STARTED[name] = subprocess.Popen([*nice, *_tool(name), *args], cwd=REPO, stdout=subprocess.PIPE,
                                          stderr=subprocess.STDOUT, text=True)


def stop() -> None:
    """End the checks started ahead whose test did not run (a run stopped early, ``-x``)."""
    for p in _STARTED.values():
        if p.poll() is None:
            p.kill()
            p.wait()
    _STARTED.clear()


def _tool_module(name: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(name) is not None


def _check(name: str, args: list[str], timeout: float) -> None:
    """Run ``name args`` in the repository (or collect the run :func:`start` began); fail with its
    output unless it exits 0."""
    p = _STARTED.pop(name, None) or subprocess.Popen([*_tool(name), *args], cwd=REPO, stdout=subprocess.PIPE,
                                                     stderr=subprocess.STDOUT, text=True)
    try:
        out, _ = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        out, _ = p.communicate()
        pytest.fail(f"{name} {' '.join(args)} ran over {timeout:g} s:\n{out}", pytrace=False)
    if p.returncode != 0:
        pytest.fail(f"{name} {' '.join(args)} failed (exit {p.returncode}):\n{out}", pytrace=False)


def test_ruff_is_clean():
    _check("ruff", ["check", "--no-cache", "hlaid", "tests", "scripts"], timeout=120)


def test_mypy_is_clean():
    _check("mypy", MYPY_ARGS, timeout=600)
