"""The ``hlaid`` command line: a thin layer over library functions.

Exit status: 0 success, 2 bad input (one line on stderr, no traceback; a full disk too), 1
internal error, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM). Every message has its control
characters escaped (a hostile file name cannot drive the terminal). Each subcommand lives in its
own module with a ``register(subparsers)`` function, listed in :data:`COMMANDS`; registering
imports nothing heavy (torch, numba, scipy, matplotlib, scikit-learn, dask): the command
functions check their inputs, outputs and configs first, then import what they run.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from .. import _interrupt, _progress
from .._version import __version__
from ..errors import InputError, escape_controls, one_line
from ..limits import check_environment

COMMANDS = [
    "hlaid.cli.simulate",
    "hlaid.cli.demo",
    "hlaid.cli.hla",
    "hlaid.cli.identify",
    "hlaid.cli.events",
    "hlaid.cli.run",
    "hlaid.cli.ida",
    "hlaid.cli.fleet",
    "hlaid.cli.loss",
]
"""Modules that each register one or more subcommands."""


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2."""

    commands: tuple[str, ...] = ()
    """The subcommand names (set on the top-level parser by :func:`build_parser`)."""

    def error(self, message):  # noqa: D401
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def add_common(p: argparse.ArgumentParser) -> None:
    """Options every subcommand accepts (also after the subcommand name)."""
    g = p.add_argument_group("output and messages")
    g.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS, help="print only errors")
    g.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                   help="print details (and tracebacks of internal errors)")


class _Deprecated(argparse.Action):
    """An old spelling of an option: works, says which one replaces it (hidden from ``--help``)."""

    def __init__(self, option_strings, dest, *, advice: str, **kw):
        self.advice = advice
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        _progress.warn(f"{option_string} is deprecated and will be removed: {self.advice}")
        setattr(namespace, self.dest, True if self.nargs == 0 else values)


def deprecated(p: argparse.ArgumentParser, old: str, dest: str, advice: str, **kw) -> None:
    """Keep the old spelling ``old`` of an option working (into ``dest``), with a warning that gives
    ``advice`` (``"use --ensemble"``)."""
    p.add_argument(old, dest=dest, action=_Deprecated, advice=advice, **kw)


# --------------------------------------------------------------------- options shared by commands
# Every command that takes the same thing takes it through one of these (tests/test_cli_vocabulary.py
# checks that an option's flags and default are the same in every command).
def add_plots(p: argparse.ArgumentParser) -> None:
    """``--no-plots``: figures are written unless this is given."""
    p.add_argument("--no-plots", action="store_true", help="write no figures (PNG)")


def add_read(p: argparse.ArgumentParser) -> None:
    """``--read KEY=VALUE``: an option of the measurement file's reader (``hlaid.read(path, KEY=VALUE)``)."""
    p.add_argument("--read", action="append", metavar="KEY=VALUE", default=None,
                   help="an option of the measurement's reader, as hlaid.read(path, KEY=VALUE) takes it, e.g. "
                        "event=13 (the hotel's .mat), ground=3 and floors=7 or floors=5,7 (a CSMIP record); "
                        "repeat for several (docs/data.md)")


def add_ensemble(p: argparse.ArgumentParser, what: str) -> None:
    """``--ensemble N``: clones drawn from the clone's identification uncertainty."""
    from ..uncertainty.config import N_ENSEMBLE
    what = f" {what}" if what else ""
    p.add_argument("--ensemble", type=int, default=None, metavar="N",
                   help=f"clones drawn from the clone's identification uncertainty{what} (default {N_ENSEMBLE} "
                        "when the clone has it, else 0; 0: the identified clone alone)")


STORY_HEIGHT_MM = (500.0, 50_000.0)
"""Story heights ``--heights`` accepts [mm]: 0.5 m (a crawl space) to 50 m (a hangar's story); a
value of a few units is a height in metres."""

DRIFT_LIMIT_MAX = 0.5
"""The largest collapse drift ratio ``--drift-limit`` accepts (50 % of the story height)."""


