"""What the classifiers' knobs buy: accuracy and time of identification per choice.

    python scripts/study_svm_knobs.py                          # 3 records x 2 seeds, paper method
    python scripts/study_svm_knobs.py --refine --seeds 0 1 2   # with the replay refinement too

The Table 1 building (10 % noise, records at PGA 0.62 g, as ``study_identification.py``),
identified from scratch with the default settings and with one knob changed at a time:

- the cross-validated C and gamma grid against one fixed pair (no cross-validation),
- the bags (5 machines on random halves) against 3 and against one machine on all samples,
- the outer loop (coarse to fine, then fine passes along reconstructed paths until the
  parameters settle, at most 3 iterations) against at most 1 and 2 iterations.

Prints one row per choice: the 12 parameters' |relative error| (alpha, p, dy, delta_eta of
the 3 stories) of the paper's method alone (the classifiers' and regressions' estimate, what
the knobs act on), mean over the runs and worst run's mean and worst single error, the same
after the refinement with ``--refine``, and the mean wall time of the classifier passes
(training samples and fits), of the whole identification and its CPU seconds. Every choice runs the same
measurements one after the other in one process; compare times within one run.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np
from study_identification import TABLE1_RECORDS, errors, run_errors  # a sibling script (scripts/ is on sys.path)

from hlaid import _progress, identify_clone
from hlaid.identify import IdentifyConfig
from hlaid.io import read
from hlaid.synthetic import load_simulation_config, simulate_measurement


def choices(base: IdentifyConfig) -> dict[str, IdentifyConfig]:
    """The default settings and one knob changed at a time."""
    svm, outer = base.svm, base.outer

    def with_svm(**kw):
        return dataclasses.replace(base, svm=dataclasses.replace(svm, **kw))

    def with_outer(n):
        return dataclasses.replace(base, outer=dataclasses.replace(outer, max_iterations=n))

    return {"default (C x gamma grid, 5 bags, <= 3 outer iterations)": base,
            "no cross-validation: C 1000, gamma 0.1 x scale": with_svm(C_grid=(1000.0,), gamma_grid=(0.1,)),
            "no cross-validation: C 10000, gamma 0.03 x scale": with_svm(C_grid=(10000.0,), gamma_grid=(0.03,)),
            "3 bags": with_svm(n_bags=3),
            "1 machine on all samples (no bags)": with_svm(n_bags=1),
            "<= 2 outer iterations": with_outer(2),
            "1 outer iteration (coarse + fine pass)": with_outer(1)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=3, help="the first N of Table 1's records (default 3)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--refine", action="store_true", help="also refine (default: the paper's method alone)")
    ap.add_argument("--only", nargs="+", default=None, help="run only the choices whose name starts with these")
    args = ap.parse_args(argv)
    _progress.set_verbosity(0)
    base = IdentifyConfig()
    if not args.refine:
        base = dataclasses.replace(base, refine=dataclasses.replace(base.refine, method="none"))
    truth = load_simulation_config("configs/poc_3story.yaml").building.build()
    meas = [simulate_measurement(truth, read(r, "motion").scaled_to_pga(0.62), noise_rms=0.1, seed=s)
            for r in TABLE1_RECORDS[: args.records] for s in args.seeds]
    print(f"{len(meas)} runs per choice ({args.records} records x seeds {args.seeds}), "
          f"load average {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    for name, cfg in choices(base).items():
        if args.only and not any(name.startswith(o) for o in args.only):
            continue
        paper, final, secs, cls, cpu = [], [], [], [], []
        for m in meas:
            t, c = time.perf_counter(), _cpu()
            res = identify_clone(m, cfg, cache_dir="")
            secs.append(time.perf_counter() - t)
            cpu.append(_cpu() - c)
            cls.append(sum(v for k, v in res.timings.items() if k.startswith("classifiers_")))
            row = {"identifiable": [s.identifiable for s in res.clone.paper.stories],
                   "paper": errors(res.paper_estimate, truth), "final": errors(res.clone.building, truth)}
            paper.append(run_errors(row, "paper"))
            final.append(run_errors(row, "final"))
        rows.append((name, paper, final, secs, cls, cpu))
        print(f"  {name}: {_cell(paper)} | {np.mean(cls):.1f} s classifiers, {np.mean(secs):.1f} s in all, "
              f"{np.mean(cpu):.1f} s CPU; load average {os.getloadavg()[0]:.2f}", flush=True)
    head = "| choice | paper method: mean error (worst run) | worst single error |"
    head += " refined: mean (worst run) | worst |" if args.refine else ""
    head += " classifier passes [s] | identification [s] | CPU [s] |"
    print("\n" + head + "\n" + "|---" * (head.count("|") - 1) + "|")
    for name, paper, final, secs, cls, cpu in rows:
        ref = f" {_cell(final)} |" if args.refine else ""
        print(f"| {name} | {_cell(paper)} |{ref} {np.mean(cls):.1f} | {np.mean(secs):.1f} | {np.mean(cpu):.1f} |")
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")
    return 0


def _cpu() -> float:
    """CPU seconds of this process and of its finished worker processes."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _cell(errs: list) -> str:
    means = [float(e.mean()) for e in errs]
    return f"{np.mean(means):.1%} ({max(means):.1%}) | {max(float(e.max()) for e in errs):.1%}"


if __name__ == "__main__":
    sys.exit(main())
