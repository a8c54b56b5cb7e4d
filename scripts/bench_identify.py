"""Wall time of ``hlaid identify`` on the Table 1 case (10 % noise, El Centro at 0.62 g):
classifiers trained from scratch, then again with the cached machines, and a peer in the same
run: the same from-scratch run with scikit-learn's SVC in place of hlaid's KernelSVC.

    python scripts/bench_identify.py [--no-peer]
    python scripts/bench_identify.py --stories 20      # a tall building (target: <= 3 min on 2 cores)

``--stories N``: a regular N-story shear building (20 t floors, k0 from 4e4 down to 1.5e4
N/mm, alpha 0.1-0.3, p 1.5-2.5, dy 5-8 mm, delta_eta 0.5-1.5) under El Centro scaled until
every story reaches 1.5 dy, 10 % noise; one from-scratch identification, its step timings.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time

import numpy as np

from hlaid import _progress
from hlaid.identify import IdentifyConfig, classify, identify_clone
from hlaid.io import read
from hlaid.synthetic import load_simulation_config, simulate_measurement


def run(meas, cache, cfg=None):
    t = time.perf_counter()
    res = identify_clone(meas, cfg or IdentifyConfig(), cache_dir=cache)
    return time.perf_counter() - t, res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--stories", type=int, default=None)
    args = ap.parse_args(argv)
    if args.stories:
        return tall(args.stories)
    _progress.set_verbosity(0)
    b = load_simulation_config("configs/poc_3story.yaml").building.build()
    gm = read("builtin:elcentro-1940-ns", "motion").scaled_to_pga(0.62)
    meas = simulate_measurement(b, gm, noise_rms=0.1, seed=0)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        t1, res = run(meas, d)
        t2, _ = run(meas, d)
    rows.append(("hlaid identify, classifiers from scratch (KernelSVC)", t1))
    rows.append(("hlaid identify, cached classifiers", t2))
    fits = sum(st["seconds"] for p in res.passes for s in p["stories"] for st in s.values())
    if not args.no_peer:
        from sklearn.svm import SVC
        orig = classify.make_svc
        classify.make_svc = lambda cfg, C=None, gamma=None: SVC(C=cfg.C if C is None else C, kernel=cfg.kernel,
                                                                gamma=cfg.gamma if gamma is None else gamma)
        try:  # no cache: scikit-learn's SVC cannot be stored in hlaid's classifier cache
            t3, _ = run(meas, "")
        finally:
            classify.make_svc = orig
        rows.append(("peer: same from scratch with sklearn.svm.SVC", t3))
    print("| run | wall time [s] | ratio to first row |")
    print("|---|---|---|")
    for name, t in rows:
        print(f"| {name} | {t:.1f} | {t / rows[0][1]:.2f} |")
    tm = res.timings
    sim = sum(v for k, v in tm.items() if k.startswith("simulate"))
    print(f"\nfrom scratch: training samples {sim:.1f} s, classifier fits {fits:.1f} s of CPU (on the worker "
          f"processes, overlapping the samples), "
          f"refinement {tm.get('refine', np.nan):.1f} s, HLA {tm['hla']:.2f} s; outer iterations {res.iterations}")
    print("targets: <= 10 s from scratch, <= 3 s cached (the paper: ~30 min of training on a Core i7)")
    return 0


def tall(n: int) -> int:
    from study_identification import scale_to_yield  # a sibling script (scripts/ is on sys.path)

    from hlaid.model import Building

    u = np.linspace(0.0, 1.0, n)
    b = Building(mass=np.full(n, 20.0), k0=4e4 - 2.5e4 * u, alpha=0.1 + 0.2 * u, p=1.5 + u, dy=5.0 + 3.0 * u,
                 delta_eta=0.5 + u, name=f"{n}-story")
    gm = scale_to_yield(b, read("builtin:elcentro-1940-ns", "motion").resampled(200.0))
    meas = simulate_measurement(b, gm, noise_rms=0.1, seed=0)
    t, res = run(meas, "")
    e = {k: np.abs(getattr(res.clone.building, k) / getattr(b, k) - 1) for k in ("k0", "alpha", "p", "dy", "delta_eta")}
    ident = np.array([s["identifiable"] for s in res.clone.diagnostics["stories"]])
    allv = np.concatenate([e[k][ident] for k in ("alpha", "p", "dy", "delta_eta")])
    print(f"{n}-story identification from scratch: {t:.1f} s (target <= 180 s); {ident.sum()} of {n} stories "
          f"identifiable; alpha, p, dy, delta_eta median error {100 * np.median(allv):.1f} %")
    print({k: round(v, 1) for k, v in res.timings.items()})
    info = res.clone.diagnostics["refine"] or {}
    restart = info.get("restart")
    ratio = info.get("noise_ratio")  # None without refinement
    print(f"refinement: cost {'n/a' if ratio is None else f'{ratio:.2f}'} x the noise's; restart: "
          f"{'none' if restart is None else ('kept' if restart['kept'] else 'not kept')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
