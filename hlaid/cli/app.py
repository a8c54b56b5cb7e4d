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
    with _progress.cli_warnings(), _interrupt.sticky_sigint():
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    prog, verbose = "hlaid", False
    try:  # Ctrl-C while the subcommands are imported is an interruption too
        parser = build_parser()
        args = parser.parse_args(argv)
        verbose, quiet = getattr(args, "verbose", False), getattr(args, "quiet", False)
        _progress.set_verbosity(2 if verbose else 0 if quiet else 1)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        prog = f"hlaid {args.command}"
        for name in check_environment():  # a bad HLAID_MAX_* is exit 2 before any work
            _progress.warn(f"environment variable {name} is no limit of hlaid (a typo?); it is ignored")
        from .. import _fileio, _inputs
        _fileio.command = prog  # named in the marker of every output folder
        with _inputs.recording():  # every file the command reads is an input it must not replace
            return int(args.func(args) or 0)
    except InputError as err:
        _progress.end_line()
        print(f"{prog}: error: {err}", file=sys.stderr)
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
    """One line for a full disk or an exhausted quota (outside hlaid's atomic writers), else None."""
    from .._fileio import NO_SPACE
    if err.errno not in NO_SPACE:
        return None
    where = f"{escape_controls(err.filename)}: " if err.filename else ""
    return f"{where}{err.strerror or 'no space left on the device'}; free some space or choose another output folder"


def _internal(prog: str, err: BaseException, verbose: bool) -> int:
    _progress.end_line()
    if verbose:
        traceback.print_exc()
    print(f"{prog}: internal error: {type(err).__name__}: {one_line(err)} "
          f"(please report it; --verbose shows the traceback)", file=sys.stderr)
    return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
