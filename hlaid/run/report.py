"""``report.html``: a self-contained page (images embedded) built from a run folder.

``hlaid report RUN_DIR`` rebuilds it from the saved results: ``summary.json``,
``figures/*.png``, ``ida/*.png`` and ``ida/summary.json``. The fields it reads are checked
first (:data:`_SUMMARY`), and a figure the run wrote must still be there: a tampered summary or a
missing figure is an :class:`~hlaid.errors.InputError` naming the field or file.
"""

from __future__ import annotations

import base64
import html
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from .._fileio import atomic_write
from .._inputs import read_bytes, read_json, read_text
from ..errors import InputError, kind_of

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;\
margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em;border-bottom:2px solid #2a6;padding-bottom:.2em}h2{font-size:1.25em;margin-top:1.6em;color:#175}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}\
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}
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
_ASSESS_FIGURE = ("figures/fragility_band.png",
                  "Collapse fragility over the ensemble of clones drawn from the identification uncertainty: "
                  "median curve and band (identification and record sampling), the measured record's intensity "
                  "marked (dashed) with P(collapse) there, coloured by the re-occupancy indicator.")
_INDICATOR_CSS = {"green": "#1e8e3e", "yellow": "#d4a000", "red": "#c5221f"}


_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _img(path: Path, source: str) -> str:
    try:
        raw = read_bytes(path)
    except InputError as err:
        raise InputError(f"cannot read figure {path.relative_to(source)} ({err})", source=source) from None
    if not raw.startswith(_PNG_MAGIC):
        raise InputError(f"figure {path.relative_to(source)} is not a PNG image", source=source)
    data = base64.b64encode(raw).decode()
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}">'


class _Null:
    """Schema wrapper: the value may also be null."""

    def __init__(self, spec):
        self.spec = spec


class _Pair:
    """Schema wrapper: a list of exactly two items."""

    def __init__(self, spec):
        self.spec = spec


_NAMES = {"num": "a number", "int": "an integer", "str": "a string", "bool": "true or false"}
_FRAG = _Null({"median_g?": _Null("num"), "beta?": _Null("num"), "median_ci_g?": _Null(_Pair(_Null("num"))),
               "beta_ci?": _Null(_Pair(_Null("num"))), "ci?": _Null("num")})
_IDA = {"intensity_measure?": {"label?": "any", "name?": "any", "period_s?": _Null("num")},
        "collapse_criteria?": {"drift_limit?": "num", "slope_ratio?": "num"},
        "records?": ["any"], "notes?": ["str"],
        "collapse_fragility?": _Null({"capacities?": _FRAG, "counts?": _FRAG}),
        "drift_limits?": _Null({"*num": {"fragility?": _FRAG}})}
_SUMMARY = {"format": "str", "name": "str", "hlaid_version": "str", "n_stories": "int",
            "mass_normalised?": _Null("bool"), "noise_rms?": _Null("num"),
            "replay": {"r_measured": ["num"], "r_true?": _Null(["num"]), "stiffness_error": ["num"]},
            "parameters": [{"parameter": "str", "story": "int", "identified": "num", "true": _Null("num"),
                            "error": _Null("num")}],
            "paper_method?": _Null([{"parameter": "str", "story": "int", "identified?": _Null("num"),
                                     "error?": _Null("num")}]),
            "outer_iterations": "int", "timings": {"*": "num"}, "ida?": _Null(_IDA), "ida_after?": _Null(_IDA),
            "assessment?": _Null({"n_ensemble": "int", "n_records": "int", "ci": "num", "im_label": "str",
                                  "collapse_median": "num", "collapse_median_band": _Pair("num"),
                                  "own_im": _Null("num"), "p_collapse": _Null("num"),
                                  "p_collapse_band": _Null(_Pair("num")), "drift_limits": ["num"],
                                  "p_exceed": ["num"], "indicator": _Null("str"), "placard": _Null("str"),
                                  "reasons": ["str"], "own_residual_drift_median?": _Null("num"),
                                  "own_peak_drift_median?": _Null("num")}),
            "loss?": _Null({"engine": "str", "system": "str", "inventory": "str", "replacement_cost": "num",
                            "replacement_time": "num", "floor_area_m2": ["num"], "assumptions": ["str"],
                            "collapse_fragility": {"median_g": _Null("num"), "beta": _Null("num"), "source": "str"},
                            "irreparable": {"median": "num", "beta": "num"}, "n_ensemble": "int",
                            "realizations": "int",
                            "recorded": _Null({"im": "num", "im_label": "str", "repair_cost_median": "num",
                                               "repair_cost_band": _Pair("num"), "repair_cost_ratio_median": "num",
                                               "repair_cost_ratio_band": _Pair("num"), "repair_cost_mean": "num",
                                               "repair_time_parallel_median": "num",
                                               "repair_time_sequential_median": "num", "p_collapse": "num",
                                               "p_irreparable": "num", "cost_unit": "str", "n_realizations": "int",
                                               "n_demand_realisations": "int"}),
                            "curve": [{"level_g": "num", "repair_cost_ratio_mean": "num", "p_collapse": "num",
                                       "p_irreparable": "num"}]})}
