"""Benchmark of hlaid's IDA against OpenSeesPy on the same runs (prints markdown tables).

Case: the Table 1 clone (docs/DESIGN.md section 4) with 3 m stories, P-Delta on (the IDA default),
the 44 FEMA P695 far-field components, IM = Sa(T1, 5%), 20 levels 0.4, 0.8, ..., 8.0 g
(up to about the median collapse intensity): 880 record x level runs.

1. ``hlaid.ida`` as users run it: grid only (``refine=False``; a record is not run above
   its collapse), then with hunt-and-fill refinement; wall and CPU time, runs, peak memory.
2. The full 880-run grid without early stop through the batch simulator (the runs the IDA
   performs, each to the end of its record) -- and the same 880 runs in OpenSeesPy through
   the exported clone script, at dt and dt/10, on as many worker processes as hlaid's threads.
3. Accuracy of the peak drifts against a converged reference (hlaid, one RK4 step per 0.5 ms:
   the records linearly interpolated to 2000 Hz, the same input; peaks at every step) on every 4th
   level, for runs below the 10 % drift limit; and the IDA cross-check: hlaid's IDA points vs
   OpenSees at dt/10 (all records x levels, and the issue's 10 records x 8 levels).

Usage: python scripts/bench_ida.py [--records DIR] [--quick] [--figures DIR]
(--quick: OpenSees at dt only, on every 4th level; --figures: also write the docs figures:
the IDA curves, fragility and exceedance of this run and the Vamvatsikos & Cornell SDOF check)
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc
from pathlib import Path

import numpy as np

from hlaid import _progress
from hlaid.ida import IDAConfig, prepare_building, run_ida
from hlaid.ida.analysis import upsampled
from hlaid.io import read
from hlaid.model import Building
from hlaid.opensees import run_opensees_batch
from hlaid.simulate import simulate_response

REPO = Path(__file__).resolve().parents[1]

DEFAULT_RECORDS = REPO.parent / "shared" / "data" / "ground_motions" / "fema_p695_farfield"
TABLE1 = [{"weight_kN": w, "k0": k, "alpha": a, "p": p, "dy": d, "delta_eta": e, "height_mm": 3000.0}
          for w, k, a, p, d, e in zip((171.85, 171.85, 90.0), (1.94e4, 1.65e4, 1.37e4), (0.23, 0.17, 0.12),
                                      (2.5, 1.5, 1.9), (7.0, 6.0, 3.0), (0.7, 0.66, 1.54))]
LEVELS = np.round(np.arange(1, 21) * 0.4, 3)
MAX_STEP = 0.0025


def timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def grid(b: Building, motions, scales, rate=None, stop=None):
    """Peak drifts (record, level, story) of every record x scale row. As the IDA runs them:
    each record refined to ``ceil(dt / MAX_STEP)`` samples per sample (linear interpolation) and
    one RK4 step per refined sample; or, with ``rate`` [Hz], refined to that rate."""
    fine = []
    for m in motions:
        f = int(np.ceil(m.dt / MAX_STEP - 1e-9)) if rate is None else round(m.dt * rate)
        fine.append(upsampled(m, f))
    sub = np.array([round(m.dt * 1e9) for m in fine])
    out = np.empty((len(motions), scales.shape[1], b.n_stories))
    for s in np.unique(sub):  # one call per refined dt (any grouping gives the same numbers)
        sel = np.flatnonzero(sub == s)
        r = simulate_response(b, [fine[i] for i in sel], scales[sel], substeps=1, outputs="peaks", stop_drift=stop)
        out[sel] = r.peak_drift.reshape(sel.size, scales.shape[1], -1)
    return out


def errs(x, ref, ok):
    e = np.abs(x / ref - 1).max(axis=-1)[ok]
    e = e[np.isfinite(e)]
    return float(np.median(e)), float(e.max()), int(e.size)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", default=str(DEFAULT_RECORDS))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--figures", help="write the documentation figures into this folder")
    a = ap.parse_args(argv)
    import numba
    threads = numba.config.NUMBA_NUM_THREADS
    _progress.set_verbosity(0)
    clone = Building.from_stories(TABLE1, name="table1", pdelta=False)
    motions = read(a.records, "records")
    b, _ = prepare_building(clone)
    R, L = len(motions), LEVELS.size
    print(f"# bench_ida: Table 1 clone (P-Delta on), {R} records x {L} levels = {R * L} runs, "
          f"IM Sa(T1, 5%), {threads} numba threads", flush=True)
    run_ida(clone, motions[:1], IDAConfig(levels=[1.0], refine=False))  # load the compiled kernels

    tracemalloc.start()
    res, w_grid, c_grid = timed(lambda: run_ida(clone, motions, IDAConfig(levels=LEVELS, refine=False)))
    mem_grid = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    res_full, w_full, c_full = timed(lambda: run_ida(clone, motions, IDAConfig(levels=LEVELS)))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    sa = res.record_im
    scales = LEVELS[None, :] / sa[:, None]
    pk_ida, w_raw, c_raw = timed(lambda: grid(b, motions, scales))
    every = slice(3, None, 4)
    pk_ref = grid(b, motions, scales[:, every], rate=2000.0)
    ok = (pk_ref / 3000.0).max(axis=-1) < 0.10
    e_ida = errs(pk_ida[:, every], pk_ref, ok)

    jobs = [(m, s) for i, m in enumerate(motions) for s in scales[i]]
    sub_jobs = [(m, s) for i, m in enumerate(motions) for s in scales[i, every]]
    rows, os_pk = [], {}
    for f in ([1] if a.quick else [1, 10]):
        js = sub_jobs if a.quick else jobs
        wall, cpu, pk = run_opensees_batch(b, js, dt_factor=f, workers=threads)
        pk = pk.reshape(R, -1, b.n_stories)
        os_pk[f] = pk
        e = errs(pk if a.quick else pk[:, every], pk_ref, ok)
        rows.append((f, wall, cpu, len(js), e))
        print(f"OpenSees dt/{f}: {wall:.1f} s wall, {cpu:.1f} s CPU, {len(js)} runs", flush=True)

    print()
    print("Wall times on this machine (shared with other jobs) and CPU time summed over threads/processes;")
    print(f"errors: peak drift, worst story of each run, vs the converged reference, "
          f"on {e_ida[2]} runs below 10 % drift.")
    print()
    print("| case | runs | wall time | CPU time | peak-drift error (median / worst run) |")
    print("|---|---|---|---|---|")
    print(f"| `hlaid.ida`, grid only (stops at collapse) | {int(res.timing['runs'])} | "
          f"{w_grid:.1f} s | {c_grid:.1f} s | |")
    print(f"| `hlaid.ida`, with hunt-and-fill | {int(res_full.timing['runs'])} | {w_full:.1f} s | {c_full:.1f} s | |")
    print(f"| hlaid, the full {R}x{L} grid, every run to the record's end | {R * L} | {w_raw:.1f} s | {c_raw:.1f} s | "
          f"{100 * e_ida[0]:.3f} % / {100 * e_ida[1]:.3f} % |")
    for f, wall, cpu, n, e in rows:
        print(f"| OpenSeesPy at dt/{f}, {threads} processes | {n} | {wall:.1f} s | {cpu:.1f} s | "
              f"{100 * e[0]:.3f} % / {100 * e[1]:.3f} % |")
    print()
    print(f"- target: the {R * L}-run IDA in <= 10 s on 2 cores: `hlaid.ida` grid {w_grid:.1f} s "
          f"(CPU {c_grid:.1f} s), full grid to the end {w_raw:.1f} s (CPU {c_raw:.1f} s)")
    for f, wall, cpu, n, e in rows:
        k = n / (R * L)
        better = "better" if e_ida[1] <= e[1] else "WORSE"
        print(f"- speed-up vs OpenSees at dt/{f} (same runs): **{wall / (w_raw * k):.0f}x** wall, "
              f"**{cpu / (c_raw * k):.0f}x** CPU (target >= 20x at equal or better accuracy: hlaid's worst "
              f"error is {better}, {100 * e_ida[1]:.3f} % vs {100 * e[1]:.3f} %)")
    print(f"- peak memory: {mem_grid / 2**20:.1f} MiB traced during the grid IDA; process max RSS {rss:.0f} MiB "
          "(torch, numba and matplotlib loaded)")
    print(f"- collapse fragility (capacities MLE): median {res_full.collapse_fragility(n_boot=0).median:.2f} g, "
          f"beta {res_full.collapse_fragility(n_boot=0).beta:.2f}; {sum(np.isfinite(res_full.collapse_im))}/{R} "
          "records collapsed")
    if 10 in os_pk:
        pk_os = os_pk[10]
        valid = (pk_ida / 3000.0).max(axis=-1) < 0.10
        d = np.abs(pk_ida / pk_os - 1)[valid]
        d = d[np.isfinite(d)]
        sub = np.zeros_like(valid)
        sub[np.ix_(np.arange(0, R, 4)[:10], np.arange(3, L, 2)[:8])] = True  # 10 records x 8 levels
        d10 = np.abs(pk_ida / pk_os - 1)[valid & sub]
        print(f"- IDA cross-check vs OpenSees at dt/10 (peak drift of every story, runs below 10 % drift): "
              f"median {100 * np.median(d):.2f} %, 95th percentile {100 * np.percentile(d, 95):.2f} %, "
              f"worst {100 * d.max():.2f} % over {d.size} values; 10 records x 8 levels: median "
              f"{100 * np.median(d10):.2f} %, worst {100 * d10.max():.2f} % (target: median <= 2 %)")


    if a.figures:
        figures(res_full, Path(a.figures))


def figures(res, out: Path):
    """Docs figures: this IDA, and the V&C (2002) Fig. 4a SDOF against the bilinear reference."""
    from reference_models import VC2002 as V  # the SDOF and its independent bilinear reference
    from reference_models import bilinear_peak

    from hlaid.ida import intensity
    from hlaid.ida.plots import plot_exceedance, plot_fragility, plot_ida_curves
    from hlaid.plots import plt, save_figure
    out.mkdir(parents=True, exist_ok=True)
    save_figure(plot_ida_curves(res, title="IDA of the Table 1 clone (P-Delta), 44 far-field records"),
                out / "ida_table1_curves.png")
    save_figure(plot_fragility(res), out / "ida_table1_fragility.png")
    save_figure(plot_exceedance(res), out / "ida_table1_exceedance.png")
    gm = read(DEFAULT_RECORDS.parent / "openseismomatlab" / "LomaPrietaHallsValley90.dat", "motion", units="m/s^2")
    sa0 = intensity(gm, "sa_t1", period=V.T)[0]
    levels = np.round(np.arange(0.05, 3.51, 0.05), 3)
    ref = np.array([bilinear_peak(gm.acc * (L / sa0), gm.dt, 50, V.M, V.K, V.ALPHA, V.UY,
                                  2 * V.XI * (2 * np.pi / V.T) * V.M) for L in levels]) / V.UY
    b = Building(mass=[V.M], k0=[V.K], alpha=[V.ALPHA], p=[30.0], dy=[V.UY], delta_eta=[0.0], height=[1e5])
    r = run_ida(b, gm, IDAConfig(levels=levels, refine=False, pdelta=False, max_step=0.002))
    g = np.argsort(np.where(r.point_stage == "grid", r.point_im, np.inf))[: levels.size]
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    ax.plot(ref, levels, "k-", lw=2.5, alpha=0.35, label="bilinear reference (Newmark, dt/50)")
    ax.plot(r.peak_drift[g, 0] / V.UY, r.point_im[g], "r.-", lw=1, ms=4, label="hlaid IDA (Bouc-Wen, p = 30)")
    ax.set_xlim(0, 3)
    ax.set_ylim(0, 3.5)
    ax.set_xlabel("ductility, mu")
    ax.set_ylabel("Sa(T1, 5%) [g]")
    ax.set_title("T = 1 s, 5 %, alpha = 1 %: Loma Prieta, Halls Valley 090")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    save_figure(fig, out / "ida_vc2002_sdof.png")


if __name__ == "__main__":
    main()
