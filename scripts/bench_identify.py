"""Wall time of ``hlaid identify`` on the Table 1 case (10 % noise, El Centro at 0.62 g):
classifiers trained from scratch, then again with the cached machines, and a peer in the same
run: the same from-scratch run with scikit-learn's SVC in place of hlaid's KernelSVC.

    python scripts/bench_identify.py [--no-peer] [--repeat 3]
    python scripts/bench_identify.py --baseline ../main   # cached runs paired with another checkout's
    python scripts/bench_identify.py --stories 20      # a tall building (target: <= 3 min on 2 cores)

``--repeat R``: the from-scratch run and its scikit-learn peer alternate R times (best and median
of each; the ratio of the bests). ``--baseline PATH``: the cached identification of this checkout
and of the checkout at PATH (e.g. the code before a change) in two worker processes, each warmed
by one from-scratch run, then called in turn ``--rounds`` times (best and median of each).

``--stories N``: a regular N-story shear building (20 t floors, k0 from 4e4 down to 1.5e4
N/mm, alpha 0.1-0.3, p 1.5-2.5, dy 5-8 mm, delta_eta 0.5-1.5) under El Centro scaled until
every story reaches 1.5 dy, 10 % noise; one from-scratch identification, its step timings.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hlaid import _progress
from hlaid.identify import IdentifyConfig, classify
from hlaid.io import read
from hlaid.synthetic import load_simulation_config, simulate_measurement

ROOT = Path(__file__).resolve().parents[1]


def run(meas, cache, cfg=None):
    hid = sys.modules["hlaid.identify"]  # the module (older checkouts, --baseline, name the function identify)
    ident = getattr(hid, "identify_clone", None) or hid.identify
    t = time.perf_counter()
    res = ident(meas, cfg or IdentifyConfig(), cache_dir=cache)
    return time.perf_counter() - t, res


def table1_measurement():
    """The Table 1 building under El Centro at 0.62 g, 10 % noise, seed 0."""
    b = load_simulation_config(ROOT / "configs/poc_3story.yaml").building.build()
    gm = read("builtin:elcentro-1940-ns", "motion").scaled_to_pga(0.62)
    return simulate_measurement(b, gm, noise_rms=0.1, seed=0)


def serve() -> int:
    """Worker of ``--baseline``: one from-scratch run into a fresh cache, then one cached run
    per line read from stdin, its wall time printed."""
    _progress.set_verbosity(0)
    meas = table1_measurement()
    with tempfile.TemporaryDirectory() as d:
        run(meas, d)
        print("ready", flush=True)
        for _ in sys.stdin:
            print(f"{run(meas, d)[0]:.6f}", flush=True)
    return 0


def paired_cached(baseline: str, rounds: int) -> list[tuple[str, np.ndarray]]:
    """Cached wall times of this checkout and of ``baseline``, alternating in two warmed workers."""
    workers = {}
    for name, path in (("this checkout", ROOT), (f"baseline {baseline}", Path(baseline).resolve())):
        env = {**os.environ, "PYTHONPATH": str(path)}
        workers[name] = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--serve"], env=env,
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=path)
    times: dict = {k: [] for k in workers}
    try:
        for w in workers.values():  # their from-scratch warm-up runs (side by side, not timed)
            if w.stdout is None or w.stdout.readline().strip() != "ready":
                raise RuntimeError("a --baseline worker failed (see its error above)")
        for _ in range(rounds):
            for k, w in workers.items():
                assert w.stdin is not None and w.stdout is not None
                w.stdin.write("go\n")
                w.stdin.flush()
                times[k].append(float(w.stdout.readline()))
    finally:
        for w in workers.values():
            if w.stdin is not None:
                w.stdin.close()
            w.wait()
    return [(k, np.array(v)) for k, v in times.items()]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--stories", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=1, help="from-scratch runs (each paired with its peer)")
    ap.add_argument("--baseline", default=None, help="another checkout whose cached runs are paired with ours")
    ap.add_argument("--rounds", type=int, default=5, help="cached runs of each checkout with --baseline")
    ap.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.serve:
        return serve()
    if args.stories:
        return tall(args.stories)
    _progress.set_verbosity(0)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    meas = table1_measurement()
    scratch, peer, cached = [], [], []
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory() as d:
            t1, res = run(meas, d)
            cached.append(run(meas, d)[0])
        scratch.append(t1)
        if not args.no_peer:
            peer.append(peer_run(meas))
    rows = [("hlaid identify, classifiers from scratch (KernelSVC)", np.array(scratch)),
            ("hlaid identify, cached classifiers", np.array(cached))]
    if peer:
        rows.append(("peer: same from scratch with sklearn.svm.SVC", np.array(peer)))
    fits = sum(st["seconds"] for p in res.passes for s in p["stories"] for st in s.values())
    print("| run | best wall time [s] | median [s] | best, ratio to first row |")
    print("|---|---|---|---|")
    for name, t in rows:
        print(f"| {name} | {t.min():.2f} | {np.median(t):.2f} | {t.min() / rows[0][1].min():.2f} |")
    if peer:
        print(f"from scratch / peer: {rows[0][1].min() / rows[2][1].min():.2f} (bests), "
              f"{np.median(rows[0][1] / rows[2][1]):.2f} (median of the paired runs)")
    if args.baseline:
        pc = paired_cached(args.baseline, args.rounds)
        print("\n| cached identification | best [s] | median [s] | best, ratio to first row |")
        print("|---|---|---|---|")
        for name, t in pc:
            print(f"| {name} | {t.min():.2f} | {np.median(t):.2f} | {t.min() / pc[0][1].min():.2f} |")
        print(f"this checkout / baseline, cached: {pc[0][1].min() / pc[1][1].min():.2f} (bests), "
              f"{np.median(pc[0][1] / pc[1][1]):.2f} (median of the paired runs)")
    tm = res.timings
    sim = sum(v for k, v in tm.items() if k.startswith("simulate"))
    print(f"\nfrom scratch: training samples {sim:.1f} s, classifier fits {fits:.1f} s of CPU (on the worker "
          f"processes, overlapping the samples), "
          f"refinement {tm.get('refine', np.nan):.1f} s, HLA {tm['hla']:.2f} s; outer iterations {res.iterations}")
    print("targets: <= 10 s from scratch, <= 3 s cached (the paper: ~30 min of training on a Core i7)")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


def peer_run(meas) -> float:
    """Wall time of the from-scratch identification with scikit-learn's SVC in place of KernelSVC."""
    from sklearn.svm import SVC
    orig = classify.make_svc
    classify.make_svc = lambda cfg, C=None, gamma=None: SVC(C=cfg.C if C is None else C, kernel=cfg.kernel,
                                                            gamma=cfg.gamma if gamma is None else gamma)
    try:  # no cache: scikit-learn's SVC cannot be stored in hlaid's classifier cache
        return run(meas, "")[0]
    finally:
        classify.make_svc = orig


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
