"""Event-to-event clones: a clone of a building's earlier events predicts its next one.

    python scripts/study_events.py --out runs/events [--parts steel,hotel,simulated] \\
        [--peer runs/peer/peer.json] [--ensemble 20] [--seeds 0,1,2] [--force]

Parts:

* **steel** (``steel-frame`` of configs/validate_real.yaml, its events in time order, its
  compared band): for k = 1..n-1 the clone identified jointly from events 1..k
  (``hlaid.identify_clone``) predicts event k+1, from the state it carries and undamaged
  (``hlaid.predict_event``, R per floor, peak-drift errors, the share of the
  measurement inside the predictive band of ``--ensemble`` clones drawn from its posterior).
  Beside it the sequential clone: the clone of event 1 updated with each later event
  (``hlaid.update_clone``), its parameters compared with the joint clone's of
  the same events (share within 2 combined standard deviations).
* **hotel** (``hotel``, events in numeric order): the joint clone of events 1..3 predicts 4, then
  it is updated event by event, each clone predicting the next (joint fits over many long
  records are slow). With ``--peer`` (a ``peer.json`` of scripts/study_linear_peer.py) the
  linear peer's ``history`` case of the same events stands beside each prediction.
* **simulated**: the paper's Table 1 building (configs/poc_3story.yaml) under three records in a
  row at growing PGA and a fourth, 10 % noise, two record sets, several seeds: the parameter
  errors of the joint clone of the first three against the best single-event clone's, the
  carried degradation eta against the true one, and the fourth record's prediction against the
  true building's replay from its true state.

Writes ``events.json``, ``events.md`` (the tables, each naming this command), ``figures/`` and the
real parts' ``clones/`` into
``--out`` (new, or replaced with ``--force``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from hlaid import _progress, identify_clone, update_clone
from hlaid._fileio import atomic_directory, write_json
from hlaid.clone import Clone
from hlaid.config import load_config
from hlaid.errors import InputError
from hlaid.events.predict import predict_event
from hlaid.events.start import START_STATES
from hlaid.identify import IdentifyConfig
from hlaid.motions import GroundMotion
from hlaid.motions.builtin import load_builtin
from hlaid.plots import plot_prediction, save_figure
from hlaid.studies.validation import identify_config_of, load_validation_config, read_event
from hlaid.synthetic import load_simulation_config, simulate_events

REAL_PARTS = {"steel": {"structure": "steel-frame", "first_k": 1, "joint_upto": None, "sequential_from": 1},
              "hotel": {"structure": "hotel", "first_k": 3, "joint_upto": 3, "sequential_from": 3}}
"""Per real part: its structure, the first k predicted from events 1..k, the largest k fitted
jointly (None: every k) and how many events the sequential clone starts from (jointly)."""

RECORD_SETS = (("elcentro-1940-ns", "kocaeli-1999-dzc180", "northridge-1994-mul009", "kobe-1995-nis000"),
               ("lomaprieta-1989-cap000", "landers-1992-yer270", "hector-1999-hec000", "duzce-1999-bol000"))
"""Built-in records of the simulated part: three events in a row and the one predicted."""

PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")
AGREE_SD = 2.0
"""Sequential and joint parameters agree where ``|difference| <= AGREE_SD`` combined sd."""


def time_order(names: list[str]) -> list[str]:
    """Event names in time order: numeric names by number, others as the config lists them."""
    return sorted(names, key=int) if all(n.isdigit() for n in names) else names


def prediction_row(p, k: int, names: list[str], how: str, seconds: float, start: str, wide=None) -> dict:
    """One prediction; ``start`` as asked (``auto`` resolves to ``p.start``, kept as ``resolved``);
    ``wide``: the same clone's prediction in the band the event's records hold (its story-drift
    figures kept as ``wide``)."""
    d = p.to_dict()
    w = None if wide is None else {k: wide.to_dict()[k] for k in (
        "band_hz", "r_mean", "drift_r", "drift_r_mean", "peak_drift_error", "peak_drift_error_mean_abs",
        "residual_drift_error")}
    return {"how": how, "k": k, "identified_on": names[:k], "event": p.event, "start": start, "wide": w,
            "resolved": p.start, "start_reason": p.start_reason, "r": d["r"], "r_mean": d["r_mean"],
            "drift_r": d["drift_r"], "drift_r_mean": d["drift_r_mean"], "peak_drift_error": d["peak_drift_error"],
            "peak_drift_error_mean_abs": d["peak_drift_error_mean_abs"], "roof_error": d["roof_error"],
            "coverage": d["coverage"], "coverage_mean": d["coverage_mean"], "pga_g": d["pga_g"],
            "clone_seconds": seconds, "status": d["status"]}


def agreement(a, b) -> dict:
    """Two clones' posteriors: per parameter ``|difference| / sqrt(sd_a^2 + sd_b^2)`` (transformed units)."""
    if a is None or b is None or a.slots != b.slots:
        return {"share": None}
    z = np.abs(np.asarray(a.centre) - np.asarray(b.centre)) / np.sqrt(a.std**2 + b.std**2)
    return {"share": float(np.mean(z <= AGREE_SD)), "z": dict(zip(a.names, z.round(3).tolist())),
            "z_max": float(z.max()), "z_median": float(np.median(z))}


