"""One vocabulary across the commands: the same thing is taken with the same flag and default.

The argparse parsers of ``hlaid`` (:func:`hlaid.cli.app.build_parser`) are walked, not their help
text: for every destination an optional flag fills, every command that has it must spell it with
the same option strings, the same default, type, number of values and choices; one flag always
fills one destination. Then what a command needs is checked against what it takes: a command that
reads a measurement takes the reader's options (``--read``), one that simulates a clone its story
heights, one that writes figures ``--no-plots``. Library messages name Python arguments; the
command line shows each as its flag (``PYTHON_HINTS``), which must exist.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np
import pytest

import hlaid
from hlaid.cli.app import PYTHON_HINTS, build_parser, cli_message, main, reader_options

ROOT = Path(hlaid.__file__).parent

DIFFERENT_DEFAULTS = {("out", "demo"): "the demo writes ./hlaid-demo unless told otherwise"}
"""(destination, command) pairs allowed another default, and why."""

OLD_SPELLINGS = ("--n-ensemble", "--plot", "--plots", "--realisations", "--n-realizations", "--figures")
"""Spellings of shared options that no command may offer in its help (a deprecated alias is hidden)."""


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def _optionals(p: argparse.ArgumentParser) -> list[argparse.Action]:
    """The optional arguments a command shows (deprecated aliases are hidden and left out)."""
    return [a for a in p._actions if a.option_strings and a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._HelpAction)]


def _signature(a: argparse.Action) -> tuple:
    return (tuple(a.option_strings), repr(a.default), a.nargs, tuple(a.choices) if a.choices else None,
            getattr(a.type, "__name__", a.type), type(a).__name__)


def test_the_same_option_has_the_same_flags_and_default_in_every_command():
    seen: dict[str, dict[str, tuple]] = {}
    for name, p in _commands().items():
        for a in _optionals(p):
            if (a.dest, name) in DIFFERENT_DEFAULTS:
                continue
            seen.setdefault(a.dest, {})[name] = _signature(a)
    assert len(seen) > 20  # the walk found the options
    for dest, by_command in seen.items():
        spellings = set(by_command.values())
        assert len(spellings) == 1, f"{dest}: " + "; ".join(f"{c}: {s}" for c, s in sorted(by_command.items()))
    # the shared ones are where they should be, with the same default
    assert {c for c in seen["ensemble"]} == {"predict", "demands", "ida"} and seen["ensemble"]["demands"][1] == "None"
    assert {"hla", "ida", "predict", "run"} <= set(seen["no_plots"])
    assert {"hla", "identify", "update", "predict", "demands"} <= set(seen["read"])
    assert {"ida", "demands", "export-opensees"} <= set(seen["heights"]) & set(seen["gravity_kN"]) & set(seen["pdelta"])
    assert seen["seed"]["simulate"][1] == seen["seed"]["loss"][1] == "None"


def test_one_flag_fills_one_destination():
    dest_of: dict[str, set[str]] = {}
    for p in _commands().values():
        for a in p._actions:
            for s in a.option_strings:
                dest_of.setdefault(s, set()).add(a.dest)
    assert {s: d for s, d in dest_of.items() if len(d) > 1} == {}


def test_no_command_offers_an_old_spelling():
    for name, p in _commands().items():
        shown = {s for a in _optionals(p) for s in a.option_strings}
        assert not shown & set(OLD_SPELLINGS), (name, shown & set(OLD_SPELLINGS))


def test_what_a_command_reads_it_takes_the_options_of():
    for name, p in _commands().items():
        positional = {a.dest for a in p._actions if not a.option_strings}
        optional = {a.dest for a in _optionals(p)}
        if "measurement" in positional or "motion" in optional:
            assert "read" in optional, f"{name} reads a measurement but has no --read"
        if "clone" in positional and name not in ("update", "predict"):  # those replay at the clone's own heights
            assert {"heights", "gravity_kN", "pdelta"} <= optional, f"{name} simulates a clone: needs --heights"


def test_every_python_hint_is_a_flag_and_still_used_by_the_library():
    flags = {s for p in _commands().values() for a in p._actions for s in a.option_strings}
    source = "\n".join(f.read_text(encoding="utf-8") for f in ROOT.rglob("*.py") if "cli" not in f.parts)
    for py, cli in PYTHON_HINTS.items():
        assert set(re.findall(r"--[a-zA-Z-]+", cli)) <= flags, cli
        assert py in source, f"no library message names {py} any more: drop it from PYTHON_HINTS"
    assert cli_message("story heights are unknown: IDAConfig(heights_mm=[...])") == \
        "story heights are unknown: --heights MM,MM,..."


def test_reader_options_parse_as_the_reader_takes_them():
    ns = argparse.Namespace(read=["event=13", "floors=5,7", "ground=3", "units=g", "scale=0.5", "x=[7]"])
    assert reader_options(ns) == {"event": 13, "floors": [5, 7], "ground": 3, "units": "g", "scale": 0.5, "x": [7]}
    for bad in (["13"], ["event=1", "event=2"], ["path=x"]):
        with pytest.raises(hlaid.InputError):
            reader_options(argparse.Namespace(read=bad))


def test_a_deprecated_spelling_still_works_and_says_which_replaces_it(tmp_path, capsys):
    rc = main(["hla", str(tmp_path / "missing.npz"), "-o", str(tmp_path / "out"), "--plot"])
    err = capsys.readouterr().err
    assert rc == 2 and "--plot is deprecated" in err and "missing.npz" in err


def test_library_hint_reaches_the_user_as_a_flag(tmp_path, capsys, table1):
    """A clone without story heights: the library's error names IDAConfig(heights_mm=...), the
    command line's names --heights (demands has it too)."""
    from hlaid.clone import Clone

    clone = Clone(building=table1).save(tmp_path / "clone.json")
    with pytest.raises(hlaid.InputError, match=r"IDAConfig\(heights_mm=\[\.\.\.\]\)"):
        hlaid.run_ida(clone, "builtin:elcentro-1940-ns")
    rc = main(["demands", str(clone), "--records", "builtin:elcentro-1940-ns", "--level", "0.5", "-o",
               str(tmp_path / "d.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and "--heights MM,MM,..." in err and "IDAConfig" not in err


def test_read_passes_reader_options_to_every_reading_command(data_dir, tmp_path, capsys):
    """The hotel's .mat holds 21 earthquakes: without an event the error names the flag, with
    --read event=13 the command reads that one (the same samples as hlaid.read(path, event=13))."""
    mat = data_dir / "structural_response" / "phycnn_6story_hotel" / "data_exp.mat"
    rc = main(["hla", str(mat), "-o", str(tmp_path / "a"), "--no-plots"])
    err = capsys.readouterr().err
    assert rc == 2 and "--read event=N" in err and "read(path" not in err
    rc = main(["hla", str(mat), "-o", str(tmp_path / "b"), "--no-plots", "--read", "event=13"])
    assert rc == 0, capsys.readouterr().err
    import json

    summary = json.loads((tmp_path / "b" / "hla.json").read_text())
    direct = hlaid.run_hla(hlaid.read(mat, event=13))
    assert summary["n_samples"] == direct.time.size
    np.testing.assert_allclose([s["k0"] for s in summary["stories"]], direct.k0, rtol=1e-12)
    assert not list((tmp_path / "b").glob("*.png"))  # --no-plots
    rc = main(["hla", str(mat), "-o", str(tmp_path / "c"), "--read", "event=99"])
    assert rc == 2 and "no event 99" in capsys.readouterr().err