def check_values(args) -> None:
    """Refuse absurd values of the options several commands share, right after the arguments are
    parsed (before a file is read or a heavy library loads): ``--ensemble`` outside 0..
    :data:`~hlaid.uncertainty.config.MAX_ENSEMBLE`, ``--heights`` outside :data:`STORY_HEIGHT_MM`
    (a few units: metres, said so), ``--drift-limit`` outside (0, :data:`DRIFT_LIMIT_MAX`]."""
    from ..uncertainty.config import MAX_ENSEMBLE

    n = getattr(args, "ensemble", None)
    if n is not None and not 0 <= n <= MAX_ENSEMBLE:
        raise InputError(f"--ensemble {n}: {n} clones; expected 0 (the identified clone alone) to {MAX_ENSEMBLE:,}")
    text = getattr(args, "heights", None)
    if text:
        _check_heights(str(text))
    d = getattr(args, "drift_limit", None)
    if d is not None and not 0 < d <= DRIFT_LIMIT_MAX:
        raise InputError(f"--drift-limit {d:g}: a drift limit is a ratio of the story height (0.10 is 10 %), above 0 "
                         f"and at most {DRIFT_LIMIT_MAX:g}" + (f"; {d:g} is {d:.0%}" if d > DRIFT_LIMIT_MAX else ""))


def _check_heights(text: str) -> None:
    lo, hi = STORY_HEIGHT_MM
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        return  # not numbers: the command says so
    for v in values:
        if 0 < v <= 50:
            raise InputError(f"--heights {one_line(text, 60)}: story heights are in mm; {v:g} mm looks like metres "
                             f"({v:g} m = {v * 1000:g} mm)")
        if not lo <= v <= hi:
            raise InputError(f"--heights {one_line(text, 60)}: a story height of {v:g} mm; expected {lo:g} to {hi:g} "
                             "mm (0.5 to 50 m) per story")


def _seed(text: str) -> int:
    """A ``--seed`` value: an integer within :data:`hlaid.bounds.SEED`, checked as it is parsed."""
    from ..bounds import SEED

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text[:40]!r}") from None
    try:
        SEED.check("--seed", value)
    except InputError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return value


def add_seed(p: argparse.ArgumentParser, what: str, default: str = "0") -> None:
    """``--seed N`` (checked against :data:`hlaid.bounds.SEED` as it is parsed)."""
    p.add_argument("--seed", type=_seed, default=None, metavar="N", help=f"seed of {what} (default {default})")


def add_building(p: argparse.ArgumentParser, *, pdelta_default: str = "when story heights are known") -> None:
    """The building data a clone file may lack: ``--heights``, ``--gravity-kN``, ``--pdelta/--no-pdelta``."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--pdelta", dest="pdelta", action="store_true", default=None,
                   help=f"include P-Delta (default: {pdelta_default})")
    g.add_argument("--no-pdelta", dest="pdelta", action="store_false", help="leave P-Delta out")
    p.add_argument("--heights", metavar="MM",
                   help="story heights [mm], bottom to top, e.g. 3000,3000,3000 (default: the clone's)")
    p.add_argument("--gravity-kN", metavar="KN", help="floor gravity loads [kN] for P-Delta, bottom to top "
                                                     "(default: the floor weights)")


def reader_options(args) -> dict:
    """``--read KEY=VALUE`` options as keyword arguments of :func:`hlaid.read`: a value is an
    integer, a number, true/false, a comma-separated list of those, else a string."""
    out: dict = {}
    for item in getattr(args, "read", None) or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key.isidentifier():
            raise InputError(f"--read {item!r}; expected KEY=VALUE, e.g. --read event=13")
        if key in ("path", "kind"):
            raise InputError(f"--read {key}=...: {key} is not a reader option")
        if key in out:
            raise InputError(f"--read {key} given twice")
        text = value.strip().removeprefix("[").removesuffix("]")
        parts = [_scalar(v.strip()) for v in text.split(",")] if "," in text or value.strip().startswith("[") \
            else None
        out[key] = parts if parts is not None else _scalar(text)
    return out


def _scalar(text: str):
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "null": None}.get(text.lower(), text)


PYTHON_HINTS = {
    "IDAConfig(heights_mm=[...])": "--heights MM,MM,...",
    "IDAConfig(gravity_kN=[...])": "--gravity-kN KN,KN,...",
    "IDAConfig(pdelta=False)": "--no-pdelta",
    "read(path, event=N)": "--read event=N",
    "read(path, ground=N, floors=[N, ...])": "--read ground=N --read floors=N,N,...",
    "records=[...]": "--records DIR|builtin-suite|FILE",
}
"""Library messages name Python arguments (``IDAConfig(heights_mm=[...])``); on the command line
each is shown as the flag that sets it (a test checks that every flag exists and every phrase is
still used by the library)."""


def cli_message(text: str) -> str:
    """A library message with its Python arguments replaced by the command line's flags."""
    for py, flag in PYTHON_HINTS.items():
        text = text.replace(py, flag)
    return text


