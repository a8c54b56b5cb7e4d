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


def _check(name: str, args: list[str], timeout: float) -> None:
    """Run ``name args`` in the repository; fail with its output unless it exits 0."""
    p = subprocess.run([*_tool(name), *args], cwd=REPO, capture_output=True, text=True, timeout=timeout, check=False)
    if p.returncode != 0:
        pytest.fail(f"{name} {' '.join(args)} failed (exit {p.returncode}):\n{p.stdout}{p.stderr}", pytrace=False)


def test_ruff_is_clean():
    _check("ruff", ["check", "--no-cache", "hlaid", "tests", "scripts"], timeout=120)


def test_mypy_is_clean():
    _check("mypy", ["--cache-dir", os.devnull], timeout=600)
