"""``report.html``: a self-contained page (images embedded) built from a run folder.

``hlaid report RUN_DIR`` rebuilds it from the saved results: ``summary.json``,
``figures/*.png``, ``ida/*.png`` and ``ida/summary.json``.
"""

from __future__ import annotations

import base64
import html
import json
import os
from pathlib import Path

from ._fileio import atomic_write
from .errors import InputError

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em;border-bottom:2px solid #2a6;padding-bottom:.2em}h2{font-size:1.25em;margin-top:1.6em;color:#175}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#eef6f0}td.l,th.l{text-align:left}.ok{color:#176d2c}.bad{color:#b3261e}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:.9em;color:#555}
.kpi{display:inline-block;margin:.3em 1em .3em 0;padding:.5em .8em;background:#f4f8f5;border-radius:6px}
.kpi b{font-size:1.3em;display:block}
"""

_FIGURES = [
    ("figures/loops.png", "Story restoring force against inter-story drift (HLA), each half cycle in its own colour."),
    ("figures/stiffness.png", "Stiffness evolution: HLA elastic stiffness ke(t) per half cycle against the clone's "
                              "(and the truth when the data were simulated)."),
    ("figures/replay.png", "Floor displacement relative to the ground: measured (doubly integrated, band-passed) "
                           "against the clone replayed on the measured ground motion, with R per floor."),
    ("ida/ida_curves.png", "IDA curves of the clone: each record, and the 16/50/84 % fractiles."),
    ("ida/fragility.png", "Collapse fragility: lognormal fit by maximum likelihood with its bootstrap band."),
    ("ida/exceedance.png", "Probability of exceeding drift-ratio limits against intensity."),
]


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}">'


def _fmt(v, pct=False):
    if v is None:
        return "&ndash;"
    return f"{v:.1%}" if pct else f"{v:.4g}"


def build_report(run_dir: str | os.PathLike) -> Path:
    """Write ``run_dir/report.html`` from the results saved there; returns its path."""
    d = Path(run_dir)
    try:
        s = json.loads((d / "summary.json").read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise InputError(f"not an hlaid run folder (summary.json: {err})", source=str(d)) from None
    if s.get("format") != "hlaid-run":
        raise InputError("summary.json is not an hlaid run summary", source=str(d))
    e = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(s['name'])}</title>"
             f"<style>{_CSS}</style></head><body>",
             f"<h1>{e(s['name'])}: digital clone and collapse risk</h1>",
             f"<p>Source: <code>{e(str(s.get('source')))}</code>, {s['n_stories']} stories"
             + (", masses unknown: mass-normalised clone" if s.get("mass_normalised") else "")
             + (f", simulated with {s['noise_rms']:.0%} RMS noise" if s.get("noise_rms") else "")
             + f". hlaid {e(s['hlaid_version'])}.</p>"]
    rep = s["replay"]
    r = rep["r_measured"]
    kpis = [("min R, measured vs replayed", f"{min(r):.3f}")]
    if rep.get("r_true"):
        kpis.append(("min R, true vs replayed", f"{min(rep['r_true']):.4f}"))
    errs = [row["error"] for row in s["parameters"] if row["error"] is not None and row["parameter"] != "k0"]
    if errs:
        kpis.append(("parameter error, mean / worst", f"{sum(errs) / len(errs):.1%} / {max(errs):.1%}"))
    if s.get("ida") and s["ida"].get("collapse_fragility"):
        cf = s["ida"]["collapse_fragility"]
        med = cf.get("median")
        if med is not None:
            kpis.append((f"median collapse {s['ida'].get('im_label', 'IM')}", f"{med:.3g} g"))
    parts.append("<div>" + "".join(f"<span class='kpi'>{e(k)}<b>{v}</b></span>" for k, v in kpis) + "</div>")
    parts.append("<h2>Identified parameters</h2>")
    parts.append(_param_table(s))
    parts.append(f"<p>Outer iterations: {s['outer_iterations']}. Stiffness-evolution error (clone against HLA) per "
                 f"story: {', '.join(f'{v:.1%}' for v in rep['stiffness_error'])}.</p>")
    for rel, cap in _FIGURES:
        p = d / rel
        if p.exists():
            parts.append(f"<figure>{_img(p)}<figcaption>{e(cap)}</figcaption></figure>")
    if s.get("ida"):
        parts.append("<h2>Incremental dynamic analysis</h2>" + _ida_block(s["ida"]))
    t = s["timings"]
    parts.append("<h2>Run</h2><p>" + ", ".join(f"{e(k)} {v:.1f} s" for k, v in t.items()) +
                 ". Files: <code>clone.json</code>, <code>parameters.csv</code>, <code>hla/</code>, "
                 "<code>ida/</code>, <code>tensorboard/</code>.</p></body></html>")
    return atomic_write(d / "report.html", lambda tmp: tmp.write_text("\n".join(parts)))


def _param_table(s: dict) -> str:
    rows = s["parameters"]
    paper = {(r["parameter"], r["story"]): r for r in s.get("paper_method", [])}
    has_truth = any(r["true"] is not None for r in rows)
    head = "<tr><th class='l'>parameter</th><th>story</th><th>identified</th>"
    head += "<th>true</th><th>error</th>" if has_truth else ""
    head += "<th>paper method alone</th>" + ("<th>its error</th>" if has_truth else "") + "</tr>"
    body = []
    for r in rows:
        pr = paper.get((r["parameter"], r["story"]), {})
        cells = [f"<td class='l'>{r['parameter']}</td><td>{r['story']}</td><td>{_fmt(r['identified'])}</td>"]
        if has_truth:
            cls = "ok" if r["error"] is not None and r["error"] <= 0.03 else "bad"
            cells.append(f"<td>{_fmt(r['true'])}</td><td class='{cls}'>{_fmt(r['error'], True)}</td>")
        cells.append(f"<td>{_fmt(pr.get('identified'))}</td>")
        if has_truth:
            cells.append(f"<td>{_fmt(pr.get('error'), True)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return "<table>" + head + "".join(body) + "</table>"


def _ida_block(ida: dict) -> str:
    cf = ida.get("collapse_fragility") or {}
    items = []
    for k in ("im_label", "n_records", "period"):
        if k in ida:
            items.append(f"{k.replace('_', ' ')}: {ida[k]}")
    if cf:
        items.append("collapse fragility: " + ", ".join(f"{k} {v:.3g}" if isinstance(v, (int, float)) else f"{k} {v}"
                                                        for k, v in cf.items() if not isinstance(v, (list, dict))))
    return "<p>" + html.escape("; ".join(items)) + "</p>"
