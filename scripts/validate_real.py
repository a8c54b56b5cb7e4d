"""Real-structure validation: clones identified from measured records predict events they never saw.

    python scripts/validate_real.py --config configs/validate_real.yaml --out runs/validation \\
        --figures docs/figures/validation [--structures steel-frame,hotel] [--cache DIR | --no-cache] [--force]

Per structure of the config (``hlaid.studies.validation.ValidationConfig``): identify a clone from each
identification event (the paper's method, or a labelled linear clone when no story yielded),
save it and load it back, replay it under every prediction event, and compare with what was
measured (R per floor, peak-drift error, stiffness evolution against HLA). Writes
``validation.json``, ``tables.md`` and ``clones/*.json`` into ``--out`` (a new folder, or
replaced with ``--force``), figures into ``--figures`` (``''``: none), and prints the tables.
The protocol is ``hlaid.studies.validation.run_validation``; this script adds the figures.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from hlaid import _progress
from hlaid._fileio import atomic_directory, write_json
from hlaid.errors import InputError
from hlaid.hla.plots import plot_stiffness
from hlaid.plots import plot_measured_predicted, plt, save_figure, story_axes
from hlaid.studies.validation import (
    ValidationResult,
    format_tables,
    load_validation_config,
    run_validation,
)


def _window(p, pad_s: float = 3.0) -> slice:
    """The strong part of a record: where the measured roof displacement exceeds 10 % of its peak."""
    roof = np.abs(p.disp_measured[:, -1])
    idx = np.flatnonzero(roof > 0.1 * roof.max())
    pad = int(pad_s / (p.time[1] - p.time[0]))
    return slice(max(idx[0] - pad, 0), min(idx[-1] + pad, roof.size))


def plot_displacement(p, levels=None):
    """Measured against predicted floor displacement (relative to the ground), one panel per floor."""
    what = "self-replay" if p.self_replay else "prediction"
    q = p.prediction
    return plot_measured_predicted(q.time, q.disp_measured, q.disp_predicted, q.r, label=f"clone ({p.kind})",
                                   levels=levels, title=f"{p.structure}: clone from {p.identified_from}, {what} of "
                                   f"{p.event} ({q.band_hz[0]:.2g}-{q.band_hz[1]:.2g} Hz)")


def plot_loops(p):
    """Story force against drift: HLA of the measured event against the clone's spring force."""
    fig, axes = story_axes(p.hla.n_stories, size=(3.3, 2.8))
    for i, (s, ax) in enumerate(zip(p.hla.stories, axes)):
        ax.plot(s.drift, s.force_fit, color="k", lw=0.5, label="measured (HLA)")
        check = p.prediction.hla_check
        ax.plot(check.drift[:, i], check.force[:, i], color="C3", lw=0.6, alpha=0.8, label="clone")
        ax.set_title(f"story {i + 1}", fontsize=9)
        ax.set_xlabel("drift [mm]", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("force / total mass [N/t]", fontsize=8)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{p.structure}: loops of {p.event}, clone from {p.identified_from}", fontsize=10)
    return fig


def plot_r_matrix(res: ValidationResult, structure: str):
    """Mean R of every (clone, event) pair of a structure."""
    ps = [p for p in res.predictions if p.structure == structure]
    src = list(dict.fromkeys(p.identified_from for p in ps))
    ev = list(dict.fromkeys(e for p in ps for e in [p.event]))
    ev = sorted(ev, key=lambda e: next(p.pga_g for p in ps if p.event == e))
    m = np.full((len(src), len(ev)), np.nan)
    for p in ps:
        m[src.index(p.identified_from), ev.index(p.event)] = np.mean(p.r)
    fig, ax = plt.subplots(figsize=(1.2 * len(ev) + 2, 0.6 * len(src) + 1.6))
    im = ax.imshow(m, vmin=0.5, vmax=1.0, cmap="RdYlGn")
    for (i, j), v in np.ndenumerate(m):
        if np.isfinite(v):
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=8)
    ax.set_xticks(range(len(ev)), ev)
    ax.set_yticks(range(len(src)), [f"{s} ({next(p.kind for p in ps if p.identified_from == s)})" for s in src])
    ax.set_xlabel("predicted event (by PGA)")
    ax.set_ylabel("clone identified from")
    fig.colorbar(im, ax=ax, label="mean R")
    ax.set_title(f"{structure}: mean R per clone and event (diagonal: self-replay)", fontsize=9)
    return fig


