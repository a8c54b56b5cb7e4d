"""Wall time of ``hlaid identify`` on the Table 1 case (10 % noise, El Centro at 0.62 g):
classifiers trained from scratch, then again with the cached machines, and a peer in the same
run: the same from-scratch run with scikit-learn's SVC in place of hlaid's KernelSVC.

    python scripts/bench_identify.py [--no-peer] [--repeat 3]
    python scripts/bench_identify.py --baseline ../main   # cached runs paired with another checkout's
    python scripts/bench_identify.py --stories 20      # a tall building (target: <= 3 min on 2 cores)
    python scripts/bench_identify.py --baseline ../main --cases table1,cached,steel4,update,hotel21,tall20

``--repeat R``: the from-scratch run and its scikit-learn peer alternate R times (best and median
of each; the ratio of the bests). ``--baseline PATH``: the cached identification of this checkout
and of the checkout at PATH (e.g. the code before a change) in two worker processes, each warmed
by one from-scratch run, then called in turn ``--rounds`` times (best and median of each).

``--cases`` (with ``--baseline``): the same two warmed workers run each named case in turn,
``--rounds`` times each (``--tall-rounds`` for ``tall20``), and the script prints the ratios
the identification's speed aims are stated in, with the load average before and after:

* ``table1``: Table 1 from scratch (a fresh classifier cache each time);
* ``cached``: Table 1 with the worker's cache (filled by its warm-up run);
* ``steel4``: ``hlaid identify s1 s2 s3 s4 --config configs/identify_steel_frame.yaml`` from an
  empty cache (the steel frame's runs fbgm152s1..s4, ``--data``);
* ``update``: ``hlaid update`` of the clone of s1..s3 (identified once per worker, not timed)
  with s4;
* ``mini``: the mini shake table's flexible model under Northridge, one nearly elastic record
  (each checkout's default identification, ``--data``), from an empty cache;
* ``hotel21``: the joint clone of the hotel's 21 events (``--data``; default identification);
* ``tall20``: the ``--stories 20`` building from scratch.

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
    import hlaid  # older checkouts (--baseline) name the function hlaid.identify.identify
    ident = getattr(hlaid, "identify_clone", None) or sys.modules["hlaid.identify"].identify
    t = time.perf_counter()
    res = ident(meas, cfg or IdentifyConfig(), cache_dir=cache)
    return time.perf_counter() - t, res


def table1_measurement():
    """The Table 1 building under El Centro at 0.62 g, 10 % noise, seed 0."""
    b = load_simulation_config(ROOT / "configs/poc_3story.yaml").building.build()
    gm = read("builtin:elcentro-1940-ns", "motion").scaled_to_pga(0.62)
    return simulate_measurement(b, gm, noise_rms=0.1, seed=0)


STEEL = "structural_response/shake_table_3story_steel_mrf_fixedbase/filtered_fbgm152s{}_denoised.tsv.gz"
HOTEL = "structural_response/phycnn_6story_hotel/data_exp.mat"
MINI = "structural_response/mini_shake_table_3story_model/flexible_3story_northridge.csv"
CASES = ("table1", "cached", "steel4", "update", "mini", "hotel21", "tall20")


class Cases:
    """The timed cases of ``--cases``, run in a worker process (this checkout's or the
    baseline's code, whichever ``PYTHONPATH`` names): each returns its wall time [s]."""

    def __init__(self, data: str):
        self.data = Path(data)
        self.meas = table1_measurement()
        self.cache = tempfile.mkdtemp(prefix="hlaid-bench-")
        self._steel: list | None = None
        self._clone3 = None

    def warm(self) -> None:
        run(self.meas, self.cache)  # compiles what is not cached, fills the worker's classifier cache

    def steel(self) -> list:
        if self._steel is None:
            from hlaid.io import read as read_any
            self._steel = [read_any(str(self.data / STEEL.format(k)), "measurement") for k in range(1, 5)]
        return self._steel

    def steel_config(self):
        from hlaid.config import load_config
        return load_config(ROOT / "configs/identify_steel_frame.yaml", IdentifyConfig)

    def table1(self) -> float:
        with tempfile.TemporaryDirectory() as d:
            return run(self.meas, d)[0]

    def cached(self) -> float:
        return run(self.meas, self.cache)[0]

    def steel4(self) -> float:
        with tempfile.TemporaryDirectory() as d:
            return run(self.steel(), d, self.steel_config())[0]

    def update(self) -> float:
        try:
            from hlaid.events import update_clone
        except ImportError:  # older checkouts (--baseline)
            from hlaid.identify.update import update_clone
        cfg = self.steel_config()
        if self._clone3 is None:
            self._clone3 = run(self.steel()[:3], self.cache, cfg)[1].clone
        t = time.perf_counter()
        update_clone(self._clone3, self.steel()[3], cfg)
        return time.perf_counter() - t

    def mini(self) -> float:
        from hlaid.io import read_mini_shake_table
        meas = read_mini_shake_table(self.data / MINI)
        with tempfile.TemporaryDirectory() as d:
            return run(meas, d)[0]  # each checkout's default identification

    def hotel21(self) -> float:
        import dataclasses
        meas = [dataclasses.replace(read(str(self.data / HOTEL), "measurement", event=k), name=str(k))
                for k in range(1, 22)]
        return run(meas, "")[0]

    def tall20(self) -> float:
        return run(tall_measurement(20)[1], "")[0]


def serve(data: str | None = None) -> int:
    """Worker of ``--baseline``: one from-scratch run into a fresh cache, then per line read from
    stdin the case it names (``go``: the cached run), its wall time printed."""
    _progress.set_verbosity(0)
    cases = Cases(data or DEFAULT_DATA)
    cases.warm()
    print("ready", flush=True)
    for line in sys.stdin:
        name = line.strip()
        print(f"{getattr(cases, 'cached' if name == 'go' else name)():.6f}", flush=True)
    return 0


DEFAULT_DATA = str(ROOT.parent / "shared" / "data")


def paired(baseline: str, rounds: dict, data: str | None = None) -> dict:
    """Wall times ``{case: [(worker name, times)]}`` of this checkout and of ``baseline``, each
    case run ``rounds[case]`` times alternating between two warmed workers (``"go"``: the cached
    Table 1 run)."""
    workers = {}
    for name, path in (("this checkout", ROOT), (f"baseline {baseline}", Path(baseline).resolve())):
        env = {**os.environ, "PYTHONPATH": str(path)}
        cmd = [sys.executable, str(Path(__file__).resolve()), "--serve"] + (["--data", data] if data else [])
        workers[name] = subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                         cwd=path)
    out: dict = {}
    try:
        for w in workers.values():  # their from-scratch warm-up runs (side by side, not timed)
            if w.stdout is None or w.stdout.readline().strip() != "ready":
                raise RuntimeError("a --baseline worker failed (see its error above)")
        for case, n in rounds.items():
            times: dict = {k: [] for k in workers}
            for _ in range(n):
                for k, w in workers.items():
                    assert w.stdin is not None and w.stdout is not None
                    w.stdin.write(f"{case}\n")
                    w.stdin.flush()
                    line = w.stdout.readline()
                    if not line:
                        raise RuntimeError(f"a --baseline worker failed on {case} (see its error above)")
                    times[k].append(float(line))
                    print(f"  {case}, {k}: {times[k][-1]:.2f} s (load {os.getloadavg()[0]:.1f})", file=sys.stderr,
                          flush=True)
            out[case] = [(k, np.array(v)) for k, v in times.items()]
    finally:
        for w in workers.values():
            if w.stdin is not None:
                w.stdin.close()
            w.wait()
    return out


