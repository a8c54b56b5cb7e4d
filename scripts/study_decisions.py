"""Decision study: are the clones' decisions consistent with what each real building did?

    python scripts/study_decisions.py --out runs/decisions [--parts steel hotel berkeley mini]
        [--hotel-events 13 1 2 ...] [--n-ensemble 10] [--cache DIR]

Every real dataset of ``configs/validate_real.yaml`` (read as that config says; identification
settings its ``identify_config``), story heights assumed where the data do not give them (the
steel frame 1000 mm as docs/events.md suggests; the others below, each flagged by the run):

* per event, one ``hlaid run`` (:func:`hlaid.run.run_pipeline`: identification, IDA undamaged and
  from the state the event left, the ensemble assessment with the survival evidence);
* per multi-event clone (the steel frame s1..s4; the hotel's events 1..3; each mini shake-table
  model's two runs) the same from the library: :func:`hlaid.identify_clone` of the events, then
  :func:`hlaid.run_ida` (undamaged and carried) and :func:`hlaid.ida.assess` with the events as
  evidence;
* on every clone, ``hlaid predict`` (the clone's last event, its default 20-clone band) and
  ``hlaid demands`` (its last event as recorded, the default ensemble), both as commands.

The invariants, per clone: the nominal clone survives the events it was identified from with the
collapse law in force; P(collapse) at each recorded event's intensity < 0.5 (the building survived
every one); no parameter's 90 % interval wider than a factor 100; the aftershock collapse median
(from the carried state) >= 0.25 x the undamaged one; predict and demands exit 0. Writes
``decisions.json`` and ``decisions.md`` (the table, each violation listed) into ``--out`` and
prints the table. Resumable: a case whose ``case.json`` exists is read back.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from hlaid import _progress
from hlaid.clone import Clone
from hlaid.ida import IDAConfig
from hlaid.studies.validation import load_validation_config
from hlaid.studies.validation.schema import identify_config_of, read_event
from hlaid.uncertainty.config import AssessConfig

REPO = Path(__file__).resolve().parents[1]
HEIGHTS = {"steel-frame": [1000.0] * 3, "hotel": [9000.0, 9000.0], "berkeley": [10500.0, 7000.0],
           "mini-flexible": [300.0] * 3, "mini-stiff": [300.0] * 3}
"""Assumed story heights [mm]: the steel frame's as docs/events.md suggests; the hotel's two
measured levels as three 3 m stories each; the Berkeley building's 4th floor at 3 x 3.5 m and the
roof two stories above; the mini shake-table model's 300 mm stories."""

PARTS = {"steel": ["steel-frame"], "hotel": ["hotel"], "berkeley": ["berkeley"],
         "mini": ["mini-flexible", "mini-stiff"]}
MULTI = {"steel-frame": [["s1", "s2", "s3", "s4"]], "hotel": [["1", "2", "3"]],
         "mini-flexible": [["northridge", "sine1.5"]], "mini-stiff": [["northridge", "sine1.5"]]}
MAX_FACTOR = 100.0
AFTERSHOCK_RATIO = 0.25
P_SURVIVED = 0.5


def _ida_config(heights, n_levels: int) -> IDAConfig:
    return IDAConfig(records="builtin-suite", n_levels=n_levels, heights_mm=list(heights), bootstrap=200)


def _median(ida) -> float | None:
    try:
        return float(ida.collapse_fragility("capacities", n_boot=0).median)
    except ValueError:
        return None


def _widest(clone: Clone) -> tuple[float | None, str | None]:
    if clone.uncertainty is None:
        return None, None
    iv = clone.uncertainty.interval(0.9)
    ratio = {k: (hi / lo if lo > 0 else np.inf) for k, (lo, hi) in iv.items()}
    k = max(ratio, key=lambda n: ratio[n])
    return float(ratio[k]), k


