"""IDA of a clone with each collapse model: median collapse Sa(T1) before/after, and figures.

Case: a clone file (``--clone``, e.g. the demo's ``hlaid-demo/clone.json``) or, by default, the
Table 1 building with 3 m stories; P-Delta on; IDA as ``hlaid ida`` runs it (default settings) over
``--records`` (default the 10 built-in FEMA P695 records; a folder such as the 44 far-field
components works too). Prints, per collapse model, the median collapse Sa(T1), beta, runs and time.

With ``--figures DIR``: ``collapse_backbone.png`` (story 1 of the case: monotonic pushover and a
cyclic path, with and without the steel-mrf model, and the IMK lines), ``collapse_ida.png`` (IDA
curves, none vs steel-mrf) and ``collapse_fragility.png`` (the fitted collapse fragilities).

Usage: python scripts/study_collapse.py [--clone FILE] [--records builtin-suite|DIR] [--figures DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from reference_models import table1_stories

from hlaid import _progress
from hlaid.clone import Clone
from hlaid.ida import IDAConfig, run_ida
from hlaid.io import read
from hlaid.model import Building
from hlaid.model.collapse import COLLAPSE_MODELS
from hlaid.simulate.path import drive_story

REPO = Path(__file__).resolve().parents[1]

MODELS = ("none", "steel-mrf", "rc-frame", "rc-frame-nonductile")


def backbone_figure(b: Building, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    bs = b.replace(collapse="steel-mrf")
    h = float(b.height[0])
    kw = {"k0": b.k0[0], "alpha": b.alpha[0], "p": b.p[0], "dy": b.dy[0], "delta_eta": b.delta_eta[0],
          "mass": b.mass[0]}
    t = np.linspace(0.0, 400.0, 8001)
    push = 0.15 * h / 400.0 * t
    w = 2 * np.pi / 20.0
    cyc = (0.005 + 0.1 * t / 400.0) * h * np.sin(w * t)
    cyc_v = 0.1 * h / 400.0 * np.sin(w * t) + (0.005 + 0.1 * t / 400.0) * h * w * np.cos(w * t)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    kg = bs.geometric_stiffness()[0]
    for ax, (x, v, title) in zip(axes, ((push, np.gradient(push, t), "monotonic pushover"),
                                        (cyc, cyc_v, "cyclic, growing amplitude"))):
        dt = t[1] - t[0]
        f0 = drive_story(x, velocity=v, dt=dt, **kw).force[0] - kg * x
        f1 = drive_story(x, velocity=v, dt=dt, collapse=bs.collapse_values()[0], **kw).force[0] - kg * x
        ax.plot(100 * x / h, f0 / 1e3, color="0.6", lw=1.0, label="none (paper's law), with P-Delta")
        ax.plot(100 * x / h, f1 / 1e3, color="tab:red", lw=1.2, label="steel-mrf, with P-Delta")
        if ax is axes[0]:
            p = bs.collapse.backbone(k0=b.k0[:1], alpha=b.alpha[:1], dy=b.dy[:1], height=b.height[:1])
            xs = np.array([p["xc"][0], min(p["xr"][0], p["xz"][0]), p["xz"][0], 0.15 * h])
            fs = np.maximum(p["fc"][0] + p["kpc"][0] * (xs - p["xc"][0]), np.where(np.isfinite(p["xr"][0]),
                                                                                   p["fr"][0], 0.0))
            ax.plot(100 * xs / h, fs / 1e3, "k--", lw=0.8, label="IMK backbone (no P-Delta)")
        ax.set_xlabel("story 1 drift ratio [%]")
        ax.set_ylabel("story shear [kN]")
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.axhline(0, color="k", lw=0.5)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def ida_figures(results: dict, out: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import norm
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), sharey=True)
    top = max(float(np.nanmax(r.point_im)) for r in results.values())
    for ax, name in zip(axes, ("none", "steel-mrf")):
        r = results[name]
        for i in range(r.n_records):
            im, edp = r.curve(i)
            ax.plot(100 * edp, im, color="0.5", lw=0.7, marker=".", ms=2)
            if np.isfinite(r.collapse_im[i]):  # the flatline at the record's collapse intensity
                ax.plot([100 * edp[-1], 110 * r.drift_limit], [r.collapse_im[i]] * 2, color="0.5", lw=0.7, ls="--")
        m = r.collapse_fragility().median
        ax.axhline(m, color="tab:red", lw=1.2, label=f"median collapse Sa(T1) = {m:.2f} g")
        ax.axvline(100 * r.drift_limit, color="k", lw=0.8, ls=":")
        ax.set_xlim(0, 100 * r.drift_limit * 1.1)
        ax.set_ylim(0, top * 1.02)
        ax.set_xlabel("peak inter-story drift ratio [%]")
        ax.set_title(f"collapse model {name}")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    axes[0].set_ylabel("Sa(T1, 5%) [g]")
    fig.tight_layout()
    fig.savefig(out / "collapse_ida.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    x = np.linspace(0.01, top, 400)
    for name, r in results.items():
        f = r.collapse_fragility()
        ax.plot(x, norm.cdf(np.log(x / f.median) / f.beta), lw=1.6, label=f"{name}: median {f.median:.2f} g, "
                f"beta {f.beta:.2f}")
    ax.set_xlabel("Sa(T1, 5%) [g]")
    ax.set_ylabel("P(collapse)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "collapse_fragility.png", dpi=120)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clone", help="clone file (default: the Table 1 building, 3 m stories)")
    ap.add_argument("--records", default="builtin-suite")
    ap.add_argument("--figures", help="folder for the figures")
    args = ap.parse_args(argv)
    _progress.set_verbosity(0)
    if args.clone:
        b = Clone.load(args.clone).building
        if b.height is None:
            b = b.replace(height=[3000.0] * b.n_stories)
    else:
        b = Building.from_stories(table1_stories(), height=[3000.0] * 3, name="table1")
    motions = read(args.records, "records")
    print(f"{b.name or 'clone'}: {b.n_stories} stories, {len(motions)} records ({args.records}), IDA defaults, "
          "P-Delta on\n")
    print("| collapse model | median collapse Sa(T1) [g] | beta | runs | time [s] |")
    print("|---|---|---|---|---|")
    results = {}
    for name in MODELS:
        t0 = time.perf_counter()
        r = run_ida(b, motions, IDAConfig(collapse=name))
        f = r.collapse_fragility()
        results[name] = r
        print(f"| {name} | {f.median:.3g} | {f.beta:.2f} | {r.point_im.size} | "
              f"{time.perf_counter() - t0:.1f} |", flush=True)
    for name in MODELS[1:]:
        print(f"- {name}: {COLLAPSE_MODELS[name].source}")
    if args.figures:
        out = Path(args.figures)
        out.mkdir(parents=True, exist_ok=True)
        backbone_figure(b, out / "collapse_backbone.png")
        ida_figures(results, out)
        print(f"wrote {out}/collapse_backbone.png, collapse_ida.png, collapse_fragility.png")


if __name__ == "__main__":
    main()