def subcommand(sub, name: str, *, help: str, example: str, description: str | None = None) -> argparse.ArgumentParser:
    """Create a subcommand parser whose help ends with an example."""
    p = sub.add_parser(name, help=help, description=description or help,
                       epilog=f"example:\n  {example}", formatter_class=argparse.RawDescriptionHelpFormatter)
    add_common(p)
    return p


def build_parser() -> Parser:
    parser = Parser(prog="hlaid", formatter_class=argparse.RawDescriptionHelpFormatter,
                    description="Digital clones of buildings from earthquake records: hysteresis loop analysis, "
                                "Bouc-Wen identification, replay, IDA and collapse fragility.",
                    epilog="example:\n  hlaid demo --out hlaid-demo      # the whole pipeline on built-in data\n"
                           "  hlaid simulate configs/poc_3story.yaml -o meas.npz")
    parser.add_argument("--version", action="version", version=f"hlaid {__version__}")
    add_common(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for mod in COMMANDS:
        importlib.import_module(mod).register(sub)
    parser.commands = tuple(sub.choices)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); returns the exit status.
    A Ctrl-C that Python drops (inside a finaliser) is raised again (:mod:`hlaid._interrupt`)."""
    try:
        with _progress.cli_warnings(), _interrupt.sticky_sigint():
            return _main(argv)
    finally:
        if argv is None:  # the program itself: a signal while the interpreter shuts down is said too
            _interrupt.said_until_exit()


def _main(argv: list[str] | None) -> int:
    prog, verbose = "hlaid", False
    try:  # Ctrl-C while the subcommands are imported is an interruption too
        _progress.set_verbosity(1)  # warnings while the arguments are parsed (a deprecated option)
        parser = build_parser()
        args = parser.parse_args(argv)
        verbose, quiet = getattr(args, "verbose", False), getattr(args, "quiet", False)
        _progress.set_verbosity(2 if verbose else 0 if quiet else 1)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        prog = f"hlaid {args.command}"
        check_values(args)
        for name in check_environment():  # a bad HLAID_MAX_* is exit 2 before any work
            _progress.warn(f"environment variable {name} is no limit of hlaid (a typo?); it is ignored")
        from .. import _fileio, _inputs
        _fileio.command = prog  # named in the marker of every output folder
        with _inputs.recording():  # every file the command reads is an input it must not replace
            return int(args.func(args) or 0)
    except InputError as err:
        _progress.end_line()
        print(f"{prog}: error: {cli_message(str(err))}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`
        sys.stderr.close()
        return 0
    except _interrupt.Terminated:  # SIGTERM: the same clean-up as Ctrl-C
        _progress.end_line()
        print(f"{prog}: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:  # workers ignore SIGINT (hlaid._workers); outputs in progress are removed
        _progress.end_line()
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except OSError as err:
        full = _no_space(err)
        if full is None:
            return _internal(prog, err, verbose)
        _progress.end_line()
        print(f"{prog}: error: {full}", file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 - the one place internal errors are reported
        return _internal(prog, err, verbose)


def _no_space(err: OSError) -> str | None:
    """One line for what the system refuses whatever hlaid does (outside hlaid's atomic writers),
    else None: a full disk or an exhausted quota, the file-size limit (``ulimit -f``), a file name
    longer than the file system allows (named shortened)."""
    import errno

    from .._fileio import NO_SPACE
    where = f"{_short(err.filename)}: " if err.filename else ""
    if err.errno in NO_SPACE:
        return (f"{where}{err.strerror or 'no space left on the device'}; free some space or choose another "
                "output folder")
    if err.errno == errno.EFBIG:
        return f"{where}the file-size limit of this process (ulimit -f) was reached; raise it"
    if err.errno == errno.ENAMETOOLONG:
        return f"{where}a name in this path is longer than the file system allows (255 bytes a name); shorten it"
    return None


def _short(name) -> str:
    text = escape_controls(str(name))
    return text if len(text) <= 120 else f"{text[:50]}...{text[-50:]} ({len(text)} characters)"


def _internal(prog: str, err: BaseException, verbose: bool) -> int:
    _progress.end_line()
    if verbose:
        traceback.print_exc()
    print(f"{prog}: internal error: {type(err).__name__}: {one_line(err)} "
          f"(please report it; --verbose shows the traceback)", file=sys.stderr)
    return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
