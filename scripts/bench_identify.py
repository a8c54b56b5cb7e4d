"""Wall time of ``hlaid identify`` on the Table 1 case (10 % noise, El Centro at 0.62 g):
classifiers trained from scratch, then again with the cached machines, and the same
from-scratch run with scikit-learn's SVC in place of hlaid's KernelSVC (peer, same run).

    python scripts/bench_identify.py [--no-peer]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time

import numpy as np

from hlaid import _progress
from hlaid.identify import IdentifyConfig, identify
from hlaid.identify import classify
from hlaid.motions import read_motion
from hlaid.synthetic import load_simulation_config, simulate_measurement


def run(meas, cache):
    t = time.perf_counter()
    res = identify(meas, IdentifyConfig(), cache_dir=cache)
    return time.perf_counter() - t, res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--no-peer", action="store_true")
    args = ap.parse_args(argv)
    _progress.set_verbosity(0)
    b = load_simulation_config("configs/poc_3story.yaml").building.build()
    meas = simulate_measurement(b, read_motion("builtin:elcentro-1940-ns").scaled_to_pga(0.62), noise_rms=0.1, seed=0)
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
        classify.make_svc = lambda cfg: SVC(C=cfg.C, kernel=cfg.kernel, gamma=cfg.gamma)
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
    print(f"\nfrom scratch: simulation of training half cycles {sim:.1f} s, classifier fits {fits:.1f} s, "
          f"refinement {tm.get('refine', np.nan):.1f} s, HLA {tm['hla']:.2f} s; outer iterations {res.iterations}")
    print("targets: <= 60 s from scratch, <= 10 s cached (the paper: ~30 min of training on a Core i7)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
