"""What README.md and docs/*.md name is there, and docs/ describes the product, not its history.

Read from the code spans of the pages (inline backquotes and fenced blocks; ``\\|`` in a table
cell is ``|``), and from the running text where a word says what a name is:

- every dotted ``hlaid.x.y`` name, and every ``from hlaid.x import y`` of a Python block, resolves:
  the longest importable module, then attributes (a dataclass's fields count);
- every structural system (``--system X``, ``system: X``, ``system="X"``, "the `X` prior"), loss
  system (``hlaid loss --system X``, ``loss: {system: X}``, "the X inventory"), collapse law
  (``--collapse``, ``collapse:``, "the `X` law"), intensity measure (``--im``, ``im:``) and method
  (``method:``: a refiner, an identifier, a torchdiffeq solver) is in its registry;
- every ``hlaid COMMAND ... --flag`` names a command of the command line and a flag that command
  takes (its argparse parser, :func:`hlaid.cli.app.build_parser`), and a literal value of a flag
  with choices is one of them;
- the clone's record as it is (README.md, docs/*.md and CONTRIBUTING.md): every ``clone.X`` and
  ``Clone.X`` is a field or attribute of :class:`hlaid.clone.Clone` (and ``clone.X.Y``, ``clone.X[i].Y``
  one of the record type of ``X``, which is read by attribute, not by ``["key"]``); no
  ``diagnostics[...]`` or ``diagnostics.KEY`` (written for the reader, never read back: a page
  names the typed field instead); no ``provenance["config"]`` or ``["choices"]`` (the clone's
  ``settings``).

And docs/ (with README.md) holds no commit hash of the project's history (a hash after ``@`` names
the commit of a dataset's source repository, docs/data.md), no path of the machine a figure was
taken on (``/work/``, ``/tmp/``, ``/home/``), no load average of a past run, no "the code before"
and no session or issue number. Relative links and backquoted repository paths are checked by
tests/test_readme_links.py.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import re
import shlex
from functools import cache
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]

FENCE = re.compile(r"^```(\S*)[^\n]*\n(.*?)^```[ \t]*$", flags=re.S | re.M)
INLINE = re.compile(r"`([^`\n]+)`")
DOTTED = re.compile(r"(?<![\w./-])hlaid(?:\.[A-Za-z_]\w*)+")
FROM_IMPORT = re.compile(r"^[ \t]*from[ \t]+(hlaid[\w.]*)[ \t]+import[ \t]+(?:\(([\w\s,]+)\)|([\w \t,]+))", flags=re.M)
COMMAND = re.compile(r"(?:^|(?<=[\s(`]))(?:python -m )?hlaid ((?:[a-z][\w-]*(?=\s|$)|-).*)")
NAME = r"[\"']?([a-z][\w.|-]*)"
CONFIG_VALUE = {kind: re.compile(rf"(?<![\w-]){kind}\s*[:=]\s*{NAME}")
                for kind in ("system", "collapse", "im", "method")}

PROSE = {  # a name in the running text, by the word beside it
    "loss system": re.compile(r"`?\b([a-z]+(?:-[a-z]+)+)`? inventor(?:y|ies)\b"),
    "system": re.compile(r"(?:\bsystem `([a-z][\w-]*)`|`([a-z][\w-]*)` (?:prior|system)\b)"),
    "collapse": re.compile(r"(?:\bcollapse (?:law|model) `([a-z][\w-]*)`|`([a-z][\w-]*)` (?:collapse )?law\b)"),
}

HASH = re.compile(r"(?<![\w@/.-])(?<!@ )(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w-])")
HISTORY = {
    "a path of the machine a figure was taken on": re.compile(r"(?<![\w.])/(?:work|tmp|home|root)/"),
    "a load average of a past run": re.compile(r"\bload average|\bat a load of\b|\bload \d", re.I),
    "a comparison with the code before": re.compile(r"\bcode before\b", re.I),
    "a session or issue number": re.compile(r"\b(?:session|issue) \d+", re.I),
}


def _rel(path: Path) -> str:
    return path.relative_to(REPO).as_posix()


# ------------------------------------------------------------------------------ the code spans
def code_spans(text: str) -> list[tuple[str, str]]:
    """``(language, code)`` of every fenced block (continued lines joined) and inline code span
    (language ``""``) of a Markdown page."""
    spans = []
    for lang, body in FENCE.findall(text):
        spans.append((lang, body.replace("\\\n", " ")))
    for code in INLINE.findall(FENCE.sub("", text)):
        spans.append(("", code))
    return spans


def _lines(spans: list[tuple[str, str]], langs=None):
    for lang, code in spans:
        if langs is None or lang in langs:
            yield from code.splitlines()


SHELLS = {"bash", "sh", "shell", "console"}


# ------------------------------------------------------------------------------ dotted names
def missing_name(dotted: str) -> str | None:
    """Why ``hlaid.a.b`` names nothing (None where it resolves): import its longest module, then
    read the rest as attributes (a dataclass's fields count as attributes); a module that needs an
    optional package this environment lacks is read as text."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError as e:
            if e.name and not ".".join(parts[:i]).startswith(e.name) and e.name.split(".")[0] != "hlaid":
                return _missing_in_source(parts, i)  # it needs an optional package: read its source
            continue
        for j, name in enumerate(parts[i:], start=i):
            fields: set[str] = {f.name for f in dataclasses.fields(obj)} if dataclasses.is_dataclass(obj) else set()
            if name in fields:
                return None if j == len(parts) - 1 else f"{'.'.join(parts[:j + 1])} is a field"
            if not hasattr(obj, name):
                return f"{'.'.join(parts[:j])} has no {name!r}"
            obj = getattr(obj, name)
        return None
    return "no such module"


def _missing_in_source(parts: list[str], i: int) -> str | None:
    """:func:`missing_name` for a module that imports an optional package this environment lacks:
    its file must exist and define or import the next name (read as text)."""
    path = REPO.joinpath(*parts[:i])
    source = next((f for f in (path / "__init__.py", path.with_suffix(".py")) if f.is_file()), None)
    if source is None:
        return "no such module"
    if i == len(parts) or re.search(rf"\b{re.escape(parts[i])}\b", source.read_text(encoding="utf-8")):
        return None
    return f"{'.'.join(parts[:i])} has no {parts[i]!r}"


def dotted_names(spans: list[tuple[str, str]]) -> set[str]:
    names: set[str] = set()
    for lang, code in spans:
        names.update(n.rstrip(".") for n in DOTTED.findall(code))
        if lang in ("python", ""):
            for module, *imported in FROM_IMPORT.findall(code):
                names.update(f"{module}.{n.strip()}" for n in "".join(imported).split(",") if n.strip())
    return names


# ------------------------------------------------------------------------------ registries
@cache
def registries() -> dict[str, set[str]]:
    """The names each kind of value may take."""
    from hlaid.baselines.registry import IDENTIFIERS
    from hlaid.hla.config import AUTO
    from hlaid.ida.measures import INTENSITY_MEASURES
    from hlaid.identify.refiners import REFINERS
    from hlaid.loss.inventory import INVENTORIES
    from hlaid.model.collapse import COLLAPSE_MODELS
    from hlaid.simulate.odeint import SOLVERS
    from hlaid.systems import SYSTEMS

    return {
        "system": set(SYSTEMS),
        "loss system": set(INVENTORIES),
        "collapse": set(COLLAPSE_MODELS) | {"null"},
        "im": set(INTENSITY_MEASURES),
        "method": {AUTO, *REFINERS, *IDENTIFIERS, "hlasvm", *SOLVERS},
    }


def _values(raw: str) -> list[str]:
    """The literal names of a value (``a|b`` is two); placeholders (``NAME``, ``...``) give none."""
    raw = raw.strip("\"'`,;)]}.")
    return [v for v in raw.split("|") if re.fullmatch(r"[a-z][\w.-]*", v)]


def unknown_values(spans: list[tuple[str, str]]) -> list[str]:
    """``KIND X (in: LINE)`` for each name of a registry a page gives that the registry lacks."""
    known, wrong = registries(), []
    for line in _lines(spans):
        line = line.replace("\\|", "|")
        is_loss = bool(re.search(r"\bhlaid loss\b|\bloss\s*:", line))
        for kind, pattern in CONFIG_VALUE.items():
            for raw in pattern.findall(line):
                where = "loss system" if kind == "system" and is_loss else kind
                wrong += [f"{where} {v!r} (in: {line.strip()})" for v in _values(raw) if v not in known[where]]
        for flag, kind in (("--system", "system"), ("--collapse", "collapse")):
            for raw in re.findall(rf"{flag}[ =]([^\s\]]+)", line):
                where = "loss system" if kind == "system" and is_loss else kind
                wrong += [f"{where} {v!r} (in: {line.strip()})" for v in _values(raw) if v not in known[where]]
    return wrong


def unknown_prose_names(text: str) -> list[str]:
    """``KIND X`` for each name the running text gives a kind to (``the `generic` prior``, ``the
    steel-moment-frame inventory``, ``collapse law `steel-mrf` ``) that its registry lacks."""
    known, text = registries(), re.sub(r"\s+", " ", text)
    return [f"{kind} {name!r} (in the text)" for kind, pattern in PROSE.items() for m in pattern.finditer(text)
            for name in m.groups() if name and name not in known[kind]]


# ------------------------------------------------------------------------------ command lines
@cache
def commands() -> dict[str, argparse.ArgumentParser]:
    from hlaid.cli.app import build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def _segments(line: str) -> list[str]:
    """The shell commands of a line: cut at ``&&``, ``;``, a comment and a pipe (``a\\|b`` and
    ``a|b`` are alternatives, not pipes)."""
    line = re.sub(r"\s#.*", "", line)
    return [s for s in re.split(r"&&|;|\s(?<!\\)\|(?=\s)", line) if s.strip()]


def _tokens(command: str) -> list[str]:
    command = command.replace("\\|", "|")
    try:
        return shlex.split(command)
    except ValueError:
        return command.split()


def bad_command_lines(spans: list[tuple[str, str]]) -> list[str]:
    """What is wrong with each ``hlaid COMMAND ...`` of the spans (the lines of shell blocks, the
    inline spans that start with ``hlaid``): an unknown command, a flag the command does not take,
    a value outside a flag's choices, a required option missing from a command given its
    arguments (``hlaid identify M1 M2 ...``, a sketch, may leave it out)."""
    parsers, wrong = commands(), []
    lines = [*_lines(spans, SHELLS), *(c for lang, c in spans if not lang and re.match(r"(python -m )?hlaid ", c))]
    for line in lines:
        for segment in _segments(line):
            m = COMMAND.search(segment)
            if not m:
                continue
            tokens = _tokens(m.group(1))
            if not tokens or tokens[0].startswith("-"):
                continue  # hlaid --help, hlaid --version
            name = tokens[0]
            if name not in parsers:
                wrong.append(f"no command {name!r} (in: {segment.strip()})")
                continue
            options = {o: a for a in parsers[name]._actions for o in a.option_strings}
            given = {t.lstrip("[(").split("=", 1)[0] for t in tokens[1:]}
            if any(not t.startswith(("-", "[", "(")) for t in tokens[1:]) and not re.search(r"\.\.|\bN\b", segment):
                wrong += [f"hlaid {name} needs {a.option_strings[-1]} (in: {segment.strip()})"
                          for a in parsers[name]._actions if a.required and a.option_strings
                          and not given & set(a.option_strings)]
            for k, token in enumerate(tokens[1:], start=1):
                flag = token.lstrip("[(").rstrip("]),.:").split("=", 1)[0]
                if not re.fullmatch(r"--?[A-Za-z][\w-]*", flag):
                    continue
                if flag not in options:
                    wrong.append(f"hlaid {name} takes no {flag} (in: {segment.strip()})")
                    continue
                choices = options[flag].choices
                value = token.split("=", 1)[1] if "=" in token else tokens[k + 1] if k + 1 < len(tokens) else ""
                if choices and not value.startswith("-"):
                    wrong += [f"hlaid {name} {flag} {v!r} is not one of {sorted(choices)}"
                              for v in _values(value) if v not in choices]
    return wrong


# ------------------------------------------------------------------------------ the clone's record
RECORD_PAGES = [*PAGES, REPO / "CONTRIBUTING.md"]
CLONE_ATTR = re.compile(r"(?<![\w/-])((?:\w+\.)*)([Cc]lone)\.([A-Za-z_]\w*)(\[[^\]\n]*\])?"
                        r"(?:\.([A-Za-z_]\w*)|\[[\"']([\w.]+)[\"']\])?")
FILE_SUFFIXES = {"json", "py", "yaml", "yml", "npz", "csv", "html", "md", "png"}
DIAGNOSTICS = re.compile(r"\bdiagnostics(?:\[[^\]\n]*\]|\.[A-Za-z_]\w*)")
PROVENANCE_MOVED = re.compile(r"\bprovenance(?:\[[\"'](config|choices)[\"']\]|\.(config|choices)\b)")
EVENT_KEY = re.compile(r"(?<![\w.])events\[[^\]\n]*\]\[[\"'](\w+)[\"']\]")  # a clone file's events[i]["replay"]


@cache
def clone_fields() -> dict[str, type | None]:
    """Each field of :class:`hlaid.clone.Clone` and the record type its values are (a frozen
    dataclass, the element's of a tuple; None: not a record)."""
    import types
    import typing

    from hlaid.clone import Clone
    from hlaid.model.uncertainty import ParameterUncertainty

    hints = typing.get_type_hints(Clone, localns={"ParameterUncertainty": ParameterUncertainty})
    out: dict[str, type | None] = {}
    for f in dataclasses.fields(Clone):
        tp = hints[f.name]
        args = [a for a in typing.get_args(tp) if a is not type(None)] if isinstance(tp, types.UnionType) else [tp]
        tp = args[0] if len(args) == 1 else None
        if typing.get_origin(tp) is tuple:
            tp = typing.get_args(tp)[0]
        out[f.name] = tp if isinstance(tp, type) and dataclasses.is_dataclass(tp) else None
    return out


def _has(cls: type, name: str) -> bool:
    return hasattr(cls, name) or (dataclasses.is_dataclass(cls) and name in {f.name for f in dataclasses.fields(cls)})


def unknown_record_names(spans: list[tuple[str, str]]) -> list[str]:
    """What a page's code spans name of the clone's record that it does not have: ``clone.X``
    that :class:`~hlaid.clone.Clone` lacks, ``clone.X.Y`` that ``X``'s record type lacks, a record
    read by ``["key"]``, a key of the write-only ``diagnostics``, ``provenance["config"]``."""
    from hlaid.clone import Clone

    fields, wrong = clone_fields(), []
    for _, code in spans:
        for m in CLONE_ATTR.finditer(code):
            prefix, _, attr, _, sub, key = m.groups()
            if prefix.endswith("hlaid.") or attr in FILE_SUFFIXES:
                continue  # the module hlaid.clone, a file clone.json
            if not (attr in fields or hasattr(Clone, attr)):
                wrong.append(f"{m.group(0)} (Clone has no {attr!r})")
                continue
            record = fields.get(attr)
            if record is None:
                continue
            if sub and not _has(record, sub):
                wrong.append(f"{m.group(0)} ({record.__name__} has no {sub!r})")
            if key:
                wrong.append(f"{m.group(0)} ({record.__name__} is read by attribute: .{key})")
        wrong += [f"{m.group(0)} (diagnostics are written for the reader, never read back: name the clone's "
                  "typed field)" for m in DIAGNOSTICS.finditer(code)]
        wrong += [f"{m.group(0)} (the clone's settings: clone.settings.{m.group(1) or m.group(2)})"
                  for m in PROVENANCE_MOVED.finditer(code)]
        wrong += [f"{m.group(0)} (an EventRecord is read by attribute: clone.events[i].{m.group(1)})"
                  for m in EVENT_KEY.finditer(code)]
    return wrong


# ------------------------------------------------------------------------------ the tests
@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_every_name_a_page_gives_is_there(page):
    text = page.read_text(encoding="utf-8")
    spans = code_spans(text)
    wrong = [f"{n} ({why})" for n in sorted(dotted_names(spans)) if (why := missing_name(n))]
    wrong += unknown_values(spans)
    wrong += unknown_prose_names(text)
    wrong += bad_command_lines(spans)
    assert wrong == [], f"{_rel(page)} names what hlaid does not have: {wrong}"


@pytest.mark.parametrize("page", RECORD_PAGES, ids=_rel)
def test_the_pages_name_the_clone_record_as_it_is(page):
    wrong = unknown_record_names(code_spans(page.read_text(encoding="utf-8")))
    assert wrong == [], f"{_rel(page)} names what the clone does not have: {wrong}"


def history_in(text: str) -> list[str]:
    """``WHAT: EXCERPT`` for each trace of the project's history in a page's text."""
    found = [f"a commit hash: {m.group(0)}" for m in HASH.finditer(text)]
    for what, pattern in HISTORY.items():
        found += [f"{what}: {text[max(0, m.start() - 30):m.end() + 30]!r}" for m in pattern.finditer(text)]
    return found


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_the_pages_describe_the_product_not_its_history(page):
    found = history_in(page.read_text(encoding="utf-8"))
    assert found == [], f"{_rel(page)}: history belongs in CHANGELOG.md: {found}"


def test_the_checks_see_what_they_look_for():
    """Each check finds a dangling name of each kind (so the empty results above are real)."""
    assert missing_name("hlaid.uncertainty.assess") == "hlaid.uncertainty has no 'assess'"
    assert missing_name("hlaid.identify.joint") == "hlaid.identify has no 'joint'"
    assert missing_name("hlaid.ida.assess") is None and missing_name("hlaid.IdentifyConfig.system") is None
    assert missing_name("hlaid.errors.HlaidWarning") is None
    assert _missing_in_source(["hlaid", "loss", "fema_p58", "nothing"], 3) == "hlaid.loss.fema_p58 has no 'nothing'"
    assert _missing_in_source(["hlaid", "loss", "assess", "assess_losses"], 3) is None
    spans = code_spans("| `hlaid loss RUN [--system steel-mrf\\|rc-frame]` |\n"
                       "```bash\nhlaid identify m.npz --system steel-frame --methd ukf && hlaid ida c.json --im sa \\\n"
                       "  --collapse steel\nhlaid identify m.npz -o c.json --method hlasvm\\|svm\n"
                       "hlaid identity m.npz\nhlaid predict c.json m.npz\nhlaid identify M1 M2 ...\n```\n"
                       "```python\nfrom hlaid.ida import assess, nothing\n```\n"
                       "```yaml\nrefine: {method: lsq}\nloss: {system: generic}\n```\n")
    assert {missing_name(n) for n in dotted_names(spans)} == {None, "hlaid.ida has no 'nothing'"}
    values = unknown_values(spans)
    for v in ("loss system 'steel-mrf'", "system 'steel-frame'", "collapse 'steel'", "method 'lsq'",
              "loss system 'generic'"):
        assert any(w.startswith(v) for w in values), (v, values)
    assert len(values) == 5, values
    lines = bad_command_lines(spans)
    assert any("takes no --methd" in w for w in lines), lines
    assert any("--im 'sa'" in w for w in lines) and any("--method 'svm'" in w for w in lines), lines
    assert any("no command 'identity'" in w for w in lines), lines
    assert any("hlaid predict needs --out" in w for w in lines), lines
    assert len(lines) == 7, lines
    prose = unknown_prose_names("the default steel-mrf inventory, the `generic` prior, the `rc-frame` law,\n"
                                "the `rc` prior and collapse law `steel`")
    assert prose == ["loss system 'steel-mrf' (in the text)", "system 'rc' (in the text)",
                     "collapse 'steel' (in the text)"], prose
    assert history_in("figures at 5f769b0, load average 2.3; the code before: 3 s; /work/x") != []
    planted = "at 5f769b0; load average 2.3; the code before; /tmp/run; " + "session" + " 12"
    assert len(history_in(planted)) == 5
    assert history_in("github.com/x/y @ c73b9f5; 1048576 bytes; dt 0.00390625 s; -o run/x") == []


def test_the_record_check_sees_what_it_looks_for():
    """The clone-record check finds each kind of stale name (so the empty results above are real)
    and passes the ones the clone has."""
    spans = code_spans("`clone.diagnostics[\"laws\"]`, `res.clone.start_rule.choice`, `Clone.fixed()`,\n"
                       "`clone.events[j][\"prequential\"]`, `clone.laws.chosen`, `clone.laws.kept_laws`,\n"
                       "`provenance[\"choices\"]`, `provenance[\"timings\"]`, `hlaid.clone.load_clone`,\n"
                       "`clone.json`, `hlaid/clone.py`, `clone.events[0].replay.band_hz`,\n"
                       "`diagnostics.refine.tangent`, `events[j][\"prequential\"][\"prefix\"]`, `provenance.config`\n"
                       "```python\nclone = hlaid.load_clone(\"c.json\")\nclone.save(\"c.json\")\n"
                       "print(clone.building.alpha, clone.uncertainty.interval(0.9), clone.parameterz)\n```\n")
    wrong = unknown_record_names(spans)
    for w in ("diagnostics[\"laws\"]", "Clone.fixed (Clone has no 'fixed')", "EventRecord is read by attribute",
              "LawChoice has no 'kept_laws'", "clone.settings.choices", "diagnostics.refine",
              "Clone has no 'parameterz'", "clone.events[i].prequential", "clone.settings.config"):
        assert any(w in x for x in wrong), (w, wrong)
    assert len(wrong) == 9, wrong
