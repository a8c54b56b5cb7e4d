"""The README's quick start runs as written.

The code blocks of the README's "Quick start" section are taken from the file itself: every
``hlaid ...`` line of its ``bash`` block is run as ``python -m hlaid ...`` in a temporary folder
holding a copy of ``configs/`` (as a user runs them from the repository root), and its
``python`` block is run as a script in an empty folder. Both share one classifier cache, so the
second identification of the same measurement loads the first one's classifiers.

What is asserted, beyond every command exiting 0: the clone of the command line is within 5 % of
the Table 1 building it was simulated from (the identification study's worst parameter over 15
such runs is 4.3 %, README), and the Python route gives the same clone as the command line.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from reference_systems import TABLE1

REPO = Path(__file__).resolve().parents[1]
PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")


def quick_start_blocks(readme: Path = REPO / "README.md") -> dict[str, list[str]]:
    """``{"bash": [...], "python": [...]}``: the fenced code blocks of the "Quick start" section."""
    text = readme.read_text(encoding="utf-8")
    section = re.search(r"^## Quick start\n(.*?)(?=^## )", text, flags=re.S | re.M)
    assert section, "README.md has no '## Quick start' section"
    blocks: dict[str, list[str]] = {"bash": [], "python": []}
    for lang, body in re.findall(r"^```(\w+)\n(.*?)^```", section.group(1), flags=re.S | re.M):
        blocks.setdefault(lang, []).append(body)
    return blocks


def _env(cache: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    env["HLAID_CACHE"] = str(cache)
    env["MPLBACKEND"] = "Agg"
    return env


def _run(args: list[str], cwd: Path, cache: Path) -> None:
    p = subprocess.run(args, cwd=cwd, env=_env(cache), capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, f"{' '.join(args)} exited {p.returncode}:\n{p.stdout[-2000:]}\n{p.stderr[-4000:]}"


def _building(clone_file: Path) -> dict[str, np.ndarray]:
    stories = json.loads(clone_file.read_text(encoding="utf-8"))["stories"]
    return {k: np.array([s[k] for s in stories]) for k in PARAMS}


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("classifier-cache")


@pytest.fixture(scope="module")
def cli_folder(tmp_path_factory, cache) -> Path:
    """The quick start's command lines, run in a folder with a copy of ``configs/``."""
    (bash,) = quick_start_blocks()["bash"]
    work = tmp_path_factory.mktemp("quickstart-cli")
    shutil.copytree(REPO / "configs", work / "configs")
    commands = [shlex.split(line, comments=True) for line in bash.splitlines()]
    commands = [c for c in commands if c]
    assert len(commands) >= 3 and all(c[0] == "hlaid" for c in commands), commands
    for c in commands:
        _run([sys.executable, "-m", "hlaid", *c[1:]], work, cache)
    return work


@pytest.fixture(scope="module")
def python_folder(tmp_path_factory, cache) -> Path:
    """The quick start's Python block, run as a script in an empty folder."""
    (code,) = quick_start_blocks()["python"]
    work = tmp_path_factory.mktemp("quickstart-python")
    (work / "quickstart.py").write_text(code, encoding="utf-8")
    _run([sys.executable, "quickstart.py"], work, cache)
    return work


def test_quick_start_command_lines_identify_table1(cli_folder):
    clone = _building(cli_folder / "clone.json")
    for k in PARAMS:
        err = np.abs(clone[k] / np.asarray(TABLE1[k]) - 1.0)
        assert err.max() < 0.05, f"{k}: identified {clone[k]}, true {TABLE1[k]}"
    summary = json.loads((cli_folder / "ida-out" / "summary.json").read_text(encoding="utf-8"))
    assert len(summary["records"]) == 10  # builtin-suite: the ten built-in far-field records
    # the demo's building, the demo's collapse law: the structural system named on the command line
    assert any("collapse model 'steel-mrf' chosen for the clone's structural system" in n for n in summary["notes"])


@pytest.mark.slow  # the whole quick start again, through Python
def test_quick_start_python_gives_the_command_lines_clone(cli_folder, python_folder):
    py, cli = _building(python_folder / "clone.json"), _building(cli_folder / "clone.json")
    for k in PARAMS:
        np.testing.assert_allclose(py[k], cli[k], rtol=1e-6, err_msg=k)
