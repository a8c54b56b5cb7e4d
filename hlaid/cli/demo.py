"""``hlaid demo``."""

from __future__ import annotations

from .app import subcommand


def register(sub) -> None:
    p = subcommand(sub, "demo", help="the whole pipeline on the embedded Table 1 case: simulate, HLA, identify, "
                                     "replay, IDA, report.html",
                   example="hlaid demo --out hlaid-demo")
    p.add_argument("-o", "--out", default="hlaid-demo", help="output folder (default ./hlaid-demo)")
    p.add_argument("--cache", metavar="DIR", help="classifier cache folder (default ~/.cache/hlaid/svm)")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=run_demo_command)


def run_demo_command(args) -> int:
    from .._fileio import check_output_folder

    check_output_folder(args.out, force=args.force, inputs=[args.cache])  # fail before the pipeline, not after it
    from ..demo import run_demo
    from ..run.summary import read_summary
    from .run import print_run_summary

    run_demo(args.out, force=args.force, cache_dir=args.cache)
    print_run_summary(read_summary(args.out), args.out)
    return 0
