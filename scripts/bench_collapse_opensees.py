"""Collapse intensities of a clone with a collapse model: hlaid against OpenSeesPy (prints a table).

Case: the Table 1 clone (docs/DESIGN.md section 4) with 3 m stories, P-Delta on, collapse model
``steel-mrf`` (or --collapse), the 10 built-in FEMA P695 far-field records. OpenSees runs the
exported clone script (hlaid.opensees: BoucWen + ElasticPPGap gap springs + P-Delta, Newmark
average acceleration at dt/10); hlaid the batch simulator with RK4 steps of at most 0.5 ms.

Per record and code, the *same* search: IM = Sa(T1, 5%) from 0.5 g multiplied by 1.5 until the
run collapses (a story drift beyond 10 %, or OpenSees failing to converge), then the bracket
bisected ``--bisect`` times (8: 0.16 % of IM). The collapse IM is the bracket's upper end.
Prints every record's collapse IM in both codes, their ratio, and the medians.

Usage: python scripts/bench_collapse_opensees.py [--collapse steel-mrf|'{"theta_p": ...}'] [--records 10]
       [--bisect 8] [--stories 3|1]
"""

from __future__ import annotations

import argparse
import io
import os
import time
from contextlib import redirect_stderr
from pathlib import Path

import numpy as np
from reference_models import table1_stories

from hlaid.ida.measures import get_intensity_measure
from hlaid.io import read
from hlaid.model import Building
from hlaid.opensees import run_opensees
from hlaid.simulate import simulate_response
from hlaid.units import G_MM_S2

REPO = Path(__file__).resolve().parents[1]

DRIFT_LIMIT = 0.10


def collapse_im(collapses, im_start=0.5, factor=1.5, max_hunt=12, n_bisect=8):
    """The collapse IM found by hunting (x ``factor``) and bisection (geometric) with ``collapses(im)``."""
    lo, hi = 0.0, im_start
    for _ in range(max_hunt):
        if collapses(hi):
            break
        lo, hi = hi, hi * factor
    else:
        return np.nan
    if lo == 0.0:
        lo = hi / factor
        while collapses(lo):
            hi, lo = lo, lo / factor
    for _ in range(n_bisect):
        mid = np.sqrt(lo * hi)
        if collapses(mid):
            hi = mid
        else:
            lo = mid
    return hi


def building(stories: int, collapse: str) -> Building:
    if collapse.lstrip().startswith("{"):
        import json
        collapse = json.loads(collapse)  # user ratios: '{"theta_p": 0.02, "theta_pc": 0.05, ...}'
    s = table1_stories()[:stories]
    return Building.from_stories(s, pdelta=True, height=[3000.0] * stories, collapse=collapse, name="table1")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--collapse", default="steel-mrf")
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--bisect", type=int, default=8)
    ap.add_argument("--stories", type=int, default=3, choices=[1, 2, 3])
    ap.add_argument("--dt-factor", type=int, default=10)
    args = ap.parse_args(argv)
    b = building(args.stories, args.collapse)
    motions = read("builtin-suite", "records")[: args.records]
    T1 = float(b.periods()[0])
    sa = get_intensity_measure("sa_t1").compute(motions, T1, 0.05) / G_MM_S2
    stop = DRIFT_LIMIT * b.height
    print(f"Table 1 clone, {args.stories} stor{'y' if args.stories == 1 else 'ies'}, T1 = {T1:.3f} s, P-Delta on, "
          f"collapse model {args.collapse}: {b.collapse.to_dict()}")
    print(f"OpenSees dt/{args.dt_factor}, hlaid RK4 <= 0.5 ms; collapse at {DRIFT_LIMIT:.0%} drift "
          f"(or no convergence); {args.bisect} bisections\n")
    print("| record | Sa(T1) collapse hlaid [g] | OpenSees [g] | ratio | runs (hlaid / OpenSees) | time [s] |")
    print("|---|---|---|---|---|---|")
    rows = []
    for gm, sa1 in zip(motions, sa):
        sub = max(1, int(np.ceil(gm.dt / 0.0005 - 1e-9)))
        n = {"h": 0, "o": 0}

        def ours(im, gm=gm, sa1=sa1, sub=sub, n=n):
            n["h"] += 1
            r = simulate_response(b, gm, im / sa1, substeps=sub, outputs="peaks", stop_drift=stop)
            return bool(r.status[0] != 0 or np.any(r.peak_drift[0] > stop))

        def theirs(im, gm=gm, sa1=sa1, n=n):
            n["o"] += 1
            with redirect_stderr(io.StringIO()):
                r = run_opensees(b, gm, scale=im / sa1, dt_factor=args.dt_factor)
            return bool(not r.ok or np.any(r.peak_drift > stop))

        t0 = time.perf_counter()
        a = collapse_im(ours, n_bisect=args.bisect)
        t1 = time.perf_counter()
        o = collapse_im(theirs, n_bisect=args.bisect)
        t2 = time.perf_counter()
        rows.append((a, o))
        print(f"| {gm.name} | {a:.4g} | {o:.4g} | {a / o:.4f} | {n['h']} / {n['o']} | "
              f"{t1 - t0:.1f} / {t2 - t1:.1f} |", flush=True)
    a, o = np.array(rows).T
    ok = np.isfinite(a) & np.isfinite(o)
    ma, mo = np.median(a[ok]), np.median(o[ok])
    dev = np.abs(a[ok] / o[ok] - 1)
    print(f"\nmedian collapse Sa(T1): hlaid {ma:.4g} g, OpenSees {mo:.4g} g, difference {100 * (ma / mo - 1):+.2f} % "
          f"(target within 2 %); per record: mean |diff| {100 * dev.mean():.2f} %, worst {100 * dev.max():.2f} % "
          f"({ok.sum()} records)")


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
