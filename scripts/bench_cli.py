"""Start-up time of the command line: ``hlaid --help`` and every ``hlaid SUBCOMMAND --help``.

Each command is run ``--repeat`` times as a fresh ``python -m hlaid ...`` process (the
interpreter that runs this script, so set ``PYTHONPATH`` to test a source tree); the table
gives the median wall time and its ratio to the peer, a bare ``python -c pass`` (the
interpreter's own start-up). The target is under 0.3 s for every line.

    python scripts/bench_cli.py [--repeat 7] [--limit 0.3]

Exit status 1 when a median is above ``--limit``.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time


def wall(argv: list[str], repeat: int) -> float:
    """Median wall time [s] of ``repeat`` runs of ``argv`` (output discarded)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def subcommands() -> list[str]:
    """The subcommand names, in the order ``hlaid --help`` lists them."""
    from hlaid.cli.app import build_parser

    return list(build_parser().commands)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs per command (default 7)")
    ap.add_argument("--limit", type=float, default=0.3, help="largest acceptable median [s] (default 0.3)")
    a = ap.parse_args(argv)
    py = sys.executable
    peer = wall([py, "-c", "pass"], a.repeat)
    rows = [("python -c pass (peer)", peer)]
    rows.append(("hlaid --help", wall([py, "-m", "hlaid", "--help"], a.repeat)))
    for name in subcommands():
        rows.append((f"hlaid {name} --help", wall([py, "-m", "hlaid", name, "--help"], a.repeat)))
    print(f"{'command':32s} {'median [s]':>10s} {'x peer':>7s}")
    for label, t in rows:
        print(f"{label:32s} {t:10.3f} {t / peer:7.1f}")
    slow = [label for label, t in rows[1:] if t > a.limit]
    print(f"slowest: {max(t for _, t in rows[1:]):.3f} s (limit {a.limit:g} s); "
          + (f"over the limit: {', '.join(slow)}" if slow else "all under the limit"))
    return 1 if slow else 0


if __name__ == "__main__":
    sys.exit(main())
