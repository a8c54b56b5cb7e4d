"""Benchmark of the batch simulator against OpenSeesPy, in one run (prints a markdown table).

Case: the Table 1 structure (docs/DESIGN.md section 4, 5 % Rayleigh, no P-Delta), far-field records
resampled to 200 Hz and cut to 30 s (6001 samples), RK4 with 4 sub-steps.

1. one record: wall time of ``simulate`` (full histories, and peaks only);
2. 200 runs = 20 FEMA P695 far-field records x 10 scale factors (PGA 0.1 ... 1.0 g) in one
   batched call (``outputs="peaks"``, numba threads = the machine's cores);
3. the same 200 runs in OpenSeesPy (the exported clone script: zeroLength + BoucWen, Newmark,
   Newton; one ``analyze`` call per run with an envelope recorder), at dt and dt/10, on as
   many worker processes as hlaid has threads.

Accuracy of peak drifts against a converged reference: hlaid with 4 sub-steps on the record
linearly interpolated to 2000 Hz (the same input function; peaks taken over 10x denser samples,
i.e. the true peak), checked on two runs against OpenSees at dt/100. hlaid's own peaks are taken
at the record's 200 Hz samples (their sampling error is included in its error); OpenSees'
over every analysis step.

Usage: python scripts/bench_simulator.py [--records DIR] [--quick]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from hlaid.io import read
from hlaid.model import Building
from hlaid.motions import GroundMotion
from hlaid.opensees import run_opensees_batch
from hlaid.simulate import simulate_response

REPO = Path(__file__).resolve().parents[1]

DEFAULT_RECORDS = REPO.parent / "shared" / "data" / "ground_motions" / "fema_p695_farfield"
TABLE1 = [{"weight_kN": w, "k0": k, "alpha": a, "p": p, "dy": d, "delta_eta": e} for w, k, a, p, d, e in
          zip((171.85, 171.85, 90.0), (1.94e4, 1.65e4, 1.37e4), (0.23, 0.17, 0.12), (2.5, 1.5, 1.9), (7.0, 6.0, 3.0),
              (0.7, 0.66, 1.54))]
G = 9806.65


def thirty_seconds(gm: GroundMotion, rate=200.0, seconds=30.0) -> GroundMotion:
    g = gm.resampled(rate)
    n = round(seconds * rate) + 1
    acc = np.zeros(n)
    acc[: min(n, g.npts)] = g.acc[:n]
    return GroundMotion(dt=1.0 / rate, acc=acc, name=gm.name, source=gm.source)


def upsampled(gm: GroundMotion, factor: int) -> GroundMotion:
    """The same piecewise-linear input sampled ``factor`` times denser."""
    t = np.arange((gm.npts - 1) * factor + 1) * gm.dt / factor
    return GroundMotion(dt=gm.dt / factor, acc=np.interp(t, gm.time, gm.acc), name=gm.name)


def best_of(fn, n):
    """(best wall time, its CPU time over all threads) of ``n`` calls [s]."""
    best = (np.inf, np.inf)
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best = min(best, (time.perf_counter() - t0, time.process_time() - c0))
    return best


def rel_errors(x, ref):
    e = np.abs(x / ref - 1).max(axis=1)  # worst story of each run
    return float(np.median(e)), float(e.max())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", default=str(DEFAULT_RECORDS), help="folder of FEMA P695 far-field AT2 files")
    ap.add_argument("--quick", action="store_true", help="OpenSees at dt only (skip dt/10 and dt/100)")
    a = ap.parse_args(argv)
    import numba
    threads = numba.config.NUMBA_NUM_THREADS
    b = Building.from_stories(TABLE1, name="table1", pdelta=False)
    files = sorted(Path(a.records).glob("FF*.AT2"))[::2][:20]
    motions = [thirty_seconds(read(f, "motion")) for f in files]
    scales = np.linspace(0.1, 1.0, 10)
    rows = np.array([scales * G / m.pga for m in motions])  # each record to PGA 0.1 ... 1.0 g
    print(f"# bench_simulator: Table 1, {len(motions)} records x {scales.size} scales, 30 s at 200 Hz, "
          f"RK4 x 4 sub-steps, {threads} numba threads, {os.cpu_count()} cores", flush=True)

    t0 = time.perf_counter()
    simulate_response(b, motions[0], substeps=4)
    compile_s = time.perf_counter() - t0
    one_full = best_of(lambda: simulate_response(b, motions[0], substeps=4), 20)
    one_peaks = best_of(lambda: simulate_response(b, motions[0], substeps=4, outputs="peaks"), 20)
    batch = best_of(lambda: simulate_response(b, motions, rows, substeps=4, outputs="peaks"), 3)
    ours = simulate_response(b, motions, rows, substeps=4, outputs="peaks").peak_drift
    ref = simulate_response(b, [upsampled(m, 10) for m in motions], rows, substeps=4, outputs="peaks").peak_drift
    err_ours = rel_errors(ours, ref)
    print(f"first call (numba load/compile): {compile_s:.2f} s", flush=True)

    jobs = [(m, s) for i, m in enumerate(motions) for s in rows[i]]
    results = {}
    for f in ([1] if a.quick else [1, 10]):
        wall, cpu, pk = run_opensees_batch(b, jobs, dt_factor=f, workers=threads)
        results[f] = (wall, cpu, rel_errors(pk, ref))
        print(f"OpenSees dt/{f}: {wall:.1f} s (CPU {cpu:.1f} s)", flush=True)
    check = ""
    if not a.quick:  # the reference against OpenSees at dt/100 (two runs: the strongest scale)
        _, _, pk100 = run_opensees_batch(b, [jobs[9], jobs[19]], dt_factor=100, workers=2)
        e = np.abs(pk100 / ref[[9, 19]] - 1).max()
        check = f"reference vs OpenSees at dt/100 (2 runs): max difference {100 * e:.3f} %"

    print()
    print("Wall times on this machine (shared: other jobs inflate them) and CPU time summed over threads or")
    print("processes (insensitive to sharing; CPU / cores is the wall time on idle cores).")
    print()
    print("| case | wall time | CPU time | target | peak-drift error vs converged (median / worst run) |")
    print("|---|---|---|---|---|")
    print(f"| hlaid, one 30 s record at 200 Hz, 4 sub-steps, full histories | {1e3 * one_full[0]:.1f} ms | "
          f"{1e3 * one_full[1]:.1f} ms | <= 20 ms | |")
    print(f"| hlaid, same, peaks only | {1e3 * one_peaks[0]:.1f} ms | {1e3 * one_peaks[1]:.1f} ms | | |")
    print(f"| hlaid, 200 runs (20 records x 10 scales), {threads} threads | {batch[0]:.2f} s | {batch[1]:.2f} s | "
          f"<= 1 s on {threads} cores | {100 * err_ours[0]:.3f} % / {100 * err_ours[1]:.3f} % |")
    for f, (wall, cpu, err) in results.items():
        print(f"| OpenSeesPy, same 200 runs at dt/{f}, {threads} processes | {wall:.1f} s | {cpu:.1f} s | | "
              f"{100 * err[0]:.3f} % / {100 * err[1]:.3f} % |")
    print()
    for f, (wall, cpu, err) in results.items():
        better = "better" if err_ours[1] <= err[1] else "WORSE"
        print(f"- speed-up vs OpenSees at dt/{f}: **{wall / batch[0]:.0f}x** wall, **{cpu / batch[1]:.0f}x** CPU "
              f"(target >= 20x); hlaid's worst-run error is {better} ({100 * err_ours[1]:.3f} % vs "
              f"{100 * err[1]:.3f} %)")
    if check:
        print(f"- converged reference: hlaid, 4 sub-steps on the record linearly interpolated to 2000 Hz; {check}")


if __name__ == "__main__":
    main()