def plot_r_by_pga(res: ValidationResult, structure: str):
    """Mean R against the event's PGA (cross-event predictions)."""
    ps = [p for p in res.predictions if p.structure == structure]
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for p in ps:
        ax.plot(p.pga_g, np.mean(p.r), "o" if not p.self_replay else "*", color="C3" if p.self_replay else "C0", ms=6)
        ax.annotate(p.event, (p.pga_g, np.mean(p.r)), fontsize=8, xytext=(2, 2), textcoords="offset points")
    ax.axhline(res.targets.r_mean, color="k", ls=":", lw=1, label=f"paper {res.targets.r_mean}")
    ax.set_xscale("log")
    ax.set_xlabel("PGA [g]")
    ax.set_ylabel("mean R")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{structure}: clone from {ps[0].identified_from} (star: self-replay)", fontsize=9)
    return fig


def figures(res: ValidationResult, cfg, folder: Path, force: bool) -> list[Path]:
    """Per structure: the R matrix (or R against PGA when many events), for every clone the
    displacement of its strongest other event (or itself), and for nonlinear clones the loops and
    the stiffness evolution of that event."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []

    def save(fig, name):
        out.append(save_figure(fig, _checked(folder / name, force), dpi=72))

    levels = {s.name: s.levels for s in cfg.structures}
    for name in dict.fromkeys(p.structure for p in res.predictions):
        ps = [p for p in res.predictions if p.structure == name]
        if len({p.event for p in ps}) > 6:
            save(plot_r_by_pga(res, name), f"{name}_r_by_pga.png")
        elif len({p.event for p in ps}) > 1:
            save(plot_r_matrix(res, name), f"{name}_r_matrix.png")
        for src in dict.fromkeys(p.identified_from for p in ps):
            own = [p for p in ps if p.identified_from == src]
            others = [p for p in own if not p.self_replay]
            p = max(others, key=lambda q: q.pga_g) if others else own[0]
            tag = f"{name}_{src}_to_{p.event}".replace(".", "p")
            save(plot_displacement(p, levels.get(name)), f"{tag}_disp.png")
            if p.kind == "nonlinear" and p.hla is not None:
                save(plot_loops(p), f"{tag}_loops.png")
                fig = plot_stiffness(p.hla, clone_ke=p.prediction.hla_check.ke)
                w = _window(p.prediction)
                for ax in fig.axes:
                    ax.set_xlim(p.prediction.time[w.start], p.prediction.time[w.stop - 1])
                fig.suptitle(f"{name}: stiffness evolution of {p.event}, HLA against the clone from {src}", fontsize=10)
                save(fig, f"{tag}_stiffness.png")
    return out


def _checked(path: Path, force: bool) -> Path:
    if path.exists() and not force:
        raise InputError("already exists; use --force to overwrite", source=str(path))
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/validate_real.yaml", help="validation config YAML")
    ap.add_argument("--out", default="runs/validation", help="output folder (validation.json, tables.md, clones/)")
    ap.add_argument("--figures", default="docs/figures/validation", help="figure folder ('' for none)")
    ap.add_argument("--structures", help="comma-separated structure names (default all)")
    ap.add_argument("--cache", help="classifier cache folder (default: the config's, else ~/.cache/hlaid/svm)")
    ap.add_argument("--no-cache", action="store_true", help="train every classifier afresh and cache nothing")
    ap.add_argument("--force", action="store_true", help="replace the output folder and figures")
    ap.add_argument("-q", "--quiet", action="store_true")
    args = ap.parse_args(argv)
    if args.quiet:
        _progress.set_verbosity(0)
    t0 = time.perf_counter()
    try:
        cfg = load_validation_config(args.config)
        if args.figures and not args.force and any(Path(args.figures).glob("*.png")):
            # before any work: the figures are only known once the clones are identified
            raise InputError("already holds figures; use --force to overwrite them, or another --figures",
                             source=args.figures)
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        with atomic_directory(out, force=args.force) as tmp:
            res = run_validation(cfg, clone_dir=str(tmp / "clones"), cache_dir="" if args.no_cache else args.cache,
                                 structures=args.structures.split(",") if args.structures else None)
            tables = format_tables(res)
            write_json(tmp / "validation.json", res.to_dict())
            (tmp / "tables.md").write_text(tables)
        figs = figures(res, cfg, Path(args.figures), args.force) if args.figures else []
    except InputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(tables)
    _progress.info(f"wrote {out}/ ({len(res.clones)} clones, {len(res.predictions)} predictions) and "
                   f"{len(figs)} figures in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
