"""The worked example of docs/loss.md: FEMA P-58 losses of the demo building through pelicun.

Usage (needs ``pip install 'hlaid[loss]'``)::

    hlaid demo --out hlaid-demo
    python scripts/study_loss.py hlaid-demo            # runs hlaid loss hlaid-demo unless hlaid-demo/loss exists

Writes ``docs/figures/loss_curve.png`` and ``docs/figures/loss_repair_cost.png`` (copies of the run's
``loss/`` figures) and prints the tables of docs/loss.md (the recorded event and the loss curve),
each with the command behind it.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", help="a run folder (hlaid demo --out DIR)")
    ap.add_argument("--force", action="store_true", help="recompute the losses even when RUN_DIR/loss exists")
    args = ap.parse_args(argv)
    run = Path(args.run_dir)
    if args.force or not (run / "loss" / "loss.json").exists():
        from hlaid.run.loss import loss_of_run

        loss_of_run(run, force=args.force)
    block = json.loads((run / "loss" / "loss.json").read_text())
    FIGURES.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(run / "loss" / "loss_curve.png", FIGURES / "loss_curve.png")
    shutil.copyfile(run / "loss" / "repair_cost.png", FIGURES / "loss_repair_cost.png")
    r = block["recorded"]
    print(f"## Recorded event (`hlaid loss {run}`; {block['engine']})\n")
    print(f"{block['inventory']}; floor area {sum(block['floor_area_m2']):.1f} m2 ({block['floor_area_source']}); "
          f"replacement {block['replacement_cost']:,.0f} USD_2011, {block['replacement_time']:,.0f} worker-days; "
          f"collapse fragility median {block['collapse_fragility']['median_g']:.3g} g, beta "
          f"{block['collapse_fragility']['beta']:.2f} ({block['collapse_fragility']['source']}); "
          f"{block['n_ensemble']} clones, {block['realizations']} realizations per assessment.\n")
    print("| measure | median | 90 % band |\n|---|---|---|")
    lo, hi = r["repair_cost_band"]
    print(f"| repair cost [USD_2011] | {r['repair_cost_median']:,.0f} | {lo:,.0f} - {hi:,.0f} |")
    lo, hi = r["repair_cost_ratio_band"]
    print(f"| repair cost / replacement | {r['repair_cost_ratio_median']:.1%} | {lo:.1%} - {hi:.1%} |")
    for k in ("parallel", "sequential"):
        lo, hi = r[f"repair_time_{k}_band"]
        print(f"| repair time, {k} [worker-days] | {r[f'repair_time_{k}_median']:.1f} | {lo:.1f} - {hi:.1f} |")
    print(f"| P(collapse) | {r['p_collapse']:.1%} | |\n| P(irreparable) | {r['p_irreparable']:.1%} | |")
    print(f"\nIntensity {r['im_label']} = {r['im']:.3g} g.\n")
    print(f"## Loss curve (`hlaid loss {run}`, file loss/loss_curve.csv)\n")
    print("| Sa(T1) [g] | mean loss ratio | median | 90 % band | P(collapse) | P(irreparable) | collapsed in replay |")
    print("|---|---|---|---|---|---|---|")
    for s in block["stripes"]:
        lo, hi = s["repair_cost_ratio_band"]
        print(f"| {s['level_g']:.3g} | {s['repair_cost_ratio_mean']:.1%} | {s['repair_cost_ratio_median']:.1%} | "
              f"{lo:.1%} - {hi:.1%} | {s['p_collapse']:.1%} | {s['p_irreparable']:.1%} | "
              f"{s['n_collapsed_in_replay']} / {s['n_demand_realizations']} |")
    print(f"\nwrote {FIGURES / 'loss_curve.png'} and {FIGURES / 'loss_repair_cost.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