def real_part(cfg, spec, part: dict, n_ensemble: int, folder: Path, log) -> dict:
    """Joint and sequential clones of one structure's event history, each predicting the next
    event (the clones saved in ``folder/clones``, figures in ``folder/figures``)."""
    icfg = identify_config_of(spec, source=cfg.source)
    band = None if spec.compare_band_hz is None else tuple(spec.compare_band_hz)
    names = time_order([e.name for e in spec.events])
    meas = [read_event(spec, n, cfg.data_dir) for n in names]
    meas = [dataclasses.replace(m, name=n) for m, n in zip(meas, names)]
    n = len(names)
    upto = n - 1 if part["joint_upto"] is None else part["joint_upto"]
    rows, joint, figs = [], {}, []
    (folder / "clones").mkdir(exist_ok=True)

    def save(clone, how, k):
        clone.save(folder / "clones" / f"{spec.name}_{how}_{names[0]}-{names[k - 1]}.json")

    def predict(clone, k, how, seconds):
        out = []
        for start in START_STATES:
            p = predict_event(clone, meas[k], band_hz=band, hla_config=icfg.hla, start=start,
                              n_ensemble=n_ensemble if start == "carried" else 0)
            wide = predict_event(clone, meas[k], hla_config=icfg.hla, start=start)  # the band the records hold
            out.append(prediction_row(p, k, names, how, seconds, start, wide))
            log(f"{spec.name}: {how} clone of {names[0]}..{names[k - 1]} -> {names[k]} ({start}): "
                f"R {np.round(p.r, 3)}, mean {p.r_mean:.3f}")
            if start == "carried":
                figs.append((f"{spec.name}_{how}_{names[k - 1]}_to_{names[k]}", p.r_mean, p, how, k))
        return out

    for k in range(min(part["first_k"], part["sequential_from"]), upto + 1):
        t = time.perf_counter()
        res = identify_clone(meas[:k], icfg)
        joint[k] = (res.clone, time.perf_counter() - t)
        save(res.clone, "joint", k)
        log(f"{spec.name}: joint clone of {names[0]}..{names[k - 1]} in {joint[k][1]:.0f} s")
        if k >= part["first_k"]:
            rows += predict(res.clone, k, "joint", joint[k][1])
    seq, agree = joint[part["sequential_from"]][0], []
    for k in range(part["sequential_from"] + 1, n):
        t = time.perf_counter()
        seq = update_clone(seq, meas[k - 1], icfg).clone
        dt = time.perf_counter() - t
        save(seq, "sequential", k)
        log(f"{spec.name}: sequential clone + {names[k - 1]} in {dt:.0f} s")
        rows += predict(seq, k, "sequential", dt)
        if k in joint:
            agree.append({"k": k, "identified_on": names[:k], **agreement(joint[k][0].uncertainty, seq.uncertainty),
                          "joint": _params(joint[k][0]), "sequential": _params(seq)})
    for tag, _, p, how, k in _chosen_figures(figs):
        save_figure(plot_prediction(p, title=f"{spec.name}: {how} clone of {names[0]}..{names[k - 1]} predicts "
                                    f"{names[k]}", levels=spec.levels), folder / "figures" / f"{tag}.png", dpi=72)
    return {"structure": spec.name, "events": names, "band_hz": band, "identify": {"system": icfg.system,
            "refine": icfg.refine.method}, "predictions": rows, "agreement": agree, "n_ensemble": n_ensemble}