def _commands(folder: Path, clone_file: Path, meas_file: Path, band, heights) -> dict:
    """``hlaid predict`` and ``hlaid demands`` with their default ensembles; exit status and the
    last line of stderr of each."""
    (folder / "ida_heights.yaml").write_text(f"heights_mm: {list(heights)}\n")
    out = {}
    for name, args in (("predict", ["predict", str(clone_file), str(meas_file), "-o", str(folder / "predict"),
                                    "--force", "--band", f"{band[0]:g}", f"{band[1]:g}"]),
                       ("demands", ["demands", str(clone_file), "--motion", str(meas_file), "--config",
                                    str(folder / "ida_heights.yaml"), "-o", str(folder / "demands.csv"), "--force"])):
        p = subprocess.run([sys.executable, "-m", "hlaid", "-q", *args], capture_output=True, text=True)
        out[name] = {"exit": p.returncode, "stderr": (p.stderr.strip().splitlines() or [""])[-1][:300]}
    return out


def single_case(spec, event: str, data_dir: str, folder: Path, args) -> dict:
    """One ``hlaid run`` of one event."""
    from hlaid.run import RunConfig, run_pipeline
    from hlaid.run.config import MeasurementSource

    ev = spec.event(event)
    heights = HEIGHTS[spec.name]
    cfg = RunConfig(name=f"{spec.name} {event}",
                    measurement=MeasurementSource(file=str(Path(data_dir) / ev.path), format=spec.reader,
                                                  options={**spec.options, **ev.options}, height_mm=heights),
                    identify=identify_config_of(spec), ida=_ida_config(heights, args.n_levels),
                    assess=AssessConfig(n_ensemble=args.n_ensemble, n_boot=20))
    run_dir = folder / "run"
    folder.mkdir(parents=True, exist_ok=True)
    s = run_pipeline(cfg, run_dir, force=True, cache_dir=args.cache)
    clone = Clone.load(run_dir / "clone.json")
    fits = [x.collapse_fit for x in (s.ida, s.ida_after)]
    return {"clone_file": str(run_dir / "clone.json"), "meas_file": str(run_dir / "measurement.npz"),
            "events": [e.to_dict() for e in s.events], "survival": s.survival.to_dict() if s.survival else None,
            "median": fits[0].median_g if fits[0] else None,
            "median_after": fits[1].median_g if fits[1] else None, "flags": list(s.flags),
            "assessment_median": s.assessment.collapse_median if s.assessment else None,
            "_clone": clone}


def multi_case(spec, events: list[str], data_dir: str, folder: Path, args) -> dict:
    """A clone of several events, assessed from the library as ``hlaid run`` would."""
    from hlaid import identify_clone
    from hlaid.ida import assess, run_ida
    from hlaid.run.decision import event_risks, run_flags

    heights = HEIGHTS[spec.name]
    meas = [dataclasses.replace(read_event(spec, e, data_dir), height=np.asarray(heights)) for e in events]
    clone = identify_clone(meas, identify_config_of(spec), cache_dir=args.cache).clone
    folder.mkdir(parents=True, exist_ok=True)
    clone.save(folder / "clone.json", force=True)
    meas[-1].save(folder / "measurement.npz", force=True)
    motions = [m.ground_motion(name=m.name) for m in meas]
    cfg = _ida_config(heights, args.n_levels)
    before = run_ida(clone, "builtin-suite", cfg, event_motions=motions)
    after = run_ida(clone, "builtin-suite", cfg.replace(start="carried"), event_motions=motions)
    a = None
    if clone.uncertainty is not None:
        a = assess(clone, "builtin-suite", n_ensemble=args.n_ensemble, ida_config=cfg, own_motion=motions[-1],
                   n_boot=20, event_motions=motions[:-1]).to_dict()
    from hlaid.events.evidence import survivors
    surv = survivors(clone, 0, prepare=lambda _: before.building, motions=motions, drift_limit=cfg.drift_limit)
    survival = {**surv.to_dict(), **((a or {}).get("survival") or {}), "nominal_survives": surv.nominal_survives,
                "nominal_collapsed_in": surv.nominal_collapsed_in}
    events = event_risks(a, before, surv.motions.available)
    flags = run_flags(clone, survival=survival, assessment=a, heights_given=heights, events=events,
                      drift_limit=cfg.drift_limit)
    return {"clone_file": str(folder / "clone.json"), "meas_file": str(folder / "measurement.npz"),
            "events": events, "survival": survival,
            "median": _median(before), "median_after": _median(after), "flags": flags,
            "assessment_median": None if a is None else a["collapse_median"], "_clone": clone}


