"""Fleet benchmark: ``hlaid fleet`` on N simulated buildings x R far-field records x ensemble E.

Buildings: N random 3-story shear buildings (Table 1 of the paper scaled: k0 x U(0.6, 1.6),
alpha, p, dy, delta_eta drawn around Table 1, 3 m stories), each "recorded" under one event
(a built-in record at a PGA of U(0.3, 0.6) g, 20 s around its peak, 200 Hz, 10 % RMS noise),
written as NPZ measurements with a fleet config into WORK/. The fleet then runs on the local
cluster (``--workers``, one thread each) or ``--scheduler``: identification (``--identify``
settings), then ``hlaid.ida.assess`` (ensemble IDA over the first R FEMA P695 far-field
components) -- or, where that module is missing, the point-clone fallback (ensemble 0).

Printed: wall time, per-unit cost (identify / assess / total; mean, median, worst), building-events
per CPU-minute and the city-scale projection (``--city 1000,64``: 1000 buildings, one event each, on
64 single-threaded workers, from the measured per-unit CPU times), the
cluster overhead (wall minus the busiest worker's task time), and a projection of the wall time
on W workers from the measured task times (greedy longest-first list scheduling of the measured
per-unit times + the measured overhead; the task times are those measured here, where the
workers shared the machine's cores with each other and with anything else running).

Usage::

    python scripts/bench_fleet.py --buildings 4 --records 44 --ensemble 4 --workers 2
    python scripts/bench_fleet.py --buildings 50 --records 44 --ensemble 20 --workers 2   # the issue's size
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

DEFAULT_RECORDS = REPO.parent / "shared" / "data" / "ground_motions" / "fema_p695_farfield"
TABLE1 = dict(weight=(171.85, 171.85, 90.0), k0=(1.94e4, 1.65e4, 1.37e4), alpha=(0.23, 0.17, 0.12),
              p=(2.5, 1.5, 1.9), dy=(7.0, 6.0, 3.0), delta_eta=(0.7, 0.66, 1.54))
EVENTS = ("elcentro-1940-ns", "kocaeli-1999-dzc180", "northridge-1994-mul009", "kobe-1995-nis000")
IDENTIFY = {  # identification settings: the demo's (configs/demo.yaml) or the fast test ones
    "demo": {"training": {"samples": 800}, "outer": {"max_iterations": 2, "tol": 0.02}},
    "fast": {"training": {"samples": 60, "n_segments": 8}, "outer": {"max_iterations": 1}},
}


def make_fleet(work: Path, n: int, records: list[str], ensemble: int, identify: str, workers: int, threads: int,
               n_levels: int, seed: int) -> Path:
    """Simulated measurements and the fleet config in ``work``; returns the config's path."""
    import yaml

    from hlaid.model import Building
    from hlaid.motions import GroundMotion, load_builtin
    from hlaid.synthetic import simulate_measurement
    from hlaid.units import weight_kn_to_mass_t
    rng = np.random.default_rng(seed)
    buildings = []
    for i in range(n):
        name = f"B{i + 1:03d}"
        ev = EVENTS[i % len(EVENTS)]
        gm = load_builtin(ev).scaled_to_pga(rng.uniform(0.3, 0.6)).resampled(200.0)
        k = int(np.argmax(np.abs(gm.acc)))
        i0 = max(0, k - 1000)
        gm = GroundMotion(dt=gm.dt, acc=gm.acc[i0:i0 + 4000], name=ev, source=gm.source)
        t = TABLE1
        b = Building(mass=np.array([weight_kn_to_mass_t(w) for w in t["weight"]]),
                     k0=np.array(t["k0"]) * rng.uniform(0.6, 1.6),
                     alpha=np.array(t["alpha"]) * rng.uniform(0.8, 1.2, 3),
                     p=np.clip(np.array(t["p"]) * rng.uniform(0.85, 1.15, 3), 1.0, 3.0),
                     dy=np.array(t["dy"]) * rng.uniform(0.8, 1.25, 3),
                     delta_eta=np.array(t["delta_eta"]) * rng.uniform(0.8, 1.25, 3), height=np.full(3, 3000.0),
                     pdelta=False, name=name)
        path = work / f"{name}.npz"
        if not path.exists():
            simulate_measurement(b, gm, noise_rms=0.10, seed=i).save(path)
        buildings.append({"name": name, "mass_t": [float(v) for v in b.mass], "height_mm": [3000.0] * 3,
                          "measurements": {"quake": {"file": path.name}}})
    cfg = {"name": f"bench fleet {n} x {len(records)} x {ensemble}", "records": records, "n_ensemble": ensemble,
           "seed": seed, "identify": IDENTIFY[identify], "ida": {"n_levels": n_levels},
           "cluster": {"n_workers": workers, "threads_per_worker": threads}, "buildings": buildings}
    p = work / "fleet.yaml"
    p.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return p