def _chosen_figures(figs: list, most: int = 4) -> list:
    """Every case where there are few, else the worst and best of each kind of clone."""
    if len(figs) <= most:
        return figs
    out = []
    for how in dict.fromkeys(f[3] for f in figs):
        own = sorted((f for f in figs if f[3] == how), key=lambda f: f[1])
        out += own if len(own) <= 2 else [own[0], own[-1]]
    return out


def _params(clone: Clone) -> dict:
    b = clone.building
    return {**{k: getattr(b, k).tolist() for k in PARAMS}, "damping": b.damping.ratio}


def strong_part(gm: GroundMotion, seconds: float, lead_s: float = 3.0) -> GroundMotion:
    """``seconds`` of ``gm`` from ``lead_s`` before its peak."""
    start = max(0, int(np.argmax(np.abs(gm.acc))) - int(round(lead_s / gm.dt)))
    stop = start + int(round(seconds / gm.dt)) + 1
    return GroundMotion(dt=gm.dt, acc=gm.acc[start:stop], name=gm.name, source=gm.source)


def _errors(b, truth) -> np.ndarray:
    """``(parameter, story)`` relative errors [%]."""
    return np.array([100.0 * (getattr(b, k) / getattr(truth, k) - 1.0) for k in PARAMS])


def simulated_case(truth, motions: list[GroundMotion], seed: int, cfg: IdentifyConfig, noise: float, log) -> tuple:
    """Joint clone of three events against each single-event clone, its carried eta and its
    prediction of the fourth against the true building's."""
    meas, states = simulate_events(truth, motions, noise_rms=noise, seed=seed)
    t = time.perf_counter()
    joint = identify_clone(meas[:3], cfg).clone
    seconds = {"joint": time.perf_counter() - t}
    singles: list[dict] = []
    for m in meas[:3]:
        t = time.perf_counter()
        try:
            b = identify_clone(m, cfg).clone.building
        except InputError as err:
            singles.append({"event": m.name, "failed": str(err)})
            continue
        e = _errors(b, truth)
        singles.append({"event": m.name, "mean_pct": float(np.mean(np.abs(e))), "worst_pct": float(np.max(np.abs(e))),
                        "errors_pct": e.tolist(), "seconds": time.perf_counter() - t})
    e = _errors(joint.building, truth)
    ok = [s for s in singles if "failed" not in s]
    best = min(ok, key=lambda s: s["mean_pct"]) if ok else None
    assert joint.state is not None
    eta_clone, eta_true = joint.state.eta(joint.building), states[2].eta(truth)
    band = cfg.hla
    pred = predict_event(joint, meas[3], hla_config=band)
    ref = predict_event(Clone(building=truth, state=states[2]), meas[3], hla_config=band)
    row = {"records": [m.name for m in motions], "seed": seed, "seconds": seconds,
           "joint": {"mean_pct": float(np.mean(np.abs(e))), "worst_pct": float(np.max(np.abs(e))),
                     "errors_pct": e.tolist()},
           "singles": singles, "best_single": None if best is None else best["event"],
           "eta_clone": eta_clone.tolist(), "eta_true": eta_true.tolist(),
           "eta_error_pct": (100.0 * (eta_clone / eta_true - 1.0)).tolist(),
           "prediction": {"r": pred.r.tolist(), "r_mean": pred.r_mean,
                          "r_true": None if pred.r_true is None else pred.r_true.tolist(),
                          "band_hz": list(pred.band_hz), "peak_drift_error": pred.peak_drift_error.tolist(),
                          "drift_r": pred.drift_r.tolist(), "start": pred.start, "start_reason": pred.start_reason},
           "truth_replay": {"r": ref.r.tolist(), "r_mean": ref.r_mean}}
    log(f"simulated {motions[0].name}.. seed {seed}: joint mean {row['joint']['mean_pct']:.1f} %, best single "
        f"{best['mean_pct'] if best else float('nan'):.1f} %, R {pred.r_mean:.3f} (truth {ref.r_mean:.3f})")
    return row, pred