"""What :func:`build_report` reads from ``summary.json``: keys ending in ``?`` may be absent, a
``*`` key stands for every key (``*num``: keys that read as numbers); other keys are ignored."""


def _validate(v, spec, path: str, source: str) -> None:
    """Check a value of summary.json against :data:`_SUMMARY` (an InputError naming the field, never
    quoting its value)."""
    def bad(what):
        raise InputError(f"summary.json: field {path or 'top level'} must be {what}, got {kind_of(v)}", source=source)

    if isinstance(spec, _Null):
        if v is not None:
            _validate(v, spec.spec, path, source)
        return
    if isinstance(spec, _Pair):
        if not isinstance(v, list) or len(v) != 2:
            bad("a list of two values")
        for i, x in enumerate(v):
            _validate(x, spec.spec, f"{path}[{i}]", source)
        return
    if isinstance(spec, list):
        if not isinstance(v, list):
            bad("a list")
        for i, x in enumerate(v):
            _validate(x, spec[0], f"{path}[{i}]", source)
        return
    if isinstance(spec, dict):
        if not isinstance(v, dict):
            bad("a mapping")
        for key, sub in spec.items():
            if key.startswith("*"):
                for k, x in v.items():
                    if key == "*num":
                        try:
                            float(k)
                        except ValueError:
                            raise InputError(f"summary.json: field {path} has a key that is not a number",
                                             source=source) from None
                    _validate(x, sub, f"{path}.{k}" if path else k, source)
                continue
            name = key.rstrip("?")
            if name not in v:
                if not key.endswith("?"):
                    raise InputError(f"summary.json: field {path + '.' if path else ''}{name} is missing",
                                     source=source)
                continue
            _validate(v[name], sub, f"{path}.{name}" if path else name, source)
        return
    if spec == "any":
        return
    ok = {"num": isinstance(v, (int, float)) and not isinstance(v, bool),
          "int": isinstance(v, int) and not isinstance(v, bool),
          "str": isinstance(v, str), "bool": isinstance(v, bool)}[spec]
    if not ok:
        bad(_NAMES[spec])


def required_figures(summary: dict) -> list[str]:
    """Figures (relative paths) a run folder must hold: those of :data:`_FIGURES` under
    ``figures/``, and those under ``ida/`` when the run made an IDA."""
    out = [rel for rel, _ in _FIGURES if rel.startswith("figures/") or summary.get("ida")]
    loss = summary.get("loss") or {}
    out += (["loss/repair_cost.png"] if loss.get("recorded") else []) + (["loss/loss_curve.png"] if loss.get("curve")
                                                                          else [])
    out += ["figures/aftershock.png"] if summary.get("ida") and summary.get("ida_after") else []
    return out + ([_ASSESS_FIGURE[0]] if summary.get("assessment") else [])


def _fmt(v, pct=False):
    if v is None:
        return "&ndash;"
    return f"{v:.1%}" if pct else f"{v:.4g}"


