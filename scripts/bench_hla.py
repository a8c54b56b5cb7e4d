"""Benchmark of hysteresis loop analysis, with its peers in the same run (prints a markdown table).

Case: the Table 1 structure (``configs/poc_3story.yaml``), a 60 s record at 200 Hz (12001
samples; default FEMA P695 FF19 Chi-Chi CHY101-N, its first 60 s, at PGA 0.62 g; without
``../shared/data`` the built-in Kocaeli Duzce 180 padded with free vibration to 60 s), 10 % RMS
noise. Target: HLA of it in <= 1 s.

Timed (median of ``--repeat`` runs after one warm-up call, so numba compilation is excluded
and reported apart): ``hlaid.hla.run_hla`` with each damping option (``rayleigh``, the default,
iterates the analysis until k0 settles), and, as peers, the simulation that made the data
(``hlaid.simulate.simulate_response``, full histories, RK4 x 4 sub-steps, as ``simulate_measurement``
runs it) and real time (the record's duration).

Usage: python scripts/bench_hla.py [--record PATH|builtin:NAME] [--seconds 60] [--repeat 7]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from hlaid.hla import HLAConfig, run_hla
from hlaid.hla.config import ForceConfig
from hlaid.io import read
from hlaid.motions import GroundMotion
from hlaid.simulate import simulate_response
from hlaid.synthetic import load_simulation_config, simulate_measurement

REPO = Path(__file__).resolve().parents[1]

DEFAULT_RECORD = REPO.parent / "shared" / "data" / "ground_motions" / "fema_p695_farfield" / \
    "FF19_RSN1244_CHICHI_CHY101-N.AT2"
FALLBACK = "builtin:kocaeli-1999-dzc180"
RATE_HZ = 200.0
PGA_G = 0.62


def record(spec: str | None, seconds: float) -> GroundMotion:
    """The benchmark record at 200 Hz and PGA 0.62 g, cut or padded (free vibration) to ``seconds``."""
    if spec is None:
        spec = str(DEFAULT_RECORD) if DEFAULT_RECORD.is_file() else FALLBACK
    gm = read(spec, "motion").scaled_to_pga(PGA_G).resampled(RATE_HZ)
    n = int(round(seconds * RATE_HZ)) + 1
    acc = np.zeros(n)
    acc[: min(n, gm.npts)] = gm.acc[:n]
    return GroundMotion(dt=gm.dt, acc=acc, name=gm.name, source=gm.source)


def timed(fn, repeat: int) -> tuple[float, float]:
    """``(first call, median of repeat calls)`` wall time [s]."""
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return first, statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--record", help=f"ground motion (default: {DEFAULT_RECORD.name}, else {FALLBACK})")
    ap.add_argument("--seconds", type=float, default=60.0, help="record length [s]")
    ap.add_argument("--repeat", type=int, default=7, help="timed runs per case (median reported)")
    a = ap.parse_args(argv)
    import numba

    building = load_simulation_config(REPO / "configs" / "poc_3story.yaml").building.build()
    gm = record(a.record, a.seconds)
    meas = simulate_measurement(building, gm, rate_hz=None, noise_rms=0.10, seed=0)
    duration = (gm.npts - 1) * gm.dt
    print(f"# bench_hla: Table 1, {gm.name}, {duration:g} s at {RATE_HZ:g} Hz ({gm.npts} samples), PGA {PGA_G} g, "
          f"10 % noise; median of {a.repeat} runs; {numba.config.NUMBA_NUM_THREADS} numba threads, "
          f"{os.cpu_count()} cores", flush=True)

    sim_first, sim = timed(lambda: simulate_response(building, gm, substeps=4), a.repeat)
    rows = []
    for damping in ("rayleigh", "none", "regression"):
        cfg = HLAConfig(force=ForceConfig(damping=damping))
        first, t = timed(lambda cfg=cfg: run_hla(meas, cfg), a.repeat)
        n_hc = [len(s.half_cycles) for s in run_hla(meas, cfg).stories]
        rows.append((f"`hla`, damping: {damping}" + (" (default)" if damping == "rayleigh" else ""), first, t, n_hc))

    print()
    print("| step | first call | median | target | / simulation | x real time | half cycles per story |")
    print("|---|---|---|---|---|---|---|")
    for label, first, t, n_hc in rows:
        target = "<= 1 s" if "default" in label else ""
        print(f"| {label} | {1e3 * first:.0f} ms | **{1e3 * t:.0f} ms** | {target} | {t / sim:.1f} | "
              f"{duration / t:.0f}x | {', '.join(map(str, n_hc))} |")
    print(f"| peer: `simulate` (full histories, RK4 x 4) | {1e3 * sim_first:.0f} ms | {1e3 * sim:.0f} ms | | 1.0 | "
          f"{duration / sim:.0f}x | |")
    print(f"| peer: real time | | {1e3 * duration:.0f} ms | | {duration / sim:.0f} | 1x | |")
    default = rows[0][2]
    print()
    print(f"- HLA (default) of {duration:g} s: **{1e3 * default:.0f} ms** (target <= 1 s: "
          f"{'met' if default <= 1.0 else 'NOT met'}), {duration / default:.0f}x faster than real time, "
          f"{default / sim:.1f}x the simulation that made the data.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