def simulated_part(args, figures: Path, log) -> dict:
    truth = load_simulation_config(args.sim_building).building.build()
    cfg = load_config(args.sim_config, IdentifyConfig) if args.sim_config else IdentifyConfig()
    pgas = [float(x) for x in args.pgas.split(",")]
    if len(pgas) != 4:
        raise InputError(f"--pgas {args.pgas}: expected 4 PGAs [g] (three events and the predicted one)")
    rows = []
    for s, names in enumerate(RECORD_SETS):
        motions = [strong_part(load_builtin(n).scaled_to_pga(g), args.sim_seconds) for n, g in zip(names, pgas)]
        for seed in args.seeds:
            row, pred = simulated_case(truth, motions, seed, cfg, args.noise, log)
            rows.append(row)
            if seed == args.seeds[0]:
                title = f"Table 1 building: joint clone of {', '.join(names[:3])} (seed {seed}) predicts {names[3]}"
                save_figure(plot_prediction(pred, title=title), figures / f"simulated_set{s + 1}.png", dpi=72)
    return {"building": args.sim_building, "pgas_g": pgas, "noise_rms": args.noise, "seconds_per_record":
            args.sim_seconds, "cases": rows}


def peer_history(path: str | None) -> dict:
    """The linear peer's predictions of the next event from events 1..k, by (structure, k, event)."""
    if not path:
        return {}
    try:
        cases = json.loads(Path(path).read_text())["cases"]
        out = {}
        for c in cases:
            if c["kind"] in ("history", "alone"):
                key = (c["structure"], tuple(c["identified_on"]), c["event"])
                if c["kind"] == "history" or len(c["identified_on"]) == 1:
                    pde = c["prediction"].get("peak_drift_error")
                    out[key] = {"r_mean": c["prediction"]["r_mean"], "chosen": c["chosen"], "peak_drift_error": pde,
                                "drift_r": c["prediction"].get("drift_r"),
                                "oracle_r_mean": c["oracle_prediction"]["r_mean"] if c["n_grid"] > 1 else None}
        return out
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise InputError(f"expected a peer.json of scripts/study_linear_peer.py: {err}", source=path) from None


def _f(x, fmt="{:.3f}") -> str:
    return "-" if x is None else fmt.format(x)


def _summary(rs: list[float]) -> str:
    return f"{np.mean(rs):.3f} | {np.min(rs):.3f}" if rs else "- | -"


def _pde(e) -> str:
    return "-" if not e else " / ".join(f"{100 * x:+.0f}" for x in e)


def _mean(x) -> float | None:
    return None if not x else float(np.mean(x))


def _wide(w) -> str:
    """A prediction's wide-band figures, one cell."""
    if not w:
        return "-"
    lo, hi = w["band_hz"]
    return f"{lo:g}-{hi:g} Hz, {w['drift_r_mean']:.3f}, {_pde(w['peak_drift_error'])}"


