"""The linear peer (mdof's OKID-ERA / SRIM) on the real records, side by side with hlaid's clones.

    python scripts/study_linear_peer.py --out runs/peer [--hlaid runs/validation/validation.json] \\
        [--structures steel-frame,hotel] [--force]

Needs the optional study dependency mdof (``pip install hlaid[peer]``). For each structure, in
the events' time order (steel frame: s1..s4, the config's order; hotel: event numbers 1..21):

* **alone**: the peer identified on event k predicts event k+1 (steel frame: every other run,
  the 12 cross-event pairs);
* **history**: identified on events 1..k (joined, ``hlaid.studies.validation.linear_peer``)
  predicting event k+1 (steel frame k = 1..3, hotel k >= 3);
* hotel: **from 13**, one peer from the strongest event predicting the other 20.

The peer's settings are a grid (methods, orders, horizons, OKID rcond, decimation). Each case
reports the grid point chosen by the self-fit on its identification events (all a user has)
and, apart, the oracle (best on the prediction itself: the peer's ceiling). On the hotel the
joined records are long (up to 60 000 samples), so the grid is searched on events 1..3 and its
self-fit choice is kept for every later k (the oracle only where the full grid ran).

Writes ``peer.json``, ``peer.md`` and ``figures/*.png`` (measured against peer-predicted
displacement of every next event) into ``--out`` (new, or replaced with ``--force``). With
``--hlaid`` (a ``validation.json`` of scripts/validate_real.py, or any JSON whose
``predictions`` hold ``structure``, ``identified_from``, ``event``, ``r``, ``peak_drift_error``)
hlaid's clone stands beside each prediction.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing
import sys
import time
import warnings
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from hlaid import _progress
from hlaid._fileio import atomic_directory, atomic_write, write_json
from hlaid.errors import InputError
from hlaid.hla import resolve_hla
from hlaid.plots import plot_measured_predicted, save_figure
from hlaid.studies.validation import identify_config_of, load_validation_config, read_event
from hlaid.studies.validation.linear_peer import PeerCase, compared_band, max_decimation, peer_cases, peer_grid

DECIMATIONS = (1, 2, 4, 8)
"""Decimations tried: the two largest that keep the compared band under the analysis corner."""

SEARCH_ON_FIRST = {"hotel": 3}
"""Structures whose grid is searched on their first events only (how many), then kept."""

ALSO_FROM = {"hotel": "13"}
"""A single-event peer predicting every other event (the validation's hotel clone)."""


def _events(spec) -> list[str]:
    names = [e.name for e in spec.events]
    return sorted(names, key=int) if all(n.isdigit() for n in names) else names


def run_structure(cfg, spec, grid_options: dict, mapper, log) -> list[tuple[str, PeerCase]]:
    """Every case of one structure, as ``(kind, case)`` with kind ``alone``, ``history`` or ``from``."""
    icfg = identify_config_of(spec, source=cfg.source)
    order = _events(spec)
    meas = {n: read_event(spec, n, cfg.data_dir) for n in order}
    hla_cfg = resolve_hla(list(meas.values()), icfg.hla).config  # its "auto" settings, from the events
    if spec.compare_band_hz is not None:
        hla_cfg = dataclasses.replace(hla_cfg, preprocess=dataclasses.replace(hla_cfg.preprocess,
                                                                             band_hz=tuple(spec.compare_band_hz)))

    m0 = meas[order[0]]
    dmax = max_decimation(m0.dt, compared_band(m0, hla_cfg))
    grid = peer_grid(decimations=[d for d in DECIMATIONS if d <= dmax][-2:], **grid_options)

    def cases(train, targets, g, tag):
        log(f"{spec.name}: {tag}: {len(g)} settings on {', '.join(train)} -> {', '.join(targets)}")
        return peer_cases(spec.name, [(n, meas[n]) for n in train], [(n, meas[n]) for n in targets], g, hla_cfg,
                          mapper=mapper)

    out: list[tuple[str, PeerCase]] = []
    first = SEARCH_ON_FIRST.get(spec.name)
    if first is None:
        for k, src in enumerate(order):
            out += [("alone", c) for c in cases([src], [n for n in order if n != src], grid, "alone")]
            if k >= 1 and k + 1 < len(order):
                out += [("history", c) for c in cases(order[:k + 1], [order[k + 1]], grid, "history")]
    else:
        searched = cases(order[:first], [order[first]], grid, "grid search")
        out += [("history", c) for c in searched]
        chosen = [searched[0].chosen]
        for k in range(first, len(order)):
            if k + 1 < len(order):
                out += [("history", c) for c in cases(order[:k + 1], [order[k + 1]], chosen, "history")]
        for k in range(first - 1, len(order) - 1):
            out += [("alone", c) for c in cases([order[k]], [order[k + 1]], chosen, "alone")]
    if spec.name in ALSO_FROM:
        src = ALSO_FROM[spec.name]
        out += [("from", c) for c in cases([src], [n for n in order if n != src], grid, f"from {src}")]
    return out


def _hlaid_lookup(path: str | None) -> dict:
    if not path:
        return {}
    try:
        preds = json.loads(Path(path).read_text())["predictions"]
        return {(p["structure"], str(p["identified_from"]), str(p["event"])): p for p in preds}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise InputError(f"expected a JSON with 'predictions' (structure, identified_from, event, r): {err}",
                         source=path) from None


def _hlaid_of(lookup, case: dict):
    p = lookup.get((case["structure"], case["identified_on"][-1], case["event"]))
    if p is None:  # a structure with one clone (hotel: from 13)
        srcs = {k[1] for k in lookup if k[0] == case["structure"]}
        p = lookup.get((case["structure"], next(iter(srcs)), case["event"])) if len(srcs) == 1 else None
    return p


def _next_event(case: dict, order: list[str]) -> bool:
    last = order.index(case["identified_on"][-1])
    return case["kind"] != "from" and last + 1 < len(order) and order[last + 1] == case["event"]


def _row(*cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _pcts(errors) -> str:
    return " / ".join(f"{100 * e:+.0f}" for e in errors)


def tables(cases: list[dict], lookup: dict, orders: dict[str, list[str]]) -> str:
    """Per structure: every case (``peer.json``'s) beside hlaid's clone, then means per kind
    (and for the next events, the better of alone and history, a ceiling since it is picked
    on the prediction)."""
    head = _row("kind", "identified on", "event", "PGA [g]", "peer (self-fit choice)", "self-fit R", "R per floor",
                "R mean", "peak-drift error [%]", "oracle R mean", "oracle settings", "hlaid clone", "hlaid R mean",
                "hlaid peak-drift error [%]", "better")
    out = []
    for name in dict.fromkeys(c["structure"] for c in cases):
        out += [f"### {name}", "", head, "|" + "---|" * 15]
        summary: dict[str, list[float]] = {}
        best: dict[str, float] = {}
        for c in (c for c in cases if c["structure"] == name):
            kind, p, h = c["kind"], c["prediction"], _hlaid_of(lookup, c)
            ids = c["identified_on"]
            hr = None if h is None else float(np.mean(h["r"]))
            better = "-" if hr is None else ("peer" if p["r_mean"] > hr else "hlaid")
            searched = c["n_grid"] > 1  # else the settings were chosen on earlier events: no oracle
            clone = "-" if h is None else \
                f"from {h['identified_from']} ({h.get('kind', '?')}{', self-replay' if h.get('self_replay') else ''})"
            out.append(_row(kind, ids[0] if len(ids) == 1 else f"{ids[0]}..{ids[-1]}", c["event"], f"{p['pga_g']:.3f}",
                            c["chosen"], f"{c['self_r']:.3f}", " / ".join(f"{r:.3f}" for r in p["r"]),
                            f"**{p['r_mean']:.3f}**", _pcts(p["peak_drift_error"]),
                            f"{c['oracle_prediction']['r_mean']:.3f}" if searched else "-",
                            c["oracle"] if searched else "-", clone, "-" if hr is None else f"{hr:.3f}",
                            "-" if h is None else _pcts(h["peak_drift_error"]), better))
            groups = [kind] + ([f"{kind}, next event"] if _next_event(c, orders[name]) else [])
            for g in groups:
                summary.setdefault(g, []).append(p["r_mean"])
                if searched:
                    summary.setdefault(f"{g} (oracle)", []).append(c["oracle_prediction"]["r_mean"])
                if hr is not None:
                    summary.setdefault(f"{g} (hlaid)", []).append(hr)
            if len(groups) > 1:
                best[c["event"]] = max(best.get(c["event"], -1.0), p["r_mean"])
        if best:
            summary["next event, better of alone and history"] = list(best.values())
        out += ["", "| cases | n | mean R | worst R |", "|---|---|---|---|"]
        out += [f"| {k} | {len(v)} | {np.mean(v):.3f} | {np.min(v):.3f} |" for k, v in sorted(summary.items())]
        out.append("")
    return "\n".join(out)


def plot_case(kind: str, case: PeerCase, levels=None):
    """Measured against peer-predicted displacement of one event."""
    p, ids = case.prediction, case.identified_on
    on = ", ".join(ids) if len(ids) < 4 else f"{ids[0]}..{ids[-1]}"
    return plot_measured_predicted(p.time, p.disp_measured, p.disp_predicted, p.r, label=case.chosen.label(),
                                   levels=levels, title=f"{case.structure}: linear peer ({kind}) identified on {on}, "
                                   f"prediction of {p.event} ({p.band_hz[0]:.2g}-{p.band_hz[1]:.2g} Hz)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/validate_real.yaml", help="validation config YAML")
    ap.add_argument("--out", default="runs/peer", help="output folder (peer.json, peer.md, figures/)")
    ap.add_argument("--hlaid", help="hlaid's predictions (validation.json of scripts/validate_real.py)")
    ap.add_argument("--structures", default="steel-frame,hotel", help="comma-separated structure names")
    ap.add_argument("--tables-only", action="store_true",
                    help="rewrite --out's peer.md from its peer.json (e.g. with --hlaid), running nothing")
    ap.add_argument("--orders", default="2,4,6,8,12", help="model orders of the grid")
    ap.add_argument("--horizons", default="50,100", help="OKID m / SRIM horizons of the grid [samples]")
    ap.add_argument("--rconds", default="0.001,0.003,0.01", help="OKID pseudo-inverse cut-offs of the grid")
    ap.add_argument("--jobs", type=int, default=1, help="processes evaluating the grid (default 1)")
    ap.add_argument("--force", action="store_true", help="replace the output folder")
    ap.add_argument("-q", "--quiet", action="store_true")
    args = ap.parse_args(argv)
    _progress.set_verbosity(0 if args.quiet else 1)
    t0 = time.perf_counter()
    try:
        cfg = load_validation_config(args.config)
        lookup = _hlaid_lookup(args.hlaid)
        specs = {s.name: s for s in cfg.structures}
        if args.tables_only:
            text = retable(Path(args.out), lookup, specs)
            print(text)
            return 0
        try:
            import mdof  # noqa: F401
        except ImportError:
            raise InputError("needs the optional study dependency mdof: pip install hlaid[peer]") from None
        names = args.structures.split(",")
        bad = [n for n in names if n not in specs]
        if bad:
            raise InputError(f"unknown structures {bad}; expected some of {sorted(specs)}", source=args.config)
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        try:
            grid_options = {"orders": [int(x) for x in args.orders.split(",")],
                            "horizons": [int(x) for x in args.horizons.split(",")],
                            "rconds": [float(x) for x in args.rconds.split(",")]}
        except ValueError as err:
            raise InputError(f"--orders/--horizons/--rconds: {err}; expected comma-separated numbers") from None
        pool = multiprocessing.get_context("fork").Pool(args.jobs, initializer=_quiet) if args.jobs > 1 else None
        with atomic_directory(out, force=args.force) as tmp, warnings.catch_warnings(), pool or nullcontext():
            _quiet()
            mapper = pool.imap if pool is not None else map
            results = {n: run_structure(cfg, specs[n], grid_options, mapper, lambda s: _progress.info(f"[peer] {s}"))
                       for n in names}
            cases = [{"kind": k, **c.summary()} for rows in results.values() for k, c in rows]
            write_json(tmp / "peer.json", {"format": "hlaid-linear-peer", "version": 1, "mdof": _mdof_version(),
                                           "seconds": time.perf_counter() - t0, "cases": cases})
            text = tables(cases, lookup, {n: _events(specs[n]) for n in results})
            (tmp / "peer.md").write_text(text)
            (tmp / "figures").mkdir()
            for n, rows in results.items():
                order = _events(specs[n])
                for kind, c in rows:
                    if _next_event({"kind": kind, **c.summary()}, order):
                        tag = f"{n}_{kind}_{c.identified_on[-1]}_to_{c.prediction.event}".replace(".", "p")
                        save_figure(plot_case(kind, c, specs[n].levels), tmp / "figures" / f"{tag}.png", dpi=72)
    except InputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(text)
    _progress.info(f"wrote {out}/ in {time.perf_counter() - t0:.0f} s")
    return 0


def _quiet() -> None:
    warnings.simplefilter("ignore")  # mdof warns on every ill-conditioned grid point


def retable(out: Path, lookup: dict, specs: dict) -> str:
    """``out/peer.md`` rewritten from ``out/peer.json`` (atomically)."""
    try:
        cases = json.loads((out / "peer.json").read_text())["cases"]
        text = tables(cases, lookup, {n: _events(specs[n]) for n in dict.fromkeys(c["structure"] for c in cases)})
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise InputError(f"expected the peer.json of a run of this script: {err}", source=str(out / "peer.json")) \
            from None
    atomic_write(out / "peer.md", lambda tmp: tmp.write_text(text))
    return text


def _mdof_version() -> str:
    from importlib.metadata import version

    return version("mdof")


if __name__ == "__main__":
    sys.exit(main())