def build_report(run_dir: str | os.PathLike) -> Path:
    """Write ``run_dir/report.html`` from the results saved there; returns its path."""
    d = Path(run_dir)
    src = str(d)
    if not d.is_dir():
        raise InputError("not found or not a folder; expected a run folder written by hlaid run or hlaid demo"
                         if not d.exists() else "is not a folder; expected a run folder", source=src)
    if not os.path.lexists(d / "summary.json"):
        raise InputError("not an hlaid run folder (no summary.json)", source=src)
    try:
        s = read_json(d / "summary.json")
    except InputError as err:
        raise InputError(f"not an hlaid run folder ({err})", source=src) from None
    if not isinstance(s, dict) or s.get("format") != "hlaid-run":
        raise InputError("summary.json is not an hlaid run summary", source=src)
    _validate(s, _SUMMARY, "", src)
    if not s["replay"]["r_measured"]:
        raise InputError("summary.json: field replay.r_measured is empty", source=src)
    for rel in required_figures(s):
        if not (d / rel).is_file():
            raise InputError(f"figure {rel} is missing; rerun hlaid run to recreate the folder", source=src)
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
    cf = _collapse_fit(s.get("ida"))
    if cf is not None and cf.get("median_g") is not None:
        label = s["ida"].get("intensity_measure", {}).get("label", "IM")
        beta = f" (beta {cf['beta']:.2f})" if cf.get("beta") is not None else ""
        kpis.append((f"median collapse {label}", f"{cf['median_g']:.3g} g{beta}"))
    asm = s.get("assessment")
    if asm and asm.get("indicator") in _INDICATOR_CSS:
        kpis.append(("re-occupancy indicator", f"<span style='color:{_INDICATOR_CSS[asm['indicator']]}'>"
                                               f"{e(asm['indicator'].upper())}</span>"))
    parts.append("<div>" + "".join(f"<span class='kpi'>{e(k)}<b>{v}</b></span>" for k, v in kpis) + "</div>")
    parts.append("<h2>Identified parameters</h2>")
    parts.append(_param_table(s))
    parts.append(f"<p>Outer iterations: {s['outer_iterations']}. Stiffness-evolution error (clone against HLA) per "
                 f"story: {', '.join(f'{v:.1%}' for v in rep['stiffness_error'])}.</p>")
    for rel, cap in _FIGURES:
        p = d / rel
        if p.exists():
            parts.append(f"<figure>{_img(p, src)}<figcaption>{e(cap)}</figcaption></figure>")
    if s.get("ida"):
        parts.append("<h2>Incremental dynamic analysis</h2>" + _ida_block(s["ida"]))
    if s.get("ida") and s.get("ida_after"):
        from .sections.aftershock import aftershock_section
        parts.append(aftershock_section(s["ida"], s["ida_after"], _img(d / "figures" / "aftershock.png", src)))
    if s.get("assessment"):
        parts.append("<h2>Collapse risk with identification uncertainty</h2>" + _assess_block(s["assessment"]))
        p = d / _ASSESS_FIGURE[0]
        parts.append(f"<figure>{_img(p, src)}<figcaption>{e(_ASSESS_FIGURE[1])}</figcaption></figure>")
    if s.get("loss"):
        from .sections.loss import LOSS_FIGURES, loss_html
        parts.append("<h2>Losses (FEMA P-58 through pelicun)</h2>" + loss_html(s["loss"]))
        for rel, cap in LOSS_FIGURES:
            if (d / rel).exists():
                parts.append(f"<figure>{_img(d / rel, src)}<figcaption>{e(cap)}</figcaption></figure>")
    t = s["timings"]
    parts.append("<h2>Run</h2><p>" + ", ".join(f"{e(k)} {v:.1f} s" for k, v in t.items()) +
                 ". Files: <code>clone.json</code>, <code>parameters.csv</code>, <code>hla/</code>, "
                 "<code>ida/</code>, <code>tensorboard/</code>.</p></body></html>")
    return atomic_write(d / "report.html", lambda tmp: tmp.write_text("\n".join(parts)))


