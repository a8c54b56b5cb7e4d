"""``hlaid run`` and ``hlaid report``."""

from __future__ import annotations

from .app import add_plots, subcommand


def register(sub) -> None:
    p = subcommand(sub, "run", help="the whole pipeline on your data: HLA, identification, replay, IDA, report",
                   example="hlaid run configs/run_example.yaml -o runs/my-building")
    p.add_argument("config", help="run config YAML (measurement, identify, ida)")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--cache", metavar="DIR", help="classifier cache folder (default ~/.cache/hlaid/svm)")
    add_plots(p)
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=run_run)

    r = subcommand(sub, "report", help="rebuild report.html of a run folder from its saved results",
                   example="hlaid report hlaid-demo")
    r.add_argument("run_dir", help="a folder written by hlaid run or hlaid demo")
    r.set_defaults(func=run_report)


def run_run(args) -> int:
    from pathlib import Path

    from .._fileio import check_output_folder
    from ..run.config import input_paths, load_run_config

    inputs = [args.config, args.cache]
    check_output_folder(args.out, force=args.force, inputs=inputs)  # fail before the pipeline, not after it
    cfg = load_run_config(args.config)
    base = Path(args.config).parent
    inputs += input_paths(cfg, base)
    check_output_folder(args.out, force=args.force, inputs=inputs)
    from ..run.runner import run_pipeline  # the heavy libraries, once the inputs are known to be good
    run_pipeline(cfg, args.out, base_dir=base, force=args.force, cache_dir=args.cache, inputs=inputs,
                 plots=not args.no_plots)
    return 0


def run_report(args) -> int:
    from ..run.report import build_report

    build_report(args.run_dir)
    return 0