def _abs_pde(e) -> float:
    return float(np.mean(np.abs(e))) if e else float("nan")


def real_tables(res: dict, peer: dict, command: str) -> list[str]:
    name = res["structure"]
    out = [f"### {name}: clone of events 1..k predicting k+1", "", f"`{command}`", "",
           f"Band {res['band_hz'] or 'HLA'} Hz, system {res['identify']['system']}, refinement "
           f"{res['identify']['refine']}; R: floor displacement relative to the ground, drift R: story drift "
           "(correlation of predicted and measured in the band); peak-drift error: predicted / measured - 1 of each "
           "story's peak drift in the band; coverage: share of the measurement inside the "
           f"{res['n_ensemble']}-clone 90 % band (carried start). The peer: the linear peer (self-fit) identified on "
           "the same events.", "",
           "Wide band: the same clone's replay in the band the event's floor records hold (its band in Hz, "
           "mean drift R, peak-drift error per story).", "",
           "| clone | on | predicts | start | R per floor | R mean | drift R mean | peak-drift error [%] "
           "| mean abs [%] | wide band: band, drift R, peak-drift error [%] | coverage | clone [s] | peer R "
           "| peer peak-drift error [%] |", "|" + "---|" * 14]
    for p in res["predictions"]:
        pr = peer.get((name, tuple(p["identified_on"]), p["event"]))
        on = p["identified_on"]
        start = p["start"] if p["start"] != "auto" else f"auto: {p['resolved']}"
        out.append(f"| {p['how']} | {on[0] if len(on) == 1 else f'{on[0]}..{on[-1]}'} | {p['event']} | {start} | "
                   + " / ".join(f"{r:.3f}" for r in p["r"]) + f" | **{p['r_mean']:.3f}** | "
                   f"{_f(p.get('drift_r_mean'))} | {_pde(p['peak_drift_error'])} | "
                   f"{100 * _abs_pde(p['peak_drift_error']):.1f} | {_wide(p.get('wide'))} | "
                   f"{_f(p['coverage_mean'], '{:.2f}')} | {p['clone_seconds']:.0f} | "
                   f"{_f(pr and pr['r_mean'])} | {_pde(pr and pr.get('peak_drift_error'))} |")
    out += ["", "| clone | start | n | mean R | worst R | mean drift R | mean abs peak-drift error [%] | worst story "
            "[%] | wide band: mean drift R, mean abs / worst story peak-drift error [%] | mean coverage | peer mean R "
            "| peer worst R | peer mean abs peak-drift error [%] | peer worst story [%] |", "|" + "---|" * 14]
    for how in dict.fromkeys(p["how"] for p in res["predictions"]):
        for start in START_STATES:
            ps = [p for p in res["predictions"] if p["how"] == how and p["start"] == start]
            if not ps:
                continue
            cov = [p["coverage_mean"] for p in ps if p["coverage_mean"] is not None]
            prs = [peer[k] for p in ps if (k := (name, tuple(p["identified_on"]), p["event"])) in peer]
            pde = np.abs([e for p in ps for e in p["peak_drift_error"]])
            ppde = np.abs([e for q in prs for e in (q.get("peak_drift_error") or [])])
            full = len(prs) == len(ps)
            peer_pde = f"{100 * np.mean(ppde):.1f} | {100 * np.max(ppde):.1f}" if full and ppde.size else "- | -"
            dr = [p["drift_r_mean"] for p in ps if p.get("drift_r_mean") is not None]
            ws = [p["wide"] for p in ps if p.get("wide")]
            wpde = np.abs([e for w in ws for e in w["peak_drift_error"]])
            wide = (f"{np.mean([w['drift_r_mean'] for w in ws]):.3f}, {100 * np.mean(wpde):.1f} / "
                    f"{100 * np.max(wpde):.1f}" if ws and wpde.size else "-")
            out.append(f"| {how} | {start} | {len(ps)} | {_summary([p['r_mean'] for p in ps])} | "
                       f"{_f(np.mean(dr) if dr else None)} | {100 * np.mean(pde):.1f} | {100 * np.max(pde):.1f} | "
                       f"{wide} | "
                       f"{_f(np.mean(cov) if cov else None, '{:.2f}')} | "
                       f"{_summary([q['r_mean'] for q in prs]) if full else '- | -'} | "
                       f"{peer_pde} |")
    if res["agreement"]:
        out += ["", f"Sequential against joint clone of the same events: share of parameters with |difference| <= "
                f"{AGREE_SD:g} combined sd (posterior, transformed units).", "",
                "| events | share | median z | max z (parameter) |", "|---|---|---|---|"]
        for a in res["agreement"]:
            worst = max(a["z"], key=a["z"].get) if a.get("z") else "-"
            out.append(f"| {a['identified_on'][0]}..{a['identified_on'][-1]} | {_f(a['share'], '{:.2f}')} | "
                       f"{_f(a.get('z_median'), '{:.2f}')} | {_f(a.get('z_max'), '{:.2f}')} ({worst}) |")
    return out + [""]


