"""Coverage of the identification uncertainty intervals, on simulated measurements.

    S=scripts/study_uncertainty.py; O="--out runs/study_uncert --cache runs/uq_cache"
    python $S --part run --set heldout --n 60 $O
    python $S --part analyse --out runs/study_uncert
    python $S --part bootstrap --n-boot-cases 3 --n-boot 12 $O

``run``: random 2-6 story buildings (as ``scripts/study_identification.py``'s random part)
under six far-field records scaled until every story reaches 1.5 dy, 10 % noise, a noise
seed per case; each case identified and its refinement's Jacobian and residuals stored in
``<out>/<set>/case_NNN.npz`` (resumable: existing cases are skipped). ``--set calibration``
draws other buildings (another seed); it was not run for docs/uncertainty.md (time).
``analyse``: per covariance method (naive, neff, sandwich) the fraction of true parameters
inside the nominal 90 % intervals, per parameter and overall, over the ``heldout`` cases;
the sandwich widened by calibration factors scored leave-one-case-out (each case with the
factor fitted on the other cases of its fit class); a calibration plot (observed against
nominal coverage) in ``<out>/coverage.png`` and the figures in ``<out>/coverage.json``/``.md``.
``bootstrap``: on the Table 1 structure under one to three records (PGA 0.62 g), the Laplace
standard deviations against a parametric bootstrap (re-identification on re-noised
simulations of the clone).
``system``: the posterior of a single-event clone identified with a structural system's prior
(the MAP fit over the event from the paper's estimate): the Table 1 structure under its five
records at PGA 0.62 g (system ``--table1-system``, default ``steel-moment-frame``) and ``--n``
random buildings of ``--set`` (system ``--system``, default ``generic``), 10 % noise; the share of
true parameters inside each clone's 90 % interval (every parameter: k0, alpha, p, dy, delta_eta
and the damping ratio), into ``<out>/system/coverage.json`` (resumable per case).

    python $S --part system --n 20 --out runs/study_uncert --cache runs/uq_cache
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import norm
from study_identification import RANDOM_RECORDS, random_building, scale_to_yield

from hlaid import _progress, identify_clone
from hlaid.identify import IdentifyConfig
from hlaid.identify.auto import BROAD_BAND_HZ
from hlaid.io import read
from hlaid.studies.bootstrap import parametric_bootstrap
from hlaid.synthetic import load_simulation_config, simulate_measurement
from hlaid.uncertainty import calibration_factor, zscores
from hlaid.uncertainty.laplace import METHODS, MISFIT_LIMIT, from_refinement, noise_residual_rms

SET_SEEDS = {"heldout": 1515, "calibration": 2727}
PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")
BOOT_RECORDS = ["builtin:elcentro-1940-ns", "builtin:kocaeli-1999-dzc180", "builtin:northridge-1994-mul009"]
LEVELS = np.array([0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99])


def cases(which: str, n: int):
    rng = np.random.default_rng(SET_SEEDS[which])
    out = []
    while len(out) < n:
        b = random_building(rng)
        gm = scale_to_yield(b, read(RANDOM_RECORDS[len(out) % len(RANDOM_RECORDS)], "motion"))
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
            res = identify_clone(meas, cfg, cache_dir=args.cache)
        except ValueError as err:
            print(f"[{j + 1}/{args.n}] {gm.name}: FAILED {err}", flush=True)
            np.savez(path, failed=str(err))
            continue
        rr = res.refinement
        slots = np.array([f"{n}:{i}" for n, i in rr.slots])
        true_x = np.array([getattr(truth, n)[i] if n != "damping" else truth.damping.ratio for n, i in rr.slots])
        np.savez_compressed(path, slots=slots, x=rr.x, true_x=true_x, jacobian=rr.jacobian.astype(np.float32),
                            residuals=rr.residuals, n_floors=rr.channels or meas.n_floors, criterion=rr.criterion,
                            record=gm.name, seed=seed,
                            seconds=time.perf_counter() - t, clone=json.dumps(res.clone.to_dict()))
        err = np.abs(rr.x / true_x - 1)
        print(f"[{j + 1}/{args.n}] {gm.name} {truth.n_stories} stories: {len(slots)} parameters, mean error "
              f"{err.mean():.3f} worst {err.max():.3f}, {time.perf_counter() - t:.0f} s", flush=True)


class _RR:
    """The parts of a RefineResult the covariance needs, read back from a case file."""

    def __init__(self, z):
        self.slots = tuple((s.split(":")[0], int(s.split(":")[1])) for s in z["slots"])
        self.x, self.jacobian, self.residuals = z["x"], z["jacobian"].astype(float), z["residuals"]
        self.criterion = str(z["criterion"]) if "criterion" in z else None  # absent in older case files


def load(folder: Path) -> list:
    """(refinement, true values, floors, misfit ratio) of every identified case in ``folder``."""
    s0 = noise_residual_rms(0.10, BROAD_BAND_HZ, 1 / 200.0)  # refine.band_hz chosen on simulated data
    out = []
    for p in sorted(folder.glob("case_*.npz")):
        z = np.load(p, allow_pickle=False)
        if "failed" in z:
            continue
        rr = _RR(z)
        out.append((rr, z["true_x"], int(z["n_floors"]), float(np.sqrt(np.mean(rr.residuals**2)) / s0)))
    return out


def fit_class(rr, channels: int, rho: float) -> str:
    """``"whitened"`` (the errors-in-variables fit: ``criterion`` ``"tangent"``, or in case files
    written before it was stored, a residual column more than stories), ``"consistent"`` (least
    squares at the noise level) or ``"inconsistent"`` (misfit ratio above :data:`MISFIT_LIMIT`),
    the classes the package calibrates separately."""
    if rho > MISFIT_LIMIT:
        return "inconsistent"
    if getattr(rr, "criterion", None) is not None:
        return "whitened" if rr.criterion == "tangent" else "consistent"
    return "whitened" if channels > sum(n == "k0" for n, _ in rr.slots) else "consistent"


def case_zscores(data, method: str) -> list:
    """Per case: (z-scores of its slots, their parameter names, fit consistent with the noise,
    :func:`fit_class`)."""
    out = []
    for rr, true_x, nf, rho in data:
        u = from_refinement(rr, nf, method=method)
        out.append((zscores(u, true_x), np.array([n for n, _ in u.slots]), rho <= MISFIT_LIMIT,
                    fit_class(rr, nf, rho)))
    return out


def _cat(cases, only_ok=False):
    sel = [c for c in cases if c[2] or not only_ok]
    return np.concatenate([c[0] for c in sel]), np.concatenate([c[1] for c in sel])


def _entry(z, names, scale):
    scale = np.broadcast_to(np.asarray(scale, dtype=float), z.shape)
    cov = lambda m, lv: float(np.mean(np.abs(z[m]) <= scale[m] * norm.ppf(0.5 + 0.5 * lv)))  # noqa: E731
    allm = np.ones(z.size, dtype=bool)
    return {"overall_90": cov(allm, 0.9), "n_intervals": int(z.size),
            "per_parameter_90": {p: cov(names == p, 0.9) for p in PARAMS if (names == p).any()},
            "levels": {f"{lv:g}": cov(allm, lv) for lv in LEVELS}}


def loco(cases, only_ok: bool, by_class: bool = True):
    """Leave-one-case-out calibration: each case's intervals widened by the factor fitted on the
    *other* cases of its class (:func:`fit_class`; ``by_class`` False: the other consistent fits
    for every case), so no case is scored with a factor fitted on itself.
    Returns (z, names, per-slot factors) of the cases scored (consistent fits only if ``only_ok``)."""
    zs, ns, fs = [], [], []
    for k, (z, n, ok, kind) in enumerate(cases):
        if only_ok and not ok:
            continue
        same = [c[0] for j, c in enumerate(cases) if j != k and (c[3] == kind if by_class else c[2])]
        others = np.concatenate(same or [c[0] for j, c in enumerate(cases) if j != k and c[2]])  # a class of one
        zs.append(z)
        ns.append(n)
        fs.append(np.full(z.size, calibration_factor(others, 0.9)))
    return np.concatenate(zs), np.concatenate(ns), np.concatenate(fs)


def analyse(args) -> None:
    out = Path(args.out)
    held = load(out / "heldout")
    n_ok = int(sum(r[3] <= MISFIT_LIMIT for r in held))
    report = {"cases": len(held), "misfit_limit": MISFIT_LIMIT, "fit_consistent": n_ok,
              "misfit_ratio": [r[3] for r in held], "rows": {}}
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.8, 5.0))
    ax.axhspan(0.85, 0.95, color="0.9", zorder=0)
    ax.plot([0.45, 1], [0.45, 1], "k:", lw=1, label="ideal")
    rows = report["rows"]
    for method in METHODS:
        cases = case_zscores(held, method)
        z, n = _cat(cases)
        rows[f"{method}, all cases"] = _entry(z, n, 1.0)
        zo, no = _cat(cases, True)
        rows[f"{method}, consistent fits"] = _entry(zo, no, 1.0)
        ax.plot(LEVELS, list(rows[f"{method}, all cases"]["levels"].values()), "o-", ms=4, label=f"{method}, all cases")
        if method != "sandwich":
            continue
        report["factor_all_consistent"] = calibration_factor(zo, 0.9)
        for kind in ("whitened", "consistent", "inconsistent"):
            zk = np.concatenate([c[0] for c in cases if c[3] == kind] or [np.zeros(0)])
            report[f"factor_{kind}"] = calibration_factor(zk, 0.9) if zk.size else None
            report[f"cases_{kind}"] = sum(c[3] == kind for c in cases)
        report["factor_all_inconsistent"] = report["factor_inconsistent"]
        for only_ok, by_class, label, style in (
                (True, True, "consistent fits", "^-"),
                (False, False, "all cases, consistent-fit factor for every case", "s--"),
                (False, True, "all cases, factor per class (whitened / least squares / inconsistent)", "D-")):
            zl, nl, fl = loco(cases, only_ok, by_class)
            key = f"sandwich x factor (leave-one-case-out), {label}"
            rows[key] = _entry(zl, nl, fl)
            report[f"loco_factor_range: {label}"] = [float(fl.min()), float(fl.max())]
            ax.plot(LEVELS, list(rows[key]["levels"].values()), style, ms=5, lw=2 if style != "s--" else 1,
                    label=f"sandwich x factor (LOCO), {label}")
    ax.set_xlabel("nominal coverage of the interval")
    ax.set_ylabel("fraction of true values inside")
    ax.set_title(f"{len(held)} random buildings ({n_ok} fits consistent with the noise), 10 % noise", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "coverage.png", dpi=120)
    (out / "coverage.json").write_text(json.dumps(report, indent=1))
    lines = [f"Cases: {len(held)} ({n_ok} with a fit consistent with the noise, misfit ratio <= {MISFIT_LIMIT:g}); "
             f"factors fitted on all cases: consistent fits {report['factor_all_consistent']:.2f}, the others "
             f"{report['factor_all_inconsistent'] or float('nan'):.2f}; per class "
             + ", ".join(f"{k} {report[f'factor_{k}'] or float('nan'):.2f} ({report[f'cases_{k}']} cases)"
                         for k in ("whitened", "consistent", "inconsistent")), "",
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
    jobs = [(truth, read(r, "motion").scaled_to_pga(0.62), 0) for r in BOOT_RECORDS[: args.n_boot_cases]]
    for j, (truth, gm, seed) in enumerate(jobs):
        meas = simulate_measurement(truth, gm, noise_rms=0.10, seed=seed)
        res = identify_clone(meas, cfg, cache_dir=args.cache)
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


def system_case(truth, gm, seed: int, system: str, cache: str) -> dict:
    """One clone identified with ``system``'s prior: per parameter its z-score against the truth
    and whether the truth lies inside the 90 % interval."""
    from hlaid.model.uncertainty import to_theta

    meas = simulate_measurement(truth, gm, noise_rms=0.10, seed=seed)
    t = time.perf_counter()
    res = identify_clone(meas, IdentifyConfig(system=system), cache_dir=cache)
    u = res.clone.uncertainty
    true_x = np.array([truth.damping.ratio if n == "damping" else getattr(truth, n)[i] for n, i in u.slots])
    theta = np.array([float(to_theta(tr, v)) for tr, v in zip(u.transform, true_x)])
    z = (theta - u.centre) / np.maximum(u.std, 1e-300)
    iv = u.interval(0.9)
    inside = [bool(lo <= v <= hi) for (lo, hi), v in zip(iv.values(), true_x)]
    return {"record": gm.name, "stories": truth.n_stories, "system": system, "names": u.names,
            "z": z.tolist(), "inside": inside, "method": u.method, "seconds": time.perf_counter() - t}


def system_study(args) -> None:
    out = Path(args.out) / "system"
    out.mkdir(parents=True, exist_ok=True)
    truth = load_simulation_config("configs/poc_3story.yaml").building.build()
    from study_identification import TABLE1_RECORDS

    jobs = [(f"table1_{k}", truth, read(r, "motion").scaled_to_pga(0.62), k, args.table1_system)
            for k, r in enumerate(TABLE1_RECORDS)]
    jobs += [(f"{args.set}_{j:03d}", b, gm, seed, args.system)
             for j, (b, gm, seed) in enumerate(cases(args.set, args.n))]
    rows = []
    for name, b, gm, seed, system in jobs:
        path = out / f"{name}.json"
        if not path.exists():
            path.write_text(json.dumps(system_case(b, gm, seed, system, args.cache)))
        rows.append({"case": name, **json.loads(path.read_text())})
        r = rows[-1]
        print(f"{name} ({r['system']}, {r['stories']} stories, {r['record']}): {sum(r['inside'])}/{len(r['inside'])} "
              f"inside, {r['seconds']:.0f} s", flush=True)
    report = {}
    for label, sel in (("table1", [r for r in rows if r["case"].startswith("table1")]),
                       ("random", [r for r in rows if not r["case"].startswith("table1")]), ("all", rows)):
        inside = np.concatenate([r["inside"] for r in sel]) if sel else np.zeros(0)
        names = np.concatenate([[n.split("[")[0] for n in r["names"]] for r in sel]) if sel else np.zeros(0)
        report[label] = {"cases": len(sel), "intervals": int(inside.size),
                         "coverage_90": float(inside.mean()) if inside.size else None,
                         "per_parameter": {p: float(inside[names == p].mean()) for p in (*PARAMS, "damping")
                                           if (names == p).any()}}
        print(f"{label}: {report[label]['coverage_90']:.1%} of {inside.size} true values inside the 90 % intervals "
              f"({len(sel)} cases); " + ", ".join(f"{p} {v:.0%}" for p, v in report[label]["per_parameter"].items()))
    (out / "coverage.json").write_text(json.dumps(report, indent=1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", choices=["run", "analyse", "bootstrap", "system"], default="run")
    ap.add_argument("--system", default="generic", help="structural system of the random cases (--part system)")
    ap.add_argument("--table1-system", default="steel-moment-frame", help="of the Table 1 cases (--part system)")
    ap.add_argument("--set", choices=list(SET_SEEDS), default="heldout")
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--out", default="runs/study_uncert")
    ap.add_argument("--cache", default="", help="classifier cache folder ('' = none)")
    ap.add_argument("--n-boot", type=int, default=20)
    ap.add_argument("--n-boot-cases", type=int, default=3)
    args = ap.parse_args(argv)
    _progress.set_verbosity(0)
    {"run": run, "analyse": analyse, "bootstrap": bootstrap, "system": system_study}[args.part](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
