"""Every shell and Python block of README.md and docs/*.md runs as written, or says why it does not.

A fenced block whose language is a shell (``bash``, ``sh``, ``shell``) or ``python`` is an
example. HTML comments on the lines just above its fence tell this test what to do with it:

- ``<!-- not run: REASON -->``: not run (the reason is required and said in the skip);
- ``<!-- run by: tests/FILE.py -->``: another test runs it (the file must exist and name the page);
- ``<!-- needs: meas.npz, clone.json, data, openseespy, pelicun -->``: what it needs: files made
  first in its folder (``meas.npz``: the README's simulated measurement; ``clone.json``: its
  clone), ``data`` (the real datasets as ``data/``, docs/data.md#getting-the-data), an optional
  package; without one that block is left out, the page's others still run, and the test is
  skipped at the end (failed under ``CI=true``);
- ``<!-- run: fast -->``: also run by the default test run (every other example is ``slow``).

The blocks of one page run in order in one folder (a later block may use what an earlier one
wrote), with a copy of ``configs/`` and the datasets linked as ``data/``; a shell block runs in
``bash -e`` with ``hlaid`` and ``python`` being this interpreter, a Python block as a script.
Every block must exit 0. Fenced blocks in any other language are not examples (``text``,
``yaml``); every fence must name its language, so no shell block goes unseen.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import DATA, skip_or_fail

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
SHELLS = {"bash", "sh", "shell"}
LANGS = SHELLS | {"python"}
FENCE = re.compile(r"^```(\S*)[^\n]*\n(.*?)^```[ \t]*$", flags=re.S | re.M)
MARK = re.compile(r"<!--\s*(not run|run by|needs|run)\s*:\s*(.*?)\s*-->")

RECIPES = {
    "meas.npz": [["simulate", "configs/poc_3story.yaml", "-o", "meas.npz"]],
    "clone.json": [["simulate", "configs/poc_3story.yaml", "-o", "meas.npz"], ["identify", "meas.npz", "-o",
                                                                               "clone.json"]],
}
"""Files a block may need and the ``hlaid`` commands that make them (the README's quick start)."""

PACKAGES = {"openseespy": "openseespy.opensees", "pelicun": "pelicun", "dask": "distributed", "obspy": "obspy"}


@dataclass
class Block:
    page: Path
    line: int
    lang: str
    code: str
    marks: dict[str, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"

    @property
    def needs(self) -> list[str]:
        return [n.strip() for n in self.marks.get("needs", "").split(",") if n.strip()]

    @property
    def runs_here(self) -> bool:
        return "not run" not in self.marks and "run by" not in self.marks


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of ``page`` with the markers of the comment lines just above each."""
    text = page.read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        above = text[: m.start()].splitlines()
        marks: dict[str, str] = {}
        while above and above[-1].strip().startswith("<!--"):
            for key, value in MARK.findall(above.pop()):
                marks[key] = value
        out.append(Block(page, line, m.group(1).lower(), m.group(2), marks))
    return out


def examples(page: Path | None = None) -> list[Block]:
    return [b for p in ([page] if page else PAGES) for b in blocks(p) if b.lang in LANGS]


# ----------------------------------------------------------------------------- the markers
def test_every_fence_names_its_language():
    untagged = [b.name for p in PAGES for b in blocks(p) if not b.lang]
    assert untagged == [], f"fenced blocks without a language (text, bash, python, yaml, ...): {untagged}"


def test_every_example_is_run_or_says_why_not():
    found = examples()
    assert len(found) >= 25  # the walk found the examples
    for b in found:
        unknown = set(b.marks) - {"not run", "run by", "needs", "run"}
        assert not unknown, (b.name, unknown)
        if "not run" in b.marks:
            assert len(b.marks["not run"]) >= 10, f"{b.name}: say why it is not run"
        if "run by" in b.marks:
            test = REPO / b.marks["run by"]
            assert test.is_file() and b.page.name in test.read_text(encoding="utf-8"), (b.name, b.marks["run by"])
        for need in b.needs:
            assert need in RECIPES or need in PACKAGES or need == "data", (b.name, need)
        if b.runs_here:
            assert "../shared" not in b.code, f"{b.name}: the datasets are data/ (docs/data.md#getting-the-data)"
    run = [b for b in found if "not run" not in b.marks]
    assert len(run) >= 0.6 * len(found), "most examples must run"


def test_docs_do_not_point_outside_the_repository():
    """A user clones the repository: the datasets are named by their public source, not by a
    folder beside the checkout."""
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        assert "../shared" not in text, f"{page.name} points at ../shared (outside the repository)"


# ----------------------------------------------------------------------------- running them
def _missing(b: Block) -> str | None:
    """What block ``b`` needs that is not here (the datasets, a package), or None."""
    for need in b.needs:
        if need == "data" and not DATA.is_dir():
            return f"the datasets (not found at {DATA})"
        if need in PACKAGES and importlib.util.find_spec(PACKAGES[need].split(".")[0]) is None:
            return need
        if need == "openseespy":
            from hlaid.opensees import OpenSeesUnavailable, import_opensees
            try:
                import_opensees()
            except OpenSeesUnavailable:
                return "a usable openseespy"
    return None


def _folder(tmp: Path, page_blocks: list[Block], cache: Path) -> tuple[Path, dict]:
    work = tmp / "work"
    work.mkdir()
    shutil.copytree(REPO / "configs", work / "configs")
    if DATA.is_dir():
        (work / "data").symlink_to(DATA)
    bin_dir = tmp / "bin"
    bin_dir.mkdir()
    shims = {"hlaid": f'exec "{sys.executable}" -m hlaid "$@"', "python": f'exec "{sys.executable}" "$@"'}
    for name, body in shims.items():
        shim = bin_dir / name
        shim.write_text(f"#!/bin/sh\n{body}\n")
        shim.chmod(0o755)
    env = dict(os.environ)
    env.update(PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])]),
               HLAID_CACHE=str(cache), MPLBACKEND="Agg", PATH=f"{bin_dir}{os.pathsep}{env['PATH']}")
    made: set[str] = set()
    for b in page_blocks:
        for need in b.needs:
            for cmd in RECIPES.get(need, []):
                if cmd[cmd.index("-o") + 1] not in made:
                    _run([sys.executable, "-m", "hlaid", *cmd], work, env, f"making {need} for {b.name}")
                    made.add(cmd[cmd.index("-o") + 1])
    return work, env


def _run(args: list[str], cwd: Path, env: dict, what: str) -> None:
    p = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=3000)
    assert p.returncode == 0, f"{what} exited {p.returncode}:\n{p.stdout[-3000:]}\n{p.stderr[-5000:]}"


def _run_page(page: Path, tmp: Path, cache: Path, *, fast_only: bool) -> None:
    """Run the page's examples in order; one that needs what is not here is left out (and the test
    skipped once the others have run; failed under ``CI=true`` when what it lacks is the shared data)."""
    run = [b for b in examples(page) if b.runs_here and (b.marks.get("run") == "fast" or not fast_only)]
    if not run:
        pytest.skip(f"{page.name}: no example to run here")
    left_out = [(b, why) for b in run if (why := _missing(b)) is not None]
    run = [b for b in run if _missing(b) is None]
    if run:
        work, env = _folder(tmp, run, cache)
        for k, b in enumerate(run):
            script = work / (f".block{k}.sh" if b.lang in SHELLS else f".block{k}.py")
            script.write_text(b.code)
            _run(["bash", "-e", str(script)] if b.lang in SHELLS else [sys.executable, str(script)], work, env,
                 b.name)
    if left_out:
        why = ("; ".join(f"{b.name} needs {why}" for b, why in left_out)
               + (f" (the page's other {len(run)} example(s) ran)" if run else ""))
        if not DATA.is_dir() and any("data" in b.needs for b, _ in left_out):
            skip_or_fail(why)  # the shared data: fails under CI=true
        pytest.skip(why)  # an optional tool the README's install does not bring


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("classifier-cache")


def _pages_with(fast: bool) -> list[Path]:
    return [p for p in PAGES if any(b.runs_here and (b.marks.get("run") == "fast") == fast for b in examples(p))]


@pytest.mark.parametrize("page", _pages_with(fast=True), ids=lambda p: p.name)
def test_fast_examples_run_as_written(page, tmp_path, cache):
    _run_page(page, tmp_path, cache, fast_only=True)


@pytest.mark.slow
@pytest.mark.parametrize("page", _pages_with(fast=False), ids=lambda p: p.name)
def test_examples_run_as_written(page, tmp_path, cache):
    """Every example of the page, in order (the fast ones again, as the later ones may use them)."""
    _run_page(page, tmp_path, cache, fast_only=False)
