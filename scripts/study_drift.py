"""Drift reconstruction accuracy (docs/identification.md, "Drift paths").

    python scripts/study_drift.py --out runs/study_drift [--n-random 10]

For the Table 1 structure under five records at 0.62 g and for random buildings (the
identification study's generator, scaled until every story reaches 1.5 dy), noise-free and
at 10 % RMS noise: RMS and peak error of each story's drift against the true drift, as a
fraction of the true drift's RMS and peak, for HLA's drift and for the reconstructed path
(:func:`hlaid.identify.drift.reconstruct_drift`) with the true building and with a building
whose parameters are all off by a random +-10 % (what the outer loop replays with).
Writes ``drift.json`` and ``drift.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from study_identification import RANDOM_RECORDS, TABLE1_RECORDS, random_building, scale_to_yield

from hlaid.hla import run_hla
from hlaid.identify.drift import hla_drift, reconstruct_drift
from hlaid.io import read
from hlaid.measurement import measured_ground
from hlaid.synthetic import load_simulation_config, simulate_measurement

PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")


def errors(x: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per story: RMS error / RMS of the truth, peak |error| / peak |truth|."""
    rms = np.sqrt(np.mean((x - truth) ** 2, axis=0)) / np.sqrt(np.mean(truth**2, axis=0))
    peak = np.max(np.abs(x - truth), axis=0) / np.max(np.abs(truth), axis=0)
    return rms, peak


def case(building, gm, noise: float, seed: int) -> dict:
    meas = simulate_measurement(building, gm, noise_rms=noise, seed=seed)
    res = run_hla(meas)
    ground = measured_ground(meas, res.band_hz[1], name="")
    rng = np.random.default_rng(seed + 100)
    off = building.replace(**{k: getattr(building, k) * rng.uniform(0.9, 1.1, building.n_stories) for k in PARAMS})
    truth = meas.truth.drift
    out = {}
    for name, x in (("hla", hla_drift(res)), ("replay_true", reconstruct_drift(res, ground, building)),
                    ("replay_10pct_off", reconstruct_drift(res, ground, off))):
        rms, peak = errors(x, truth)
        out[name] = {"rms": rms.tolist(), "peak": peak.tolist()}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="runs/study_drift")
    ap.add_argument("--n-random", type=int, default=10)
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t1 = load_simulation_config("configs/poc_3story.yaml").building.build()
    jobs = [("table1", t1, read(r, "motion").scaled_to_pga(0.62)) for r in TABLE1_RECORDS]
    rng = np.random.default_rng(2026)
    n = 0
    while n < args.n_random:
        b = random_building(rng)
        gm = scale_to_yield(b, read(RANDOM_RECORDS[n % len(RANDOM_RECORDS)], "motion"))
        if gm is not None:
            jobs.append(("random", b, gm))
            n += 1
    rows = []
    for j, (group, b, gm) in enumerate(jobs):
        for noise in (0.0, 0.10):
            r = {"group": group, "record": gm.name, "noise": noise, "stories": b.n_stories, **case(b, gm, noise, j)}
            rows.append(r)
            print(f"[{j + 1}/{len(jobs)}] {group} {gm.name} noise {noise:.0%}: "
                  + " | ".join(f"{k} rms {np.round(100 * np.asarray(r[k]['rms']), 0)}"
                               for k in ("hla", "replay_true", "replay_10pct_off")), flush=True)
    (out / "drift.json").write_text(json.dumps(rows, indent=1))
    lines = ["| structures | noise | path | RMS error: mean / worst story | peak error: mean / worst story |",
             "|---|---|---|---|---|"]
    for group in ("table1", "random"):
        for noise in (0.0, 0.10):
            sel = [r for r in rows if r["group"] == group and r["noise"] == noise]
            for k in ("hla", "replay_true", "replay_10pct_off"):
                rms = np.concatenate([r[k]["rms"] for r in sel])
                peak = np.concatenate([r[k]["peak"] for r in sel])
                lines.append(f"| {group} ({len(sel)} runs) | {noise:.0%} | {k} | {100 * rms.mean():.1f} % / "
                             f"{100 * rms.max():.1f} % | {100 * peak.mean():.1f} % / {100 * peak.max():.1f} % |")
    (out / "drift.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