def invariants(case: dict) -> list[str]:
    """The violations of one case, in words."""
    out = []
    surv = case.get("survival") or {}
    if surv.get("nominal_survives") is False:
        out.append(f"the clone collapses under {surv.get('nominal_collapsed_in')}")
    for e in case["events"]:
        if e.get("p_collapse") is not None and e["p_collapse"] >= P_SURVIVED:
            out.append(f"P(collapse) {e['p_collapse']:.0%} at {e['name']} (Sa {e['im']:.3g} g)")
    if case["widest"] is not None and case["widest"] > MAX_FACTOR:
        out.append(f"{case['widest_name']} interval wider than x{MAX_FACTOR:g} (x{case['widest']:.3g})")
    m, ma = case["median"], case["median_after"]
    if m and ma is not None and ma < AFTERSHOCK_RATIO * m:
        out.append(f"aftershock median {ma:.3g} g < {AFTERSHOCK_RATIO} x undamaged {m:.3g} g")
    for name in ("predict", "demands"):
        if case["commands"][name]["exit"] != 0:
            out.append(f"hlaid {name} exit {case['commands'][name]['exit']}: {case['commands'][name]['stderr']}")
    return out


def run_case(spec, events: list[str], data_dir: str, out: Path, args) -> dict:
    name = f"{spec.name}_{'+'.join(events)}"
    folder = out / name
    done = folder / "case.json"
    if done.exists():
        return json.loads(done.read_text())
    t = time.perf_counter()
    print(f"[decisions] {name} ...", flush=True)
    res = (single_case(spec, events[0], data_dir, folder, args) if len(events) == 1
           else multi_case(spec, events, data_dir, folder, args))
    clone = res.pop("_clone")
    res["widest"], res["widest_name"] = _widest(clone)
    band = tuple(spec.compare_band_hz) if spec.compare_band_hz else (0.1, 20.0)
    res["commands"] = _commands(folder, Path(res["clone_file"]), Path(res["meas_file"]), band, HEIGHTS[spec.name])
    res.update(case=name, structure=spec.name, identified_from=events, seconds=time.perf_counter() - t,
               heights_mm=HEIGHTS[spec.name], system=clone.system)
    res["violations"] = invariants(res)
    folder.mkdir(parents=True, exist_ok=True)
    done.write_text(json.dumps(res, indent=1, default=float))
    return res