def makespan(times: list[float], workers: int) -> float:
    """Greedy longest-first list scheduling of task times on ``workers`` identical workers."""
    load = [0.0] * workers
    for t in sorted(times, reverse=True):
        j = load.index(min(load))
        load[j] += t
    return max(load)


def stats(v: list[float]) -> str:
    return f"mean {statistics.mean(v):.1f} s, median {statistics.median(v):.1f} s, worst {max(v):.1f} s"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--buildings", type=int, default=4)
    ap.add_argument("--records", type=int, default=44, help="the first R components of the far-field set")
    ap.add_argument("--ensemble", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--scheduler", help="an existing dask scheduler instead of the local cluster")
    ap.add_argument("--identify", choices=sorted(IDENTIFY), default="demo")
    ap.add_argument("--n-levels", type=int, default=10, help="IDA grid levels (hunt and fill refine)")
    ap.add_argument("--record-dir", type=Path, default=DEFAULT_RECORDS)
    ap.add_argument("--work", type=Path, default=Path("bench-fleet"), help="measurements, config and output")
    ap.add_argument("--project", default="1,2,4,8,16,32,64", help="worker counts of the projection")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--city", default="1000,64", help="BUILDINGS,CORES of the city-scale projection (one event each)")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON")
    ap.add_argument("--resume", action="store_true",
                    help="continue an interrupted run (per-unit figures from every unit; wall time of this run only)")
    a = ap.parse_args()

    from hlaid import _progress
    from hlaid.fleet import load_fleet_config, run_fleet
    files = sorted(str(p) for p in a.record_dir.glob("*.AT2"))[:a.records]
    if len(files) < a.records:
        print(f"only {len(files)} records in {a.record_dir}", file=sys.stderr)
        return 2
    a.work.mkdir(exist_ok=True)
    cfg_path = make_fleet(a.work, a.buildings, files, a.ensemble, a.identify, a.workers, a.threads, a.n_levels, a.seed)
    out = a.work / f"out-{a.buildings}x{a.records}x{a.ensemble}-w{a.workers}"
    if out.exists() and not a.resume:
        print(f"{out} exists: remove it to measure afresh (or --resume to finish it)", file=sys.stderr)
        return 2
    cfg = load_fleet_config(cfg_path)
    _progress.set_verbosity(1)
    t0 = time.perf_counter()
    s = run_fleet(cfg, out, base_dir=a.work, scheduler=a.scheduler, cache_dir=str(a.work / "svm-cache"))
    wall = time.perf_counter() - t0
    results = [json.loads((out / "buildings" / f"{r['building']}@{r['event']}.json").read_text()) for r in s.rows]
    ok = [r for r in results if r["status"] == "ok"]
    if not ok:
        print("every unit failed: " + "; ".join(r.get("reason", "") for r in results), file=sys.stderr)
        return 1
    tot = [r["timings"]["total_s"] for r in ok]
    ide = [r["timings"]["identify_s"] for r in ok]
    ass = [r["timings"]["assess_s"] for r in ok]
    cpu = {k: [r["timings"][f"{k}_cpu_s"] for r in ok] for k in ("identify", "assess", "total")}
    workers = {r["worker"] for r in ok}
    busiest = max(sum(r["timings"]["total_s"] for r in ok if r["worker"] == w) for w in workers)
    overhead = max(0.0, wall - busiest)
    engine = ok[0]["assessment"].get("engine")
    print(f"\n## fleet benchmark: {a.buildings} buildings x {a.records} records x ensemble {a.ensemble} "
          f"({engine}), {a.workers} worker(s) x {a.threads} thread(s), identify: {a.identify}, "
          f"{os.cpu_count()} CPU(s), load average at the end {os.getloadavg()[0]:.1f}\n")
    print(f"- wall time {wall:.1f} s for {len(results)} unit(s) ({len(results) - len(ok)} failed); "
          f"overhead (start, scatter, table, report) {overhead:.1f} s")
    print(f"- per unit, wall on one worker: identify {stats(ide)}; assess {stats(ass)}; total {stats(tot)}")
    print(f"- per unit, CPU of the worker thread: identify {stats(cpu['identify'])}; assess {stats(cpu['assess'])}; "
          f"total {stats(cpu['total'])} (wall / CPU {sum(tot) / sum(cpu['total']):.2f}: the share of a core a "
          "worker got)")
    if a.ensemble:
        print(f"- assess CPU per ensemble member x record: "
              f"{statistics.mean(cpu['assess']) / (a.ensemble * a.records):.3f} s")
    print("\nProjection (longest-first list scheduling of the measured per-unit times on W dedicated workers, "
          "plus the measured overhead):\n\n| workers W | from wall times [s] | from CPU times [s] |\n|---|---|---|")
    proj = {}
    for w in (int(v) for v in a.project.split(",")):
        proj[w] = (makespan(tot, w) + overhead, makespan(cpu["total"], w) + overhead)
        print(f"| {w} | {proj[w][0]:.0f} | {proj[w][1]:.0f} |")
    rate = len(ok) / (sum(cpu["total"]) / 60.0)
    n_city, cores = (int(v) for v in a.city.split(","))
    city = makespan([cpu["total"][i % len(ok)] for i in range(n_city)], cores) + overhead
    print(f"\nCity scale: {rate:.2f} building-events per CPU-minute (this fleet's settings); {n_city} buildings, one "
          f"event each, on a {cores}-core cluster (one single-threaded worker per core, the measured CPU times "
          f"repeated): {city / 60:.0f} min ({n_city / rate / 60:.1f} core-hours)")
    if a.ensemble:
        scale = (44 / a.records) * (20 / a.ensemble)
        per = statistics.mean(cpu["identify"]) + statistics.mean(cpu["assess"]) * scale
        print(f"\nScaled to the issue's size (50 buildings x 44 records x ensemble 20; assess CPU scaled linearly "
              f"in records x members): {per:.0f} s CPU per building, {50 * per / 3600:.2f} core-hours; on W "
              "dedicated workers: " + ", ".join(f"W={w}: {50 * per / w / 60:.0f} min" for w in (2, 8, 16, 64)))
    if a.json:
        a.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(a).items()}, "wall_s": wall,
                                      "overhead_s": overhead, "identify_s": ide, "assess_s": ass, "total_s": tot,
                                      "cpu_s": cpu, "engine": engine, "projection_s": proj,
                                      "building_events_per_cpu_minute": rate, "city": [n_city, cores, city],
                                      "load_average": os.getloadavg()}, indent=2))
    return 0


if __name__ == "__main__":  # the local cluster's worker processes re-import this file: guard the run
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        print("bench_fleet: interrupted", file=sys.stderr)
        sys.exit(130)