def paired_cached(baseline: str, rounds: int) -> list[tuple[str, np.ndarray]]:
    """Cached wall times of this checkout and of ``baseline``, alternating in two warmed workers."""
    return paired(baseline, {"go": rounds})["go"]


def report_cases(baseline: str, cases: list[str], rounds: int, tall_rounds: int, data: str | None) -> int:
    """``--cases``: each case paired with the baseline, and the aims' ratios."""
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    res = paired(baseline, {c: (tall_rounds if c == "tall20" else rounds) for c in cases}, data)
    print("\n| case | this checkout best [s] | median [s] | baseline best [s] | median [s] | ratio (bests) "
          "| ratio (median of pairs) |")
    print("|---|---|---|---|---|---|---|")
    best = {}
    for case, ((_, a), (_, b)) in res.items():
        best[case] = (a.min(), b.min())
        print(f"| {case} | {a.min():.2f} | {np.median(a):.2f} | {b.min():.2f} | {np.median(b):.2f} | "
              f"{a.min() / b.min():.2f} | {np.median(a / b):.2f} |")
    print("\naims (this checkout):")
    aims = {"steel4": ("4-event steel clone from scratch / the baseline's", 1 / 3),
            "table1": ("Table 1 from scratch / the baseline's", 0.8),
            "mini": ("mini shake table's single record / the baseline's", 1.0),
            "tall20": ("20 stories from scratch / the baseline's", 1 / 2)}
    for case, (what, aim) in aims.items():
        if case in best:
            r = best[case][0] / best[case][1]
            print(f"- {what}: {r:.2f} (aim <= {aim:.2f}): {'met' if r <= aim else 'not met'}")
    if "cached" in best:
        c = best["cached"][0]
        print(f"- cached Table 1: {c:.2f} s (aim <= 2 s): {'met' if c <= 2 else 'not met'}")
    if "update" in best:
        u = best["update"][0]
        print(f"- update: {u:.2f} s (aim <= 5 s): {'met' if u <= 5 else 'not met'}" + (
            f"; / the 4-event identification's {best['steel4'][0]:.2f} s: {u / best['steel4'][0]:.2f} (aim <= 0.20): "
            f"{'met' if u <= 0.2 * best['steel4'][0] else 'not met'}" if "steel4" in best else ""))
    if "hotel21" in best:
        h = best["hotel21"][0]
        print(f"- hotel, joint clone of 21 events: {h:.1f} s (aim <= 60 s): {'met' if h <= 60 else 'not met'}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--stories", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=1, help="from-scratch runs (each paired with its peer)")
    ap.add_argument("--baseline", default=None, help="another checkout whose cached runs are paired with ours")
    ap.add_argument("--rounds", type=int, default=5, help="cached runs of each checkout with --baseline")
    ap.add_argument("--cases", default=None, help=f"with --baseline: comma-separated of {', '.join(CASES)}")
    ap.add_argument("--tall-rounds", type=int, default=1, help="rounds of tall20 with --cases")
    ap.add_argument("--data", default=None, help=f"the data folder of --cases (default {DEFAULT_DATA})")
    ap.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.serve:
        return serve(args.data)
    if args.cases:
        cases = args.cases.split(",")
        bad = [c for c in cases if c not in CASES]
        if bad or not args.baseline:
            ap.error(f"--cases needs --baseline and names from {', '.join(CASES)} (got {', '.join(bad) or 'none'})")
        return report_cases(args.baseline, cases, args.rounds, args.tall_rounds, args.data)
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