def table(cases: list[dict]) -> str:
    lines = ["| clone | system | survives its events | P(collapse) at each recorded event | widest 90 % interval "
             "| collapse median undamaged / after [g] | after / undamaged | predict, demands | violations |",
             "|---|---|---|---|---|---|---|---|---|"]
    for c in cases:
        s = c.get("survival") or {}
        surv = {True: "yes", False: f"**no** ({s.get('nominal_collapsed_in')})", None: "not checked"}[
            s.get("nominal_survives")]
        if s.get("n_drawn"):
            surv += f"; {s.get('n_rejected', 0)} of {s['n_drawn']} draws rejected"
        pc = ", ".join(f"{e['name']}: {'n/a' if e.get('p_collapse') is None else format(e['p_collapse'], '.1%')}"
                       for e in c["events"]) or "n/a"
        w = "n/a" if c["widest"] is None else f"x{c['widest']:.3g} ({c['widest_name']})"
        m, ma = c["median"], c["median_after"]
        ratio = "n/a" if not (m and ma) else f"{ma / m:.2f}"
        cmds = ", ".join(str(c["commands"][k]["exit"]) for k in ("predict", "demands"))
        lines.append(f"| {c['case']} | {c.get('system') or 'none'} | {surv} | {pc} | {w} | "
                     f"{'n/a' if m is None else format(m, '.3g')} / {'n/a' if ma is None else format(ma, '.3g')} | "
                     f"{ratio} | {cmds} | {'; '.join(c['violations']) or 'none'} |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------- given clones, every command
def _cli(*args) -> tuple[int, str]:
    p = subprocess.run([sys.executable, "-m", "hlaid", *map(str, args)], capture_output=True, text=True)
    return p.returncode, p.stderr


def clone_figures(clone_file: Path, events: list[Path], heights, out: Path, n_ensemble: int | None) -> list[dict]:
    """Per recorded event (the clone's own and ``events``), both P(collapse) figures and the
    replay's residual-drift error from every command that gives them on a clone file: ``hlaid
    ida`` (both; ``--event`` the later ones), ``hlaid demands --motion`` (the own motion), ``hlaid
    loss`` of the demand CSV with the IDA's fragility (the fragility at the event's intensity,
    pelicun's sample)."""
    h = ",".join(f"{v:g}" for v in heights)
    ens = [] if n_ensemble is None else ["--ensemble", str(n_ensemble)]
    ida = out / "ida"
    later = ["--event", *events] if events else []
    rc, err = _cli("ida", clone_file, "--records", "builtin-suite", "--heights", h, *later, *ens,
                   "--no-plots", "--bootstrap", "0", "-o", ida, "--force")
    if rc:
        raise SystemExit(f"hlaid ida failed: {err.strip().splitlines()[-1]}")
    basis = json.loads((ida / "summary.json").read_text())["basis"]
    rows = {e["name"]: {"event": e["name"], "ida_fragility_at_im": e.get("p_collapse_fragility_at_im"),
                        "im_g": e.get("im")} for e in basis["events"]}
    for c in basis["own_motion"]:
        r = rows.setdefault(c["name"], {"event": c["name"]})
        err_ = c.get("residual_drift_error")
        r.update(in_clone=c["in_clone"], ida_own_motion=c.get("p_collapse_own_motion"),
                 ida_residual=c.get("residual_drift_ratio"), measured_residual=c.get("measured_residual_drift_ratio"),
                 ida_residual_error=None if err_ is None else max(abs(v) for v in err_))
    clone = Clone.load(clone_file)
    files = {str(e.name): Path(str(e.source)) for e in clone.events}
    files.update({f.name.split(".")[0]: f for f in events})
    for name, r in rows.items():
        f = files.get(name) or next((v for k, v in files.items() if name.startswith(k) or k.startswith(name)), None)
        if f is None:
            continue
        csv = out / f"demands_{name}.csv"
        rc, err = _cli("demands", clone_file, "--motion", f, "--heights", h, *ens, "-o", csv, "--force")
        if rc:
            r["demands_error"] = err.strip().splitlines()[-1]
            continue
        own = json.loads(Path(str(csv) + ".basis.json").read_text())["own_motion"][0]
        e2 = own.get("residual_drift_error")
        r.update(demands_own_motion=own.get("p_collapse_own_motion"),
                 demands_residual_error=None if e2 is None else max(abs(v) for v in e2))
        rc, err = _cli("loss", csv, "--floor-area", "100", "--collapse-from", ida, "-o", out / f"loss_{name}",
                       "--force", "--no-curve")
        if rc == 0:
            r["loss_csv_fragility_at_im"] = json.loads((out / f"loss_{name}" / "loss.json").read_text()).get(
                "p_collapse")
        else:
            r["loss_error"] = err.strip().splitlines()[-1]
    return list(rows.values())


def figures_table(label: str, rows: list[dict]) -> str:
    def p(v):
        return "n/a" if v is None else f"{100 * v:.1f} %"

    def r(v):  # a drift ratio's error, in percentage points of drift
        return "n/a" if v is None else f"{100 * v:.2f}"
    lines = ["| clone | event | identified from it | P(collapse \\| own motion): ida / demands | P(collapse \\| "
             "another record of its Sa(T1)): ida / loss (CSV) | residual drift ratio's error, worst story [%]: ida / "
             "demands |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {label} | {row['event']} | {'yes' if row.get('in_clone') else 'no'} | "
                     f"{p(row.get('ida_own_motion'))} / {p(row.get('demands_own_motion'))} | "
                     f"{p(row.get('ida_fragility_at_im'))} / {p(row.get('loss_csv_fragility_at_im'))} | "
                     f"{r(row.get('ida_residual_error'))} / {r(row.get('demands_residual_error'))} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default=str(REPO / "configs" / "validate_real.yaml"))
    ap.add_argument("--out", default="runs/decisions")
    ap.add_argument("--parts", nargs="+", choices=list(PARTS), default=list(PARTS))
    ap.add_argument("--hotel-events", nargs="+", default=None, help="the hotel's single-event runs (default: all 21)")
    ap.add_argument("--no-multi", action="store_true", help="single-event runs only")
    ap.add_argument("--n-ensemble", type=int, default=10)
    ap.add_argument("--n-levels", type=int, default=10)
    ap.add_argument("--cache", default=None, help="classifier cache folder (default ~/.cache/hlaid/svm)")
    ap.add_argument("--clones", nargs="+", type=Path, default=None,
                    help="evaluate these clone files (no identification): every command's figures at every recorded "
                         "event, the clone's own and --events")
    ap.add_argument("--events", nargs="*", type=Path, default=[], help="later recorded events of the clones' building")
    ap.add_argument("--heights", default="1000,1000,1000", help="story heights [mm] of --clones")
    ap.add_argument("--ensemble", type=int, default=None, help="ensemble of the own-motion replays (--clones)")
    ap.add_argument("--table-only", action="store_true", help="--clones: the table of the figures already computed")
    args = ap.parse_args(argv)
    _progress.set_verbosity(0)
    if args.clones:
        out = Path(args.out)
        text = []
        for c in args.clones:
            folder = out / c.stem
            folder.mkdir(parents=True, exist_ok=True)
            own = {str(e.name) for e in Clone.load(c).events}
            later = [f for f in args.events if f.name.split(".")[0] not in own]
            done = folder / "figures.json"
            if args.table_only and done.exists():
                rows = json.loads(done.read_text())
            else:
                rows = clone_figures(c, later, [float(v) for v in args.heights.split(",")], folder, args.ensemble)
                done.write_text(json.dumps(rows, indent=1))
            text.append(figures_table(c.stem, rows))
            print(text[-1], flush=True)
        (out / "figures.md").write_text("\n\n".join(text) + "\n")
        return 0
    cfg = load_validation_config(args.config)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cases = []
    for part in args.parts:
        for name in PARTS[part]:
            spec = next(s for s in cfg.structures if s.name == name)
            singles = [e.name for e in spec.events]
            if name == "hotel" and args.hotel_events:
                singles = args.hotel_events
            jobs = [[e] for e in singles] + ([] if args.no_multi else MULTI.get(name, []))
            for events in jobs:
                cases.append(run_case(spec, events, cfg.data_dir, out, args))
                print(table(cases[-1:]).splitlines()[-1], flush=True)
    text = table(cases)
    bad = [c for c in cases if c["violations"]]
    text += f"\n\n{len(cases)} clones, {len(bad)} with a violation.\n"
    (out / "decisions.md").write_text(text)
    (out / "decisions.json").write_text(json.dumps(cases, indent=1, default=float))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
