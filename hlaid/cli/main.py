"""The ``hlaid`` command line: a thin layer over library functions.

Exit status: 0 success, 2 bad input (one line on stderr, no traceback), 1 internal error,
130 interrupted. Each subcommand lives in its own module with a ``register(subparsers)``
function, listed in :data:`COMMANDS`; registering imports nothing heavy (torch, numba, scipy,
matplotlib, scikit-learn, dask): the command functions import what they run.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from .. import __version__, _interrupt, _progress
from ..errors import InputError

COMMANDS = [
    "hlaid.cli.simulate",
    "hlaid.cli.demo",
    "hlaid.cli.hla",
    "hlaid.cli.identify",
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
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


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
        return int(args.func(args) or 0)
    except InputError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:  # workers ignore SIGINT (hlaid._workers); outputs in progress are removed
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # noqa: BLE001 - the one place internal errors are reported
        if verbose:
            traceback.print_exc()
        print(f"{prog}: internal error: {type(err).__name__}: {' '.join(str(err).split())} "
              f"(please report it; --verbose shows the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
