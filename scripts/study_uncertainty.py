"""Coverage of the identification uncertainty intervals (issue 15), on simulated measurements.

    S=scripts/study_uncertainty.py; O="--out runs/study_uncert --cache runs/uq_cache"
    python $S --part run --set heldout --n 66 $O
    python $S --part run --set calibration --n 20 $O
    python $S --part analyse --out runs/study_uncert
    python $S --part bootstrap --n-boot-cases 1 --n-boot 8 $O

``run``: random 2-6 story buildings (as ``scripts/study_identification.py``'s random part)
under six far-field records scaled until every story reaches 1.5 dy, 10 % noise, a noise
seed per case; each case identified and its refinement's Jacobian and residuals stored in
``<out>/<set>/case_NNN.npz`` (resumable: existing cases are skipped). The two sets draw
their buildings from different seeds, so a calibration fitted on one is tested on the other.
``analyse``: per covariance method (naive, neff, sandwich) the fraction of true parameters
inside the nominal 90 % intervals, per parameter and overall, on the held-out set; the
calibration factor fitted on the calibration set; a calibration plot (observed against
nominal coverage) in ``<out>/coverage.png`` and the figures in ``<out>/coverage.json``/``.md``.
``bootstrap``: on the Table 1 structure under one to three records (PGA 0.62 g), the Laplace
standard deviations against a parametric bootstrap (re-identification on re-noised
simulations of the clone).
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
from hlaid.synthetic import load_simulation_config, simulate_measurement  # noqa: E402
from hlaid.uncertainty import calibration_factor, coverage, parametric_bootstrap, zscores  # noqa: E402
from hlaid.uncertainty.laplace import METHODS, MISFIT_LIMIT, from_refinement, noise_residual_rms  # noqa: E402

SET_SEEDS = {"heldout": 1515, "calibration": 2727}
PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")
BOOT_RECORDS = ["builtin:elcentro-1940-ns", "builtin:kocaeli-1999-dzc180", "builtin:northridge-1994-mul009"]
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
    """(refinement, true values, floors, misfit ratio) of every identified case in ``folder``."""
    s0 = noise_residual_rms(0.10, IdentifyConfig().refine.band_hz, 1 / 200.0)
    out = []
    for p in sorted(folder.glob("case_*.npz")):
        z = np.load(p, allow_pickle=False)
        if "failed" in z:
            continue
        rr = _RR(z)
        out.append((rr, z["true_x"], int(z["n_floors"]), float(np.sqrt(np.mean(rr.residuals**2)) / s0)))
    return out


def all_zscores(data, method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standardised errors (theta_hat - theta_true) / std of every slot of every case, the slots'
    parameter names and whether their case's fit is consistent with the noise."""
    z, names, ok = [], [], []
    for rr, true_x, nf, rho in data:
        u = from_refinement(rr, nf, method=method)
        z.append(zscores(u, true_x))
        names += [n for n, _ in u.slots]
        ok += [rho <= MISFIT_LIMIT] * len(u.slots)
    return np.concatenate(z), np.array(names), np.array(ok)


def _entry(z, names, scale):
    return {"overall_90": coverage(z, 0.9, scale), "n_intervals": int(z.size),
            "per_parameter_90": {p: coverage(z[names == p], 0.9, scale) for p in PARAMS if (names == p).any()},
            "levels": {f"{lv:g}": coverage(z, lv, scale) for lv in LEVELS}}


def analyse(args) -> None:
    out = Path(args.out)
    held, cal = load(out / "heldout"), load(out / "calibration")
    n_ok_h = sum(r[3] <= MISFIT_LIMIT for r in held)
    report = {"cases_heldout": len(held), "cases_calibration": len(cal), "misfit_limit": MISFIT_LIMIT,
              "heldout_fit_consistent": int(n_ok_h), "calibration_fit_consistent": int(sum(r[3] <= MISFIT_LIMIT
                                                                                           for r in cal)),
              "misfit_ratio_heldout": [r[3] for r in held], "rows": {}}
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.6, 4.8))
    ax.axhspan(0.85, 0.95, color="0.9", zorder=0)
    ax.plot([0.45, 1], [0.45, 1], "k:", lw=1, label="ideal")
    rows = report["rows"]
    for method in METHODS:
        zh, nh, okh = all_zscores(held, method)
        rows[f"{method}, all cases"] = _entry(zh, nh, 1.0)
        ax.plot(LEVELS, list(rows[f"{method}, all cases"]["levels"].values()), "o-", ms=4, label=f"{method}, all cases")
        if method != "sandwich" or not cal:
            continue
        zc, nc, okc = all_zscores(cal, method)
        f_all = calibration_factor(zc, 0.9)
        f_ok = calibration_factor(zc[okc], 0.9)
        report["factor_all"], report["factor_consistent"] = f_all, f_ok
        rows[f"sandwich x {f_all:.2f} (factor: calibration set, all cases), all cases"] = _entry(zh, nh, f_all)
        rows[f"sandwich x {f_ok:.2f} (factor: calibration set, consistent fits), consistent fits"] = \
            _entry(zh[okh], nh[okh], f_ok)
        rows[f"sandwich x {f_ok:.2f}, all cases (inconsistent fits included)"] = _entry(zh, nh, f_ok)
        rows["sandwich, consistent fits"] = _entry(zh[okh], nh[okh], 1.0)
        ax.plot(LEVELS, [coverage(zh, lv, f_all) for lv in LEVELS], "s--", ms=4,
                label=f"sandwich x {f_all:.2f}, all cases")
        ax.plot(LEVELS, [coverage(zh[okh], lv, f_ok) for lv in LEVELS], "^-", ms=5, lw=2,
                label=f"sandwich x {f_ok:.2f}, consistent fits")
    ax.set_xlabel("nominal coverage of the interval")
    ax.set_ylabel("fraction of true values inside")
    ax.set_title(f"Held-out: {len(held)} random buildings ({n_ok_h} consistent fits), 10 % noise", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "coverage.png", dpi=120)
    (out / "coverage.json").write_text(json.dumps(report, indent=1))
    lines = [f"Held-out cases: {len(held)} ({n_ok_h} with a fit consistent with the noise, misfit ratio <= "
             f"{MISFIT_LIMIT:g}), calibration cases: {len(cal)}", "",
             "| intervals | 90 % coverage | " + " | ".join(PARAMS) + " | intervals |",
             "|---|---|" + "---|" * len(PARAMS) + "---|"]
    for name, e in rows.items():
        pp = e["per_parameter_90"]
        lines.append(f"| {name} | {e['overall_90']:.1%} | "
                     + " | ".join(f"{pp.get(p, float('nan')):.1%}" for p in PARAMS) + f" | {e['n_intervals']} |")
    (out / "coverage.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def bootstrap(args) -> None:
    out = Path(args.out)
    rows = []
    cfg = IdentifyConfig()
    truth = load_simulation_config("configs/poc_3story.yaml").building.build()
    jobs = [(truth, read_motion(r).scaled_to_pga(0.62), 0) for r in BOOT_RECORDS[: args.n_boot_cases]]
    for j, (truth, gm, seed) in enumerate(jobs):
        meas = simulate_measurement(truth, gm, noise_rms=0.10, seed=seed)
        res = identify(meas, cfg, cache_dir=args.cache)
        t = time.perf_counter()
        boot = parametric_bootstrap(res.clone, meas, args.n_boot, config=cfg, cache_dir=args.cache, seed=j)
        u = res.clone.uncertainty
        log = np.array([t == "log" for t in u.transform])
        theta = np.where(log, np.log(np.maximum(boot.values, 1e-300)), boot.values)
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
