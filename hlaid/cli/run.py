"""``hlaid run`` and ``hlaid report``."""

from __future__ import annotations

from pathlib import Path

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

    from .._fileio import check_output_folder
    from ..run.config import input_paths, load_run_config

    inputs = [args.config, args.cache]
    check_output_folder(args.out, force=args.force, inputs=inputs)  # fail before the pipeline, not after it
    cfg = load_run_config(args.config)
    base = Path(args.config).parent
    inputs += input_paths(cfg, base)
    check_output_folder(args.out, force=args.force, inputs=inputs)
    _check_inputs(cfg, base)  # a missing measurement or bad records: before the pipeline loads, not after HLA
    from ..run.runner import run_pipeline  # the heavy libraries, once the inputs are known to be good
    summary = run_pipeline(cfg, args.out, base_dir=base, force=args.force, cache_dir=args.cache, inputs=inputs,
                           plots=not args.no_plots)
    print_run_summary(summary, args.out)
    return 0


def _check_inputs(cfg, base) -> None:
    """Refuse a run whose measurement file is missing or no regular file, or whose IDA records cannot
    be read (a missing file, a folder without records, ``/``), from the config alone."""
    from .._inputs import check_input

    m = cfg.measurement
    for f in m.files:
        if not str(f).startswith("builtin"):
            p = Path(f)
            check_input(p if p.is_absolute() else base / p)
    if cfg.ida is not None:
        specs = cfg.ida.record_specs(base)
        if specs:
            from ..io.records import as_motions

            as_motions(specs, units=cfg.ida.units)


def print_run_summary(s, out) -> None:
    """The run's key figures on one screen: the clone's replay, its parameters against the truth
    when known, the collapse fragility before and after the event, the ensemble's indicator and
    the losses at the recorded event."""
    from .. import _progress

    r = s.replay
    lines = [f"summary of {s.name}:",
             f"  replay of the record: R {', '.join(f'{v:.3f}' for v in r.r_measured)} (floors bottom to top)"]
    errs = [row.error for row in s.parameters if row.error is not None and row.parameter != "k0"]
    if errs:
        lines.append(f"  parameters against the truth: {100 * sum(errs) / len(errs):.1f} % mean, "
                     f"{100 * max(errs):.1f} % worst (alpha, p, dy, delta_eta)")
    for label, ida in (("undamaged", s.ida), ("after the event", s.ida_after)):
        cf = ida.collapse_fit if ida is not None else None
        if ida is not None and cf is not None and cf.median_g is not None:
            im = ida.intensity_measure.label or "IM"
            lines.append(f"  collapse fragility, {label}: median {im} {cf.median_g:.3g} g, beta {cf.beta:.2f}")
    a = s.assessment
    if a is not None and a.own_im is not None and a.p_collapse is not None:
        lines.append(f"  at the record's own intensity ({a.own_im:.3g} g): {p_collapse_text(a)}; "
                     f"indicator {a.indicator or '-'}")
    loss = s.loss.recorded if s.loss is not None else None
    if loss is not None:
        lines.append(f"  losses at the record: repair cost {loss.repair_cost_ratio_median:.1%} of replacement "
                     f"(median), repair time {loss.repair_time_parallel_median:.1f} worker-days")
    lines.append(f"  report: {out}/report.html")
    if s.basis is not None:
        from ..ida.basis import DecisionBasis

        lines += DecisionBasis.from_dict(s.basis).lines()
    for line in lines:
        _progress.info(line)


def p_collapse_text(a) -> str:
    """P(collapse) of an ensemble assessment at the record, its interval and the indicator's
    percentile, said one way everywhere (``hlaid run``, the report)."""
    band = ("" if a.p_collapse_band is None else
            f", {a.ci:.0%} band {a.p_collapse_band[0]:.1%}-{a.p_collapse_band[1]:.1%} (its 5th to 95th percentile "
            "over members and record resamples)")
    return f"P(collapse | another record of this intensity) {a.p_collapse:.1%} (mean of the ensemble{band})"


def run_report(args) -> int:
    from ..run.report import build_report

    build_report(args.run_dir)
    return 0
