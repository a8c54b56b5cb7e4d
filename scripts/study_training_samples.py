"""The paper's Fig. 2: classifier test accuracy for alpha and p against the number of
training samples (100 ... 2000), around the Table 1 structure.

    python scripts/study_training_samples.py --config configs/svm.yaml --out runs/fig2 [--noise 0.1]

The measurement is simulated (Table 1 under the config's record, ``--noise``), its HLA drift is
reconstructed with the building, and the training samples are the story law driven along each
story's path as in an identification (:mod:`hlaid.studies.training_samples`): one feature
vector per story and sample, held out at random. Standardised features, C and gamma
cross-validated as in identification. Writes ``fig2.png``, ``fig2.json`` and TensorBoard scalars.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from hlaid.config import load_config
from hlaid.identify.classify import apply_scaler, choose_hyper, make_svc, scaler_of
from hlaid.identify.tb import TBLogger
from hlaid.plots import plt, save_figure
from hlaid.studies.training_samples import TrainingSamplesConfig, path_training_sets


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/svm.yaml")
    ap.add_argument("--out", default="runs/fig2")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 500, 700, 1000, 1500, 2000])
    ap.add_argument("--noise", type=float, default=None, help="override the config's noise_rms")
    ap.add_argument("--spread", type=float, default=None, help="override training.spread")
    ap.add_argument("--story", type=int, default=None, help="only this story (1-based)")
    ap.add_argument("--seed", type=int, default=0, help="noise seed of the simulated measurement")
    ap.add_argument("--per-half-cycle", type=int, default=1500,
                    help="at this size also train one machine per half cycle and vote (0: off)")
    args = ap.parse_args(argv)
    return study(args, load_config(args.config, TrainingSamplesConfig))


def plot(rows, stories, series, title: str, out: Path) -> None:
    """Fig. 2: accuracy against training samples, alpha and p side by side; ``series`` are
    ``(row key, line style, label)``."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, param in zip(axes, ("alpha", "p")):
        for s in stories:
            r = [x for x in rows if x["story"] == s + 1 and x["param"] == param]
            for key, style, label in series:
                ax.plot([x["n"] for x in r], [x[key] for x in r], style, label=f"story {s + 1} {label}".strip())
        ax.axhline(0.94, color="k", lw=0.8, ls=":", label="paper: 94 %")
        ax.set_title(f"{param} (coarse bins)")
        ax.set_xlabel("training samples")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("test accuracy")
    axes[1].legend(fontsize=7)
    fig.suptitle(title)
    save_figure(fig, out / "fig2.png")
    print(f"wrote {out}/fig2.png, fig2.json, tensorboard/")


def per_half_cycle_votes(S, y, idx, test, n_classes: int, cfg) -> float:
    """The alternative layout: one machine per measured half cycle (its own segment slopes),
    each held-out sample classified by the majority vote of its half cycles' machines."""
    nseg = cfg.identify.training.n_segments
    votes = np.zeros((int(test.sum()), n_classes))
    for j in range(S.X.shape[1] // nseg):
        cols = slice(j * nseg, (j + 1) * nseg)
        sc = scaler_of(S.X[idx, cols])
        X = apply_scaler(S.X[:, cols], sc)
        pred = make_svc(cfg.identify.svm, 100.0).fit(X[idx], y[idx]).predict(X[test]).astype(int)
        votes[np.arange(pred.size), pred] += 1
    return float(np.mean(votes.argmax(axis=1) == y[test]))


def study(args, cfg) -> int:
    noise = cfg.noise_rms if args.noise is None else args.noise
    tcfg = cfg.identify.training
    spread = tcfg.spread if args.spread is None else args.spread
    n_test = 500
    t0 = time.perf_counter()
    sets, bins = path_training_sets(cfg, noise=noise, spread=spread, n=max(args.sizes) + n_test, seed=args.seed)
    print(f"path-driven sets {[len(s) for s in sets]} in {time.perf_counter() - t0:.1f} s "
          f"(noise {noise:.0%}, spread {spread:.0%})")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tb = TBLogger(str(out / "tensorboard"))
    rows = []
    stories = [args.story - 1] if args.story else range(len(sets))
    for s in stories:
        S = sets[s]
        test = np.arange(len(S)) >= len(S) - n_test
        for param, bb in zip(("alpha", "p"), bins[s]):
            y = bb.label(getattr(S, param))
            for n in args.sizes:
                idx = np.arange(n)
                t = time.perf_counter()
                sc = scaler_of(S.X[idx])
                X = apply_scaler(S.X, sc)
                h = choose_hyper(X[idx], y[idx], cfg.identify.svm)
                m = make_svc(cfg.identify.svm, h.C, h.gamma).fit(X[idx], y[idx])
                fit_s = time.perf_counter() - t
                pred = m.predict(X[test])
                yt = y[test]
                row = {"story": s + 1, "param": param, "n": n, "classes": bb.n, "C": h.C,
                       "gamma_factor": h.gamma_factor, "accuracy": float(np.mean(pred == yt)),
                       "within_one_bin": float(np.mean(np.abs(pred - yt) <= 1)), "fit_seconds": fit_s}
                if args.per_half_cycle and n == args.per_half_cycle:
                    row["accuracy_per_half_cycle_votes"] = per_half_cycle_votes(S, y, idx, test, bb.n, cfg)
                rows.append(row)
                tb.scalar(f"fig2/story{s + 1}/{param}/accuracy", row["accuracy"], n)
                extra = (f" | per-half-cycle machines, votes: {row['accuracy_per_half_cycle_votes']:.3f}"
                         if "accuracy_per_half_cycle_votes" in row else "")
                print(f"story {s + 1} {param:5s} n={n:5d} accuracy {row['accuracy']:.3f} "
                      f"(+-1 bin {row['within_one_bin']:.3f}) C {h.C:g} gamma {h.gamma_factor:g}x "
                      f"fit {fit_s:.2f} s{extra}", flush=True)
    tb.close()
    (out / "fig2.json").write_text(json.dumps({"mode": "path", "noise_rms": noise, "spread": spread,
                                               "n_test": n_test, "rows": rows}, indent=1))
    plot(rows, stories, [("accuracy", "o-", "")],
         f"Path-driven training: accuracy vs samples (noise {noise:.0%}, spread {spread:.0%})", out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
