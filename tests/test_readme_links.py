"""The README is a short product page, and what it and the docs point at is there.

- README.md is at most :data:`README_MAX_LINES` lines (the results, the layout and the limits are
  docs pages it links).
- Every relative link of README.md and docs/*.md (``[text](path)``, ``[text](path#anchor)``)
  names a file or folder of the repository (anchors are not checked).
- Every mention of the design notes, in the package, the scripts, the tests and the pages, names
  the copy the repository holds (``docs/DESIGN.md``; ``DESIGN.md`` from a page in ``docs/``).
- Every path of the repository a page names in backquotes (``hlaid/...``, ``scripts/...``,
  ``tests/...``, ``configs/...``, ``docs/...``; ``*`` as a wildcard) is there.
- Every dotted ``hlaid.x.y`` name in the package, the README and the docs names a module of the
  package, or a name that module holds (read as text: nothing is imported).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "hlaid"
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]

README_MAX_LINES = 150

LINK = re.compile(r"\[[^\]\n]*\]\(([^)\s]+)\)")
DESIGN = re.compile(r"[\w./-]*DESIGN\.md")
REPO_PATH = re.compile(r"`((?:hlaid|scripts|tests|configs|docs)/[\w./*-]*)")
DOTTED = re.compile(r"(?<![\w./-])hlaid(?:\.[A-Za-z_]\w*)+")


def _rel(path: Path) -> str:
    return path.relative_to(REPO).as_posix()


def relative_links(page: Path) -> list[str]:
    """The link targets of ``page`` that are paths in the repository (no scheme, no bare anchor)."""
    text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    return [t for t in LINK.findall(text) if not re.match(r"[a-z][a-z0-9+.-]*:|#", t)]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: _rel(p))
def test_every_relative_link_resolves(page):
    missing = [t for t in relative_links(page) if not (page.parent / t.split("#", 1)[0]).exists()]
    assert missing == [], f"{_rel(page)} links to what the repository does not hold: {missing}"


def test_readme_is_a_short_product_page():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= README_MAX_LINES, "README.md: move the long sections to a docs page"
    for page in ("docs/results.md", "docs/guarantees.md", "docs/architecture.md"):
        assert f"]({page})" in text, f"README.md does not link {page}"


def test_the_links_are_found():
    """The link reader sees the README's links to its docs pages (so an empty result above is real)."""
    links = relative_links(REPO / "README.md")
    assert "docs/guarantees.md" in links and "CONTRIBUTING.md" in links


@pytest.mark.parametrize("page", [*PAGES, REPO / "CONTRIBUTING.md"], ids=lambda p: _rel(p))
def test_every_path_a_page_names_exists(page):
    missing = []
    for m in REPO_PATH.finditer(page.read_text(encoding="utf-8")):
        path = m.group(1).rstrip(".")
        if not (any(REPO.glob(path)) if "*" in path else (REPO / path).exists()):
            missing.append(path)
    assert missing == [], f"{_rel(page)} names paths the repository does not hold: {missing}"


def _sources() -> list[Path]:
    files = [*PACKAGE.rglob("*.py"), *(REPO / "scripts").glob("*.py"), *(REPO / "tests").glob("*.py")]
    here = Path(__file__).resolve()  # this file names the notes in its patterns
    return [f for f in sorted(files) if f.resolve() != here] + PAGES + [REPO / "CONTRIBUTING.md"]


def test_the_design_notes_cited_are_the_repositorys():
    assert (REPO / "docs" / "DESIGN.md").is_file()
    wrong = []
    for f in _sources():
        for m in DESIGN.finditer(f.read_text(encoding="utf-8")):
            cited = m.group(0)
            here = f.parent if f.suffix == ".md" else REPO  # code names paths from the repository root
            if not (here / cited).is_file():
                wrong.append(f"{_rel(f)}: {cited}")
    assert wrong == [], f"design notes cited where the repository holds none (it holds docs/DESIGN.md): {wrong}"


def _module_file(dotted: str) -> Path | None:
    path = REPO.joinpath(*dotted.split("."))
    for f in (path / "__init__.py", path.with_suffix(".py")):
        if f.is_file():
            return f
    return None


def missing_reference(dotted: str) -> str | None:
    """Why ``hlaid.a.b.c`` names nothing of the package (None where it does): its longest prefix
    that is a module must exist and hold the next name (defined, imported or named lazily)."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        module = _module_file(".".join(parts[:i]))
        if module is None:
            continue
        if i == len(parts):
            return None
        name = parts[i]
        if re.search(rf"\b{re.escape(name)}\b", module.read_text(encoding="utf-8")):
            return None
        return f"{'.'.join(parts[:i])} has no {name!r}"
    return "no such module"


def test_every_dotted_name_of_the_package_exists():
    files = [*sorted(PACKAGE.rglob("*.py")), *PAGES]
    wrong = []
    for f in files:
        text = f.read_text(encoding="utf-8")
        for dotted in sorted(set(DOTTED.findall(text))):
            why = missing_reference(dotted)
            if why:
                wrong.append(f"{_rel(f)}: {dotted} ({why})")
    assert wrong == [], f"names of modules or functions the package does not hold: {wrong}"


def test_a_missing_module_is_seen():
    assert missing_reference("hlaid.identify.joint.map_refine") == "hlaid.identify has no 'joint'"
    assert missing_reference("hlaid.joint.fit.map_refine") is None
    assert missing_reference("hlaid.errors.one_line") is None
