"""Compare identifiers on the same simulated cases: tables, plots, TensorBoard.

Every identifier of the config (HLA+SVM as in the paper, HLA+SVM with its replay
refinement, least squares through the differentiable model, the unscented Kalman filter)
fits the same simulated measurements: the Table 1 structure and random shear buildings,
real records scaled to PGA 0.62 g, several noise levels and seeds (see
:mod:`hlaid.studies.compare` for the metrics and what counts as a failure).

Usage: python scripts/compare_identifiers.py --config configs/compare.yaml [-o OUT] [--force] [-q | -v]

Writes into OUT (default ``compare-results``; an existing non-empty folder only with
``--force``, replaced once the new one is complete):

- ``summary.md``: per noise level, per identifier: failures, mean and worst parameter error,
  per-parameter mean error, replay R on the identification and the unseen record, peak-drift
  error on the unseen record, wall time; then every outcome, one row each
- ``results.csv`` (one row per case and identifier), ``results.json`` (everything, with the
  clones and the config)
- ``figures/param_error.png``, ``replay_r.png``, ``wall_time.png``, ``failures.png``
- ``tensorboard/`` (``tensorboard --logdir OUT/tensorboard``)
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

from hlaid import _progress  # noqa: E402
from hlaid._fileio import atomic_directory, atomic_write, write_json  # noqa: E402
from hlaid.config import config_to_dict  # noqa: E402
from hlaid.errors import InputError  # noqa: E402
from hlaid.plots import save_figure  # noqa: E402
from hlaid.studies.compare import (  # noqa: E402
    LABELS,
    PARAMETERS,
    build_cases,
    load_compare_config,
    make_identifier,
    run_case,
    study_record,
    summarise,
)

FIGURES = ("param_error.png", "replay_r.png", "wall_time.png", "failures.png")


def _pct(v, signed=False) -> str:
    if v is None or not np.isfinite(v):
        return "-"
    return f"{100 * v:+.2f}" if signed else f"{100 * v:.2f}"


def summary_tables(rows: list[dict]) -> list[str]:
    """Markdown: one table per noise level, one row per structure kind and identifier."""
    lines = []
    head = (["structure", "identifier", "cases", "failures", "mean error %", "worst error %"]
            + [f"{p} %" for p in PARAMETERS]
            + ["R ident mean (min)", "R unseen mean (min)", "unseen drift error % mean (worst)",
               "wall s mean (max)", "CPU s mean"])
    for noise in sorted({r["noise"] for r in rows}):
        lines += [f"\n### Noise {100 * noise:g} % RMS\n", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in (r for r in rows if r["noise"] == noise):
            cells = [r["structure"], LABELS.get(r["identifier"], r["identifier"]), str(r["cases"]), str(r["failures"])]
            if "mean_error" in r:
                cells += [_pct(r["mean_error"]), _pct(r["worst_error"])]
                cells += [_pct(r["param_mean_error"][p]) for p in PARAMETERS]
                cells += [f"{r['r_ident_mean']:.4f} ({r['r_ident_min']:.4f})",
                          f"{r['r_unseen_mean']:.4f} ({r['r_unseen_min']:.4f})",
                          f"{_pct(r['drift_error_unseen_mean'])} ({_pct(r['drift_error_unseen_worst'])})"]
            else:
                cells += ["-"] * (2 + len(PARAMETERS) + 3)
            cells += [f"{r['wall_mean_s']:.1f} ({r['wall_max_s']:.1f})", f"{r['cpu_mean_s']:.1f}"]
            lines.append("| " + " | ".join(cells) + " |")
        reasons = [(r["identifier"], x) for r in rows if r["noise"] == noise for x in r["reasons"]]
        if reasons:
            lines.append("\nFailures: " + "; ".join(f"{LABELS.get(i, i)}: {x}" for i, x in reasons))
    return lines


def outcome_table(outcomes) -> list[str]:
    head = ["case", "identifier", "mean error %", "max error %", "R ident min", "R unseen min", "wall s", "failure"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for o in outcomes:
        lines.append("| " + " | ".join([o.case, o.identifier, _pct(o.mean_error), _pct(o.max_error),
                                        f"{min(o.r_ident):.4f}" if o.r_ident else "-",
                                        f"{min(o.r_unseen):.4f}" if o.r_unseen else "-", f"{o.wall_s:.1f}",
                                        o.reason or ""]) + " |")
    return lines


def write_csv(path: Path, outcomes) -> None:
    n = max(len(next(iter(o.errors.values()))) if o.errors else 0 for o in outcomes)
    cols = ["case", "identifier", "structure", "record", "noise", "seed", "failed", "reason", "wall_s", "wall_own_s",
            "cpu_s", "cpu_own_s", "mean_error", "max_error"]
    cols += [f"error_{p}_{i + 1}" for p in PARAMETERS for i in range(n)]
    cols += [f"{m}_{i + 1}" for m in ("r_ident", "r_unseen", "drift_error_unseen") for i in range(n)]

    def row(o):
        d = {c: getattr(o, c) for c in cols[:14]}
        for p in PARAMETERS:
            for i, v in enumerate((o.errors or {}).get(p, [])):
                d[f"error_{p}_{i + 1}"] = v
        for m in ("r_ident", "r_unseen", "drift_error_unseen"):
            for i, v in enumerate(getattr(o, m) or []):
                d[f"{m}_{i + 1}"] = v
        return d

    def w(tmp: Path):
        with open(tmp, "w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=cols)
            wr.writeheader()
            for o in outcomes:
                wr.writerow(row(o))
    atomic_write(path, w)


def figures(outcomes, names: list[str]) -> dict:
    """The four figures of :data:`FIGURES` (every structure together), by file name."""
    from hlaid.plots import plt

    rows = summarise([dataclasses.replace(o, structure="all") for o in outcomes])
    noises = sorted({r["noise"] for r in rows})
    x = np.arange(len(noises))
    width = 0.8 / len(names)
    get = {(r["identifier"], r["noise"]): r for r in rows}
    made = {}

    def bars(ax, key_mean, key_low=None, key_high=None, scale=1.0):
        for j, name in enumerate(names):
            rs = [get.get((name, nz), {}) for nz in noises]
            mean = np.array([scale * r.get(key_mean, np.nan) for r in rs])
            pos = x - 0.4 + (j + 0.5) * width
            ax.bar(pos, mean, width, label=LABELS.get(name, name))
            if key_high or key_low:
                lo = np.array([scale * r.get(key_low, np.nan) for r in rs]) if key_low else mean
                hi = np.array([scale * r.get(key_high, np.nan) for r in rs]) if key_high else mean
                ax.errorbar(pos, mean, yerr=[np.nan_to_num(mean - lo), np.nan_to_num(hi - mean)], fmt="none",
                            ecolor="k", lw=0.8, capsize=2)
        ax.set_xticks(x, [f"{100 * nz:g} %" for nz in noises])
        ax.set_xlabel("noise (RMS, per channel)")
        ax.grid(alpha=0.3, axis="y")

    fig, ax = plt.subplots(figsize=(8, 4.2))
    bars(ax, "mean_error", None, "worst_error", 100.0)
    ax.set_yscale("log")
    ax.set_ylabel("parameter error [%]: mean, whisker to worst")
    ax.axhline(1.0, color="0.4", ls=":", lw=0.8)
    ax.legend(fontsize=8)
    made["param_error.png"] = fig

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for r in rows:  # 1 - R on a log scale: R is close to 1 for every useful clone
        for m in ("r_ident", "r_unseen"):
            if f"{m}_mean" in r:
                r[f"{m}_deficit_mean"], r[f"{m}_deficit_worst"] = 1 - r[f"{m}_mean"], 1 - r[f"{m}_min"]
    for ax, (m, title) in zip(axes, (("r_ident", "identification record"), ("r_unseen", "unseen record"))):
        bars(ax, f"{m}_deficit_mean", None, f"{m}_deficit_worst")
        ax.set_yscale("log")
        ax.set_title(f"replay of floor displacements, {title}", fontsize=10)
    axes[0].set_ylabel("1 - R: mean, whisker to the worst story")
    axes[0].legend(fontsize=8)
    made["replay_r.png"] = fig

    fig, ax = plt.subplots(figsize=(7, 4))
    data = [[o.wall_s for o in outcomes if o.identifier == n] for n in names]
    ax.boxplot(data, showfliers=True)
    ax.set_xticks(np.arange(1, len(names) + 1), [LABELS.get(n, n) for n in names], fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("wall time of fit [s]")
    ax.grid(alpha=0.3, axis="y")
    made["wall_time.png"] = fig

    fig, ax = plt.subplots(figsize=(7, 4))
    bars(ax, "failures")
    ax.set_ylabel("failures (cases)")
    ax.legend(fontsize=8)
    made["failures.png"] = fig
    for f in made.values():
        f.suptitle(f"identifier comparison ({len(outcomes) // max(len(names), 1)} cases)", fontsize=10)
    return made


def tensorboard_log(folder: Path, outcomes, rows, markdown: list[str], figs: dict) -> None:
    from torch.utils.tensorboard import SummaryWriter

    w = SummaryWriter(log_dir=str(folder))
    cases = list(dict.fromkeys(o.case for o in outcomes))
    for o in outcomes:
        step = cases.index(o.case)
        w.add_scalar(f"{o.identifier}/wall_s", o.wall_s, step)
        w.add_scalar(f"{o.identifier}/failed", float(o.failed), step)
        if not o.failed:
            w.add_scalar(f"{o.identifier}/mean_error_pct", 100 * o.mean_error, step)
            w.add_scalar(f"{o.identifier}/max_error_pct", 100 * o.max_error, step)
            w.add_scalar(f"{o.identifier}/r_ident_min", min(o.r_ident), step)
            w.add_scalar(f"{o.identifier}/r_unseen_min", min(o.r_unseen), step)
    for r in rows:
        if "mean_error" in r:
            w.add_scalar(f"summary/{r['identifier']}/mean_error_pct", 100 * r["mean_error"], round(100 * r["noise"]))
    w.add_text("summary", "\n".join(markdown))
    w.add_text("cases", "\n".join(f"{i}: {c}" for i, c in enumerate(cases)))
    for name, f in figs.items():
        w.add_figure(f"figures/{name}", f, close=False)
    w.close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", required=True, help="study config YAML (e.g. configs/compare.yaml)")
    ap.add_argument("-o", "--output", default="compare-results", help="output folder (default: %(default)s)")
    ap.add_argument("--force", action="store_true", help="replace an existing output folder")
    ap.add_argument("-q", "--quiet", action="store_true", help="print only errors")
    ap.add_argument("-v", "--verbose", action="store_true", help="print details")
    a = ap.parse_args(argv)
    _progress.set_verbosity(0 if a.quiet else 2 if a.verbose else 1)
    try:
        cfg = load_compare_config(a.config)
        base = Path(a.config).resolve().parent
        for name in cfg.identifiers:  # bad settings fail now, not after an hour
            try:
                make_identifier(name, cfg.settings.get(name), base_dir=base)
            except InputError as e:
                raise InputError(str(e), source=None if e.source else a.config) from None
        out = Path(a.output)
        if out.exists() and any(out.iterdir()) and not a.force:
            raise InputError("output folder exists and is not empty; use --force to replace it", source=str(out))
        _progress.info(f"[compare] building the cases of {a.config}")
        cases = build_cases(cfg, base)
        unseen = study_record(cfg.unseen_record, cfg, base)
        if any(c.motion.source == unseen.source for c in cases):
            raise InputError(f"unseen_record {cfg.unseen_record} is also an identification record; choose another",
                             source=a.config)
        outcomes = []
        with atomic_directory(out, force=a.force) as tmp, tempfile.TemporaryDirectory(prefix="hlaid-svm-") as cache:
            for i, case in enumerate(cases):
                _progress.info(f"[compare] case {i + 1}/{len(cases)}: {case.name}")
                outcomes += run_case(case, cfg.identifiers, cfg.settings, unseen, failure_r=cfg.failure_r,
                                     base_dir=base, cache_dir=cache if cfg.share_hlasvm_cache else "",
                                     shared_cache=cfg.share_hlasvm_cache)
            rows = summarise(outcomes)
            title = (f"# Identifier comparison: {len(cases)} cases x {len(cfg.identifiers)} identifiers\n\n"
                     f"Config `{a.config}`; records at PGA {cfg.pga_g} g, {cfg.rate_hz:g} Hz, "
                     f"window {cfg.window_s} s; unseen record {unseen.name}. Errors are |relative| over every "
                     "story parameter; R is the correlation of replayed and true floor displacements. Wall times "
                     "were measured in this run, one identifier at a time.")
            md = [title] + summary_tables(rows)
            (tmp / "figures").mkdir()
            figs = figures(outcomes, cfg.identifiers)
            tensorboard_log(tmp / "tensorboard", outcomes, rows, md, figs)
            for name, f in figs.items():
                save_figure(f, tmp / "figures" / name)
            text = "\n".join(md + ["\n## Every outcome\n"] + outcome_table(outcomes)) + "\n"
            atomic_write(tmp / "summary.md", lambda p: p.write_text(text))
            write_csv(tmp / "results.csv", outcomes)
            write_json(tmp / "results.json", {"config": config_to_dict(cfg), "summary": rows,
                                              "cases": [c.name for c in cases],
                                              "outcomes": [o.to_dict() for o in outcomes]})
        print("\n".join(md))
        _progress.info(f"[compare] wrote {out}/summary.md, results.csv, results.json, figures/, tensorboard/")
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