def simulated_tables(res: dict, command: str) -> list[str]:
    out = ["### simulated: Table 1 building, three events in a row, the fourth predicted", "", f"`{command}`", "",
           f"PGAs {res['pgas_g']} g, {res['seconds_per_record']:g} s from 3 s before each peak, noise "
           f"{100 * res['noise_rms']:.0f} % RMS. Errors: |relative error| over the 5 parameters x 3 stories; best "
           "single: the single-event clone of lowest mean error (chosen on the truth).", "",
           "| records | seed | joint mean / worst [%] | best single mean / worst [%] (event) | eta error [%] per story "
           "| R 4th (joint clone) | drift R 4th | peak-drift error 4th [%] | R 4th (true building) | R_true 4th "
           "| joint [s] |", "|" + "---|" * 11]
    for c in res["cases"]:
        b = next((s for s in c["singles"] if s["event"] == c["best_single"]), None)
        j = c["joint"]
        out.append(f"| {c['records'][0]}.. | {c['seed']} | {j['mean_pct']:.1f} / {j['worst_pct']:.1f} "
                   f"| {'-' if b is None else f'''{b['mean_pct']:.1f} / {b['worst_pct']:.1f} ({b['event']})'''} | "
                   + " / ".join(f"{e:+.1f}" for e in c["eta_error_pct"])
                   + f" | {c['prediction']['r_mean']:.3f} | {_f(_mean(c['prediction'].get('drift_r')))} | "
                   f"{_pde(c['prediction']['peak_drift_error'])} | {c['truth_replay']['r_mean']:.3f} | "
                   f"{_f(c['prediction']['r_true'] and np.mean(c['prediction']['r_true']))} | "
                   f"{c['seconds']['joint']:.0f} |")
    cs = res["cases"]
    best = [next(s for s in c["singles"] if s["event"] == c["best_single"]) for c in cs if c["best_single"]]
    out += ["", "| summary | mean | worst |", "|---|---|---|",
            f"| joint clone: mean parameter error [%] | {np.mean([c['joint']['mean_pct'] for c in cs]):.1f} | "
            f"{np.max([c['joint']['worst_pct'] for c in cs]):.1f} |",
            f"| best single-event clone: mean parameter error [%] | "
            f"{np.mean([s['mean_pct'] for s in best]) if best else float('nan'):.1f} | "
            f"{np.max([s['worst_pct'] for s in best]) if best else float('nan'):.1f} |",
            f"| carried eta error [%] | {np.mean([np.abs(c['eta_error_pct']) for c in cs]):.1f} | "
            f"{np.max([np.abs(c['eta_error_pct']) for c in cs]):.1f} |",
            f"| R of the 4th record, joint clone | {np.mean([c['prediction']['r_mean'] for c in cs]):.3f} | "
            f"{np.min([c['prediction']['r_mean'] for c in cs]):.3f} |",
            f"| mean abs peak-drift error of the 4th record, joint clone [%] | "
            f"{100 * np.mean([_abs_pde(c['prediction']['peak_drift_error']) for c in cs]):.1f} | "
            f"{100 * np.max([np.max(np.abs(c['prediction']['peak_drift_error'])) for c in cs]):.1f} |",
            f"| R of the 4th record, true building | {np.mean([c['truth_replay']['r_mean'] for c in cs]):.3f} | "
            f"{np.min([c['truth_replay']['r_mean'] for c in cs]):.3f} |", ""]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/validate_real.yaml", help="validation config YAML (real parts)")
    ap.add_argument("--out", default="runs/events", help="output folder (events.json, events.md, figures/)")
    ap.add_argument("--parts", default="steel,hotel,simulated", help="comma-separated: steel, hotel, simulated")
    ap.add_argument("--peer", help="peer.json of scripts/study_linear_peer.py (its history cases beside hlaid's)")
    ap.add_argument("--ensemble", type=int, default=20, help="clones drawn for the predictive band (default 20)")
    ap.add_argument("--sim-building", default="configs/poc_3story.yaml", help="simulation config of the building")
    ap.add_argument("--sim-config", default=None, help="identification settings of the simulated part (YAML)")
    ap.add_argument("--pgas", default="0.3,0.45,0.62,0.5", help="PGAs [g] of the 3 events and the predicted one")
    ap.add_argument("--sim-seconds", type=float, default=12.0, help="seconds of each record (from 3 s before its peak)")
    ap.add_argument("--seeds", default="0,1,2", help="noise seeds of the simulated part")
    ap.add_argument("--noise", type=float, default=0.10, help="RMS noise of the simulated part, a fraction")
    ap.add_argument("--force", action="store_true", help="replace the output folder")
    ap.add_argument("-q", "--quiet", action="store_true")
    args = ap.parse_args(argv)
    _progress.set_verbosity(0 if args.quiet else 1)
    t0 = time.perf_counter()
    command = "python scripts/study_events.py " + " ".join(argv if argv is not None else sys.argv[1:])

    def log(s: str) -> None:
        _progress.info(f"[events {time.perf_counter() - t0:5.0f} s] {s}")

    try:
        parts = args.parts.split(",")
        bad = [p for p in parts if p not in (*REAL_PARTS, "simulated")]
        if bad:
            raise InputError(f"--parts: unknown {bad}; expected some of {[*REAL_PARTS, 'simulated']}")
        try:
            args.seeds = [int(s) for s in args.seeds.split(",")]
        except ValueError:
            raise InputError(f"--seeds {args.seeds}: expected comma-separated integers") from None
        peer = peer_history(args.peer)
        cfg = load_validation_config(args.config) if any(p in REAL_PARTS for p in parts) else None
        specs = {} if cfg is None else {s.name: s for s in cfg.structures}
        result: dict = {"format": "hlaid-events-study", "version": 1, "command": command, "peer": args.peer}
        text = ["# Event-to-event clones", ""]
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        with atomic_directory(out, force=args.force) as tmp:
            (tmp / "figures").mkdir()
            for part in parts:
                t = time.perf_counter()
                if part == "simulated":
                    res = simulated_part(args, tmp / "figures", log)
                    text += simulated_tables(res, command)
                else:
                    name = REAL_PARTS[part]["structure"]
                    if name not in specs:
                        raise InputError(f"no structure {name!r} (part {part})", source=args.config)
                    res = real_part(cfg, specs[name], REAL_PARTS[part], args.ensemble, tmp, log)
                    text += real_tables(res, peer, command)
                res["seconds"] = time.perf_counter() - t
                result[part] = res
                text += [f"({part}: {res['seconds']:.0f} s)", ""]
            write_json(tmp / "events.json", result)
            (tmp / "events.md").write_text("\n".join(text))
    except InputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print("\n".join(text))
    log(f"wrote {args.out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
