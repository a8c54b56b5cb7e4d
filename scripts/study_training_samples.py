"""The paper's Fig. 2: classifier test accuracy for alpha and p against the number of
training samples (100 ... 2000), on half cycles simulated around the Table 1 structure.

    python scripts/study_training_samples.py --config configs/svm.yaml --out runs/fig2 [--noise 0.1]

``--mode path`` (the identification's default, :mod:`hlaid.identify.pathtrain`): the
measurement is simulated (Table 1 under the config's record, ``--noise``), its HLA drift is
reconstructed with the building (:mod:`hlaid.identify.drift`), and the training samples are
the story law driven along each story's path: one feature vector per story and sample, held
out at random. Standardised features, C cross-validated as in identification.

``--mode simulate`` (the first version): dynamic simulations, HLA of each, one sample per
half cycle. Two accuracies are reported per size: per half cycle (what a machine scores on
one held-out simulated half cycle) and per response (the vote over all yielding half cycles
of one held-out simulated response), plus the share within one bin of the truth.
Writes ``fig2.png``, ``fig2.json`` and TensorBoard scalars.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from hlaid.config import load_config
from hlaid.identify.classify import make_svc
from hlaid.identify.svmtrain import TrainSVMConfig, pass_bins
from hlaid.identify.tb import TBLogger
from hlaid.identify.training import Ranges, simulate_training_sets, strong_motion_window
from hlaid.measurement import measured_ground
from hlaid.motions import GroundMotion
from hlaid.plots import plt, save_figure
from hlaid.signal import lowpass


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/svm.yaml")
    ap.add_argument("--out", default="runs/fig2")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 500, 700, 1000, 1500, 2000])
    ap.add_argument("--noise", type=float, default=None, help="override the config's noise_rms")
    ap.add_argument("--spread", type=float, default=None, help="override training.spread")
    ap.add_argument("--story", type=int, default=None, help="only this story (1-based)")
    ap.add_argument("--mode", choices=("path", "simulate"), default="path")
    ap.add_argument("--seed", type=int, default=0, help="noise seed of the simulated measurement (path mode)")
    ap.add_argument("--per-half-cycle", type=int, default=1500,
                    help="at this size also train one machine per half cycle and vote (path mode; 0: off)")
    args = ap.parse_args(argv)
    cfg = load_config(args.config, TrainSVMConfig)
    if args.mode == "path":
        return path_mode(args, cfg)
    noise = cfg.noise_rms if args.noise is None else args.noise
    tcfg = cfg.identify.training
    if args.spread is not None:
        tcfg = dataclasses.replace(tcfg, spread=args.spread)
    b = cfg.building.build()
    gm = cfg.motion.load(Path(args.config).parent).resampled(200.0)
    ground = strong_motion_window(GroundMotion(dt=gm.dt, acc=lowpass(gm.acc, gm.dt, 20.0)),
                                  tcfg.arias_fraction, tcfg.tail_s)
    bins = pass_bins(b, cfg.alpha_max, cfg.identify, "coarse")
    need = int(max(args.sizes) / (1 - tcfg.test_fraction)) + 1
    t0 = time.perf_counter()
    sets = simulate_training_sets(b, ground, Ranges(alpha=np.array([bb[0].range for bb in bins]),
                                                    p=np.array([bb[1].range for bb in bins])),
                                  n_samples=need, noise_rms=noise, hla_config=cfg.identify.hla,
                                  n_segments=tcfg.n_segments, spread=tcfg.spread, max_simulations=4000,
                                  seed=tcfg.seed, n_jobs=cfg.identify.n_jobs)
    print(f"simulated {[len(s) for s in sets]} half cycles in {time.perf_counter() - t0:.0f} s "
          f"(noise {noise:.0%}, spread {tcfg.spread:.0%})")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tb = TBLogger(str(out / "tensorboard"))
    every = max(2, int(round(1 / tcfg.test_fraction)))
    rng = np.random.default_rng(0)
    rows = []
    stories = [args.story - 1] if args.story else range(b.n_stories)
    for s in stories:
        S = sets[s]
        test = S.sim % every == 0
        train_idx = rng.permutation(np.flatnonzero(~test))
        for param, bb in zip(("alpha", "p"), bins[s]):
            y = bb.label(getattr(S, param))
            for n in args.sizes:
                idx = train_idx[:n]
                if len(idx) < n or len(np.unique(y[idx])) < 2:
                    continue
                t = time.perf_counter()
                m = make_svc(cfg.identify.svm).fit(S.X[idx], y[idx])
                fit_s = time.perf_counter() - t
                pred = m.predict(S.X[test])
                yt = y[test]
                resp, near = [], []
                for sim in np.unique(S.sim[test]):
                    sel = S.sim[test] == sim
                    v = np.bincount(pred[sel], minlength=bb.n).argmax()
                    resp.append(v == yt[sel][0])
                    near.append(abs(v - yt[sel][0]) <= 1)
                row = {"story": s + 1, "param": param, "n": n, "classes": bb.n,
                       "acc_half_cycle": float(np.mean(pred == yt)),
                       "within_one_bin": float(np.mean(np.abs(pred - yt) <= 1)), "acc_response": float(np.mean(resp)),
                       "response_within_one_bin": float(np.mean(near)), "fit_seconds": fit_s}
                rows.append(row)
                tb.scalar(f"fig2/story{s + 1}/{param}/acc_half_cycle", row["acc_half_cycle"], n)
                tb.scalar(f"fig2/story{s + 1}/{param}/acc_response", row["acc_response"], n)
                print(f"story {s + 1} {param:5s} n={n:5d} half cycle {row['acc_half_cycle']:.3f} "
                      f"(+-1 bin {row['within_one_bin']:.3f})  response {row['acc_response']:.3f} "
                      f"(+-1 bin {row['response_within_one_bin']:.3f})  fit {fit_s:.2f} s", flush=True)
    tb.close()
    (out / "fig2.json").write_text(json.dumps({"noise_rms": noise, "spread": tcfg.spread, "rows": rows}, indent=1))
    plot(rows, stories, [("acc_half_cycle", "o-", "per half cycle"), ("response_within_one_bin", "s--",
                                                                        "per response, +-1 bin")],
         f"Classifier accuracy vs training samples (noise {noise:.0%}, spread {tcfg.spread:.0%})", out)
    return 0


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


def path_sets(cfg, noise: float, spread: float, n: int, seed: int):
    """Path-driven training sets of every story around the config's building, along the drift
    path reconstructed from a simulated measurement of it; ``(sets, bins)``."""
    from hlaid.hla import run_hla
    from hlaid.hla.features import half_cycle_features
    from hlaid.identify.drift import reconstruct_drift
    from hlaid.identify.pathtrain import path_training_set, story_paths
    from hlaid.synthetic import simulate_measurement

    b = cfg.building.build()
    gm = cfg.motion.load(None)
    meas = simulate_measurement(b, gm, noise_rms=noise, seed=seed)
    res = run_hla(meas, cfg.identify.hla)
    ground = measured_ground(meas, res.band_hz[1], name="")
    paths = reconstruct_drift(res, ground, b, crossover_hz=cfg.identify.training.crossover_hz)
    bins = pass_bins(b, cfg.alpha_max, cfg.identify, "coarse")
    tc = cfg.identify.training
    stories = [dataclasses.replace(s, drift=paths[:, i], force_fit=s.force) for i, s in enumerate(res.stories)]
    sps = story_paths(stories, [half_cycle_features(s, tc.n_segments) for s in stories], mass=b.mass, k0=b.k0,
                      floor_acc=meas.floor_acc, noise_rms=noise, dt=meas.dt, cutoff_hz=res.band_hz[1],
                      n_segments=tc.n_segments)
    sets = []
    for i, sp in enumerate(sps):
        sets.append(path_training_set(sp, k0=float(b.k0[i]), dy=float(b.dy[i]), delta_eta=float(b.delta_eta[i]),
                                      alpha_range=bins[i][0].range, p_range=bins[i][1].range, n_samples=n,
                                      spread=spread, seed=cfg.identify.training.seed + i))
    return sets, bins


def per_half_cycle_votes(S, y, idx, test, n_classes: int, cfg) -> float:
    """The alternative layout: one machine per measured half cycle (its own segment slopes),
    each held-out sample classified by the majority vote of its half cycles' machines."""
    from hlaid.identify.classify import apply_scaler, scaler_of

    nseg = cfg.identify.training.n_segments
    votes = np.zeros((int(test.sum()), n_classes))
    for j in range(S.X.shape[1] // nseg):
        cols = slice(j * nseg, (j + 1) * nseg)
        sc = scaler_of(S.X[idx, cols])
        X = apply_scaler(S.X[:, cols], sc)
        pred = make_svc(cfg.identify.svm, 100.0).fit(X[idx], y[idx]).predict(X[test]).astype(int)
        votes[np.arange(pred.size), pred] += 1
    return float(np.mean(votes.argmax(axis=1) == y[test]))


def path_mode(args, cfg) -> int:
    from hlaid.identify.classify import apply_scaler, choose_hyper, scaler_of

    noise = cfg.noise_rms if args.noise is None else args.noise
    tcfg = cfg.identify.training
    spread = tcfg.spread if args.spread is None else args.spread
    n_test = 500
    t0 = time.perf_counter()
    sets, bins = path_sets(cfg, noise, spread, max(args.sizes) + n_test, args.seed)
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