def _param_table(s: dict) -> str:
    rows = s["parameters"]
    paper = {(r["parameter"], r["story"]): r for r in s.get("paper_method") or []}
    has_truth = any(r["true"] is not None for r in rows)
    has_iv = any(r.get("lo90") is not None for r in rows)
    head = "<tr><th class='l'>parameter</th><th>story</th><th>identified</th>"
    head += "<th>90 % interval</th>" if has_iv else ""
    head += "<th>true</th><th>error</th>" if has_truth else ""
    head += "<th>paper method alone</th>" + ("<th>its error</th>" if has_truth else "") + "</tr>"
    body = []
    for r in rows:
        pr = paper.get((r["parameter"], r["story"]), {})
        cells = [f"<td class='l'>{html.escape(r['parameter'])}</td><td>{r['story']}</td>"
                 f"<td>{_fmt(r['identified'])}</td>"]
        if has_iv:
            lo, hi = r.get("lo90"), r.get("hi90")
            cells.append("<td>&ndash;</td>" if not isinstance(lo, (int, float)) or not isinstance(hi, (int, float))
                         else f"<td>{_fmt(lo)} &ndash; {_fmt(hi)}</td>")
        if has_truth:
            cls = "ok" if r["error"] is not None and r["error"] <= 0.03 else "bad"
            cells.append(f"<td>{_fmt(r['true'])}</td><td class='{cls}'>{_fmt(r['error'], True)}</td>")
        cells.append(f"<td>{_fmt(pr.get('identified'))}</td>")
        if has_truth:
            cells.append(f"<td>{_fmt(pr.get('error'), True)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return "<table>" + head + "".join(body) + "</table>"


def _assess_block(a: dict) -> str:
    """The ensemble assessment: indicator, P(collapse) and drift exceedance at the measured record."""
    e = html.escape
    lo, hi = a["collapse_median_band"]
    ci = f"{a['ci']:.0%}"
    out = [f"<p>IDA of {a['n_ensemble']} clones drawn from the identification uncertainty over {a['n_records']} "
           f"records. Median collapse {e(a['im_label'])}: <b>{a['collapse_median']:.3g} g</b> ({ci} band "
           f"{lo:.3g} &ndash; {hi:.3g} g).</p>"]
    if a.get("own_im") is not None and a.get("indicator") in _INDICATOR_CSS:
        colour = _INDICATOR_CSS[a["indicator"]]
        plo, phi = a["p_collapse_band"]
        out.append(f"<p style='font-size:1.15em'><span style='display:inline-block;padding:.3em .8em;border-radius:5px;"
                   f"background:{colour};color:white;font-weight:bold'>{e(a['indicator'].upper())}</span> "
                   f"{e(a.get('placard') or '')}</p>")
        rows = [f"<tr><td class='l'>collapse</td><td>{_fmt(a['p_collapse'], True)}</td>"
                f"<td>{_fmt(plo, True)} &ndash; {_fmt(phi, True)}</td></tr>"]
        for lim, p, band in zip(a["drift_limits"], a["p_exceed"], a.get("p_exceed_band") or []):
            rows.append(f"<tr><td class='l'>peak drift ratio &gt; {lim:.1%}</td><td>{_fmt(p, True)}</td>"
                        f"<td>{_fmt(band[0], True)} &ndash; {_fmt(band[1], True)}</td></tr>")
        out.append(f"<p>At the measured record's intensity, {e(a['im_label'])} = {a['own_im']:.3g} g:</p>"
                   f"<table><tr><th class='l'>event</th><th>probability</th><th>{ci} band</th></tr>"
                   + "".join(rows) + "</table>")
        if a.get("own_residual_drift_median") is not None:
            out.append(f"<p>The clones under the measured record: median peak drift ratio "
                       f"{_fmt(a.get('own_peak_drift_median'), True)}, residual "
                       f"{_fmt(a['own_residual_drift_median'], True)}."
                       "</p>")
        out.append("<ul>" + "".join(f"<li>{e(r)}</li>" for r in a["reasons"]) + "</ul>")
        out.append("<p>Indicator (assumptions, docs/uncertainty.md): the worse of P(collapse) at the experienced "
                   "intensity (red &ge; 10 %, ASCE 7-16's target at MCE<sub>R</sub>; yellow &ge; 2 %) and the residual "
                   "drift ratio (red &ge; 1 %, yellow &ge; 0.5 %: FEMA P-58 residual-drift damage states DS3, DS2), "
                   "each at the upper end of the ensemble; placards after ATC-20. The clones are undamaged at the "
                   "start of each IDA.</p>")
    return "".join(out)


def _collapse_fit(ida: dict | None) -> dict | None:
    """The collapse fragility fit (collapse capacities, else counts), or None."""
    cf = (ida or {}).get("collapse_fragility") or {}
    return cf.get("capacities") or cf.get("counts")


def _ida_block(ida: dict) -> str:
    e = html.escape
    im = ida.get("intensity_measure", {})
    crit = ida.get("collapse_criteria", {})
    period = f" at T1 = {im['period_s']:.3f} s" if im.get("period_s") else ""
    label = e(str(im.get("label", im.get("name", "?"))))
    head = (f"<p>Intensity measure {label}{period}; EDP: {e(str(ida.get('edp')))}; "
            f"collapse when a story's drift ratio exceeds {crit.get('drift_limit', 0):.0%} or the IDA slope falls "
            f"below {crit.get('slope_ratio', 0):.0%} of the elastic slope; {ida.get('n_runs', '?')} analyses of "
            f"{len(ida.get('records', []))} records.</p>")
    rows = []
    cf = _collapse_fit(ida)
    if cf is not None:
        rows.append(("collapse", cf))
    for lim, d in sorted((ida.get("drift_limits") or {}).items(), key=lambda kv: float(kv[0])):
        if d.get("fragility"):
            rows.append((f"drift ratio > {float(lim):.1%}", d["fragility"]))
    if not rows:
        return head
    tab = ["<table><tr><th class='l'>limit state</th><th>median [g]</th><th>median interval [g]</th><th>beta</th>"
           "<th>beta interval</th><th>records (censored)</th></tr>"]
    for name, f in rows:
        mci, bci = f.get("median_ci_g") or [None, None], f.get("beta_ci") or [None, None]
        tab.append(f"<tr><td class='l'>{e(name)}</td><td>{_fmt(f.get('median_g'))}</td>"
                   f"<td>{_fmt(mci[0])} &ndash; {_fmt(mci[1])}</td><td>{_fmt(f.get('beta'))}</td>"
                   f"<td>{_fmt(bci[0])} &ndash; {_fmt(bci[1])}</td>"
                   f"<td>{f.get('n_records')} ({f.get('n_censored', 0)})</td></tr>")
    ci = next((f.get("ci") for _, f in rows if f.get("ci")), None)
    tab.append("</table>" + (f"<p>Intervals: {ci:.0%} bootstrap.</p>" if ci else ""))
    notes = "".join(f"<li>{e(n)}</li>" for n in ida.get("notes", []))
    return head + "".join(tab) + (f"<ul>{notes}</ul>" if notes else "")


_BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def embedded_figures(report: str | os.PathLike) -> list[tuple[str, int]]:
    """``(alt, bytes)`` of every PNG embedded in a report; raises if one is not a valid PNG."""
    text = read_text(report)
    out = []
    for alt, data in re.findall(r'<img alt="([^"]*)" src="data:image/png;base64,([^"]+)">', text):
        raw = base64.b64decode(data)
        if not raw.startswith(b"\x89PNG\r\n\x1a\n"):
            raise InputError(f"figure {alt} is not a PNG", source=str(report))
        out.append((alt, len(raw)))
    return out


def screenshot(report: str | os.PathLike, png: str | os.PathLike, *, browser: str | None = None,
               width: int = 1200, height: int | None = None, timeout: float = 120.0) -> Path:
    """Render ``report`` in a headless Chromium and save a full-page screenshot to ``png``.

    ``height`` defaults to 900 px per embedded figure (the page is rendered in one tall window).
    Raises :class:`InputError` when no browser is found or it fails.
    """
    exe = shutil.which(browser) if browser else next((shutil.which(b) for b in _BROWSERS if shutil.which(b)), None)
    if exe is None:
        raise InputError("no headless browser found (install Debian's chromium package, or pass browser=)",
                         source=str(report))
    report, png = Path(report).resolve(), Path(png).resolve()
    height = height or 900 * max(read_text(report).count("<img "), 1) + 1200
    with tempfile.TemporaryDirectory() as profile:
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--user-data-dir={profile}",
               f"--window-size={width},{height}", f"--screenshot={png}", report.as_uri()]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or not png.exists():
        tail = (proc.stderr or "").strip().splitlines()[-1:] or [f"exit status {proc.returncode}"]
        raise InputError(f"{Path(exe).name} could not render the report: {tail[0]}", source=str(report))
    return png