def tall_measurement(n: int):
    """The regular ``n``-story building of ``--stories`` and its measurement."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from study_identification import scale_to_yield  # a sibling script

    from hlaid.model import Building

    u = np.linspace(0.0, 1.0, n)
    b = Building(mass=np.full(n, 20.0), k0=4e4 - 2.5e4 * u, alpha=0.1 + 0.2 * u, p=1.5 + u, dy=5.0 + 3.0 * u,
                 delta_eta=0.5 + u, name=f"{n}-story")
    gm = scale_to_yield(b, read("builtin:elcentro-1940-ns", "motion").resampled(200.0))
    return b, simulate_measurement(b, gm, noise_rms=0.1, seed=0)


def tall(n: int) -> int:
    b, meas = tall_measurement(n)
    t, res = run(meas, "")
    e = {k: np.abs(getattr(res.clone.building, k) / getattr(b, k) - 1) for k in ("k0", "alpha", "p", "dy", "delta_eta")}
    paper = res.clone.paper
    ident = np.array([s.identifiable for s in paper.stories])
    allv = np.concatenate([e[k][ident] for k in ("alpha", "p", "dy", "delta_eta")])
    print(f"{n}-story identification from scratch: {t:.1f} s (target <= 180 s); {ident.sum()} of {n} stories "
          f"identifiable; alpha, p, dy, delta_eta median error {100 * np.median(allv):.1f} %")
    print({k: round(v, 1) for k, v in res.timings.items()})
    info = dict(paper.refine or {})
    restart = info.get("restart")
    ratio = info.get("noise_ratio")  # None without refinement
    print(f"refinement: cost {'n/a' if ratio is None else f'{ratio:.2f}'} x the noise's; restart: "
          f"{'none' if restart is None else ('kept' if restart['kept'] else 'not kept')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
