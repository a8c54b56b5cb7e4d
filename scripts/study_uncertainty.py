"""Coverage of the identification uncertainty intervals (issue 15), on simulated measurements.

    python scripts/study_uncertainty.py --part run --set heldout --n 60 --out runs/study_uncert --cache runs/uq_cache
    python scripts/study_uncertainty.py --part run --set calibration --n 30 --out runs/study_uncert --cache runs/uq_cache
    python scripts/study_uncertainty.py --part analyse --out runs/study_uncert
    python scripts/study_uncertainty.py --part bootstrap --out runs/study_uncert --cache runs/uq_cache

``run``: random 2-6 story buildings (as ``scripts/study_identification.py``'s random part)
under six far-field records scaled until every story reaches 1.5 dy, 10 % noise, a noise
seed per case; each case identified and its refinement's Jacobian and residuals stored in
``<out>/<set>/case_NNN.npz`` (resumable: existing cases are skipped). The two sets draw
their buildings from different seeds, so a calibration fitted on one is tested on the other.
``analyse``: per covariance method (naive, neff, sandwich) the fraction of true parameters
inside the nominal 90 % intervals, per parameter and overall, on the held-out set; the
calibration factor fitted on the calibration set; a calibration plot (observed against
nominal coverage) in ``<out>/coverage.png`` and the figures in ``<out>/coverage.json``/``.md``.
``bootstrap``: on a few cases, the Laplace standard deviations against a parametric
bootstrap (re-identification on re-noised simulations of the clone).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study_identification import RANDOM_RECORDS, random_building, scale_to_yield  # noqa: E402

from hlaid import _progress  # noqa: E402
from hlaid.identify import IdentifyConfig, identify  # noqa: E402
from hlaid.motions import read_motion  # noqa: E402
from hlaid.synthetic import simulate_measurement  # noqa: E402
from hlaid.uncertainty import calibration_factor, coverage, parametric_bootstrap, zscores  # noqa: E402
from hlaid.uncertainty.laplace import METHODS, from_refinement  # noqa: E402

SET_SEEDS = {"heldout": 1515, "calibration": 2727}
PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")
LEVELS = np.array([0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99])


def cases(which: str, n: int):
    rng = np.random.default_rng(SET_SEEDS[which])
    out = []
    while len(out) < n:
        b = random_building(rng)
        gm = scale_to_yield(b, read_motion(RANDOM_RECORDS[len(out) % len(RANDOM_RECORDS)]))
        if gm is not None:
            out.append((b, gm, SET_SEEDS[which] + len(out)))
    return out


def run(args) -> None:
    folder = Path(args.out) / args.set
    folder.mkdir(parents=True, exist_ok=True)
    cfg = IdentifyConfig()
    for j, (truth, gm, seed) in enumerate(cases(args.set, args.n)):
        path = folder / f"case_{j:03d}.npz"
        if path.exists():
            continue
        meas = simulate_measurement(truth, gm, noise_rms=0.10, seed=seed)
        t = time.perf_counter()
        try:
            res = identify(meas, cfg, cache_dir=args.cache)
        except ValueError as err:
            print(f"[{j + 1}/{args.n}] {gm.name}: FAILED {err}", flush=True)
            np.savez(path, failed=str(err))
            continue
        rr = res.refinement
        slots = np.array([f"{n}:{i}" for n, i in rr.slots])
        true_x = np.array([getattr(truth, n)[i] if n != "damping" else truth.damping.ratio for n, i in rr.slots])
        np.savez_compressed(path, slots=slots, x=rr.x, true_x=true_x, jacobian=rr.jacobian.astype(np.float32),
                            residuals=rr.residuals, n_floors=meas.n_floors, record=gm.name, seed=seed,
                            seconds=time.perf_counter() - t, clone=json.dumps(res.clone.to_dict()))
        err = np.abs(rr.x / true_x - 1)
        print(f"[{j + 1}/{args.n}] {gm.name} {truth.n_stories} stories: {len(slots)} parameters, mean error "
              f"{err.mean():.3f} worst {err.max():.3f}, {time.perf_counter() - t:.0f} s", flush=True)


class _RR:
    """The parts of a RefineResult the covariance needs, read back from a case file."""

    def __init__(self, z):
        self.slots = tuple((s.split(":")[0], int(s.split(":")[1])) for s in z["slots"])
        self.x, self.jacobian, self.residuals = z["x"], z["jacobian"].astype(float), z["residuals"]


def load(folder: Path) -> list:
    out = []
    for p in sorted(folder.glob("case_*.npz")):
        z = np.load(p, allow_pickle=False)
        if "failed" in z:
            continue
        out.append((_RR(z), z["true_x"], int(z["n_floors"])))
    return out


def all_zscores(data, method: str) -> tuple[np.ndarray, list]:
    """Standardised errors (theta_hat - theta_true) / std of every slot of every case."""
    z, names = [], []
    for rr, true_x, nf in data:
        u = from_refinement(rr, nf, method=method)
        z.append(zscores(u, true_x))
        names += [n for n, _ in u.slots]
    return np.concatenate(z), names


def analyse(args) -> None:
    out = Path(args.out)
    held, cal = load(out / "heldout"), load(out / "calibration")
    report = {"cases_heldout": len(held), "cases_calibration": len(cal), "methods": {}}
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.2, 4.6))
    ax.plot([0.45, 1], [0.45, 1], "k:", lw=1, label="ideal")
    for method in METHODS:
        zh, names = all_zscores(held, method)
        entry = {"uncalibrated": {}, "calibrated": {}}
        scale = 1.0
        if cal:
            zc, _ = all_zscores(cal, method)
            scale = calibration_factor(zc, 0.9)  # the factor giving 90 % on the calibration set
            entry["calibration_factor"] = scale
        for key, s in (("uncalibrated", 1.0), ("calibrated", scale)):
            names_a = np.array(names)
            entry[key]["overall_90"] = coverage(zh, 0.9, s)
            entry[key]["per_parameter_90"] = {p: coverage(zh[names_a == p], 0.9, s) for p in PARAMS if (names_a == p).any()}
            entry[key]["levels"] = {f"{lv:g}": coverage(zh, lv, s) for lv in LEVELS}
        entry["n_intervals"] = int(zh.size)
        entry["median_abs_z"] = float(np.median(np.abs(zh)))
        report["methods"][method] = entry
        ax.plot(LEVELS, [entry["uncalibrated"]["levels"][f"{lv:g}"] for lv in LEVELS], "o-", label=method)
        if method == "sandwich" and cal:
            ax.plot(LEVELS, [entry["calibrated"]["levels"][f"{lv:g}"] for lv in LEVELS], "s--",
                    label=f"sandwich x {scale:.2f} (factor from calibration set)")
    ax.axhspan(0.85, 0.95, xmin=0, xmax=1, color="0.9", zorder=0)
    ax.set_xlabel("nominal coverage of the interval")
    ax.set_ylabel("observed fraction of true values inside")
    ax.set_title(f"Held-out: {len(held)} random buildings, 10 % noise", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "coverage.png", dpi=120)
    (out / "coverage.json").write_text(json.dumps(report, indent=1))
    lines = [f"Held-out cases: {len(held)}, calibration cases: {len(cal)}", "",
             "| method | overall 90 % | " + " | ".join(PARAMS) + " | factor (calibration set) |",
             "|---|---|" + "---|" * len(PARAMS) + "---|"]
    for m, e in report["methods"].items():
        for key in ("uncalibrated", "calibrated"):
            pp = e[key]["per_parameter_90"]
            lines.append(f"| {m} {key} | {e[key]['overall_90']:.1%} | "
                         + " | ".join(f"{pp.get(p, float('nan')):.1%}" for p in PARAMS)
                         + f" | {e.get('calibration_factor', float('nan')):.2f} |")
    (out / "coverage.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def bootstrap(args) -> None:
    out = Path(args.out)
    rows = []
    cfg = IdentifyConfig()
    for j, (truth, gm, seed) in enumerate(cases("heldout", args.n_boot_cases)):
        meas = simulate_measurement(truth, gm, noise_rms=0.10, seed=seed)
        res = identify(meas, cfg, cache_dir=args.cache)
        t = time.perf_counter()
        boot = parametric_bootstrap(res.clone, meas, args.n_boot, config=cfg, cache_dir=args.cache, seed=j)
        u = res.clone.uncertainty
        theta = np.log(np.maximum(boot.values, 1e-300))
        std_boot = theta.std(axis=0, ddof=1)
        rows.append({"case": j, "record": gm.name, "stories": truth.n_stories, "names": u.names,
                     "std_laplace": u.std.tolist(), "std_bootstrap": std_boot.tolist(),
                     "ratio": (u.std / std_boot).tolist(), "failed": boot.failed,
                     "seconds": time.perf_counter() - t})
        r = np.array(rows[-1]["ratio"])
        print(f"case {j}: {truth.n_stories} stories, Laplace/bootstrap std ratio median {np.median(r):.2f} "
              f"(range {r.min():.2f}-{r.max():.2f}), {boot.failed} failed, {rows[-1]['seconds']:.0f} s", flush=True)
        (out / "bootstrap.json").write_text(json.dumps(rows, indent=1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", choices=["run", "analyse", "bootstrap"], default="run")
    ap.add_argument("--set", choices=list(SET_SEEDS), default="heldout")
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--out", default="runs/study_uncert")
    ap.add_argument("--cache", default="", help="classifier cache folder ('' = none)")
    ap.add_argument("--n-boot", type=int, default=20)
    ap.add_argument("--n-boot-cases", type=int, default=3)
    args = ap.parse_args(argv)
    _progress.set_verbosity(0)
    {"run": run, "analyse": analyse, "bootstrap": bootstrap}[args.part](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
