"""The fleet's outputs: one table (CSV, and Parquet when pyarrow is installed) and a map-free
portfolio report (``report.html``: the buildings ranked by risk, failures with their reason, plots).

Ranking: probability of collapse at the building's own intensity (highest first), then the
ratio of the median collapse intensity to the own intensity (lowest first); failed units last.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import math
from pathlib import Path

import numpy as np

from .._fileio import atomic_write

LEADING = ["rank", "building", "event", "status", "reason", "indicator", "p_collapse", "p_collapse_band_lo",
           "p_collapse_band_hi", "own_im", "collapse_median", "collapse_median_band_lo", "collapse_median_band_hi",
           "beta", "ensemble", "engine",
           "n_stories", "T1_s", "replay_r_min", "identify_s", "assess_s", "total_s", "total_cpu_s", "worker", "digest"]
"""Columns that come first in the table (others, e.g. ``p_exceed_0.01``, follow in order of appearance)."""

UNITS = {"own_im": "g", "collapse_median": "g", "collapse_median_band_lo": "g", "collapse_median_band_hi": "g",
         "T1_s": "s", "total_s": "s", "loss.repair_cost_median": "USD_2011",
         "loss.repair_time_parallel_median": "worker-days"}
"""The unit of a column of the report's table (probabilities, ratios, counts and R: none)."""


def header(column: str) -> str:
    """A column's header with its unit (``own_im [g]``)."""
    unit = UNITS.get(column)
    return f"{column} [{unit}]" if unit else column


LOSS_COLUMNS = ("loss.repair_cost_median", "loss.repair_cost_ratio_median", "loss.repair_cost_ratio_band_lo",
                "loss.repair_cost_ratio_band_hi", "loss.repair_time_parallel_median", "loss.p_irreparable",
                "loss.p_collapse")
"""The FEMA P-58 loss columns (a ``loss`` block in the fleet config) shown in the report's table."""

RISK_KEYS = ("p_collapse",)
CAPACITY_KEYS = ("collapse_median",)
OWN_KEYS = ("own_im",)
"""Where the ranking finds P(collapse), the median collapse IM and the own IM in a row (the
assessment's ``to_dict()`` names, flattened)."""


def _get(row: dict, keys) -> float | None:
    for k in keys:
        v = row.get(k)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            return float(v)
    return None


def risk_key(row: dict) -> tuple:
    """Sort key: ok before failed, P(collapse) descending, capacity / demand ascending."""
    if row.get("status") != "ok":
        return (1, 0.0, 0.0, row.get("building", ""), row.get("event", ""))
    p = _get(row, RISK_KEYS)
    cap, own = _get(row, CAPACITY_KEYS), _get(row, OWN_KEYS)
    margin = cap / own if cap is not None and own else math.inf
    return (0, -(p if p is not None else -1.0), margin, row.get("building", ""), row.get("event", ""))


def table_rows(results: list[dict]) -> list[dict]:
    """One flat row per unit result, ranked (``rank`` 1 is the highest risk)."""
    rows = []
    for r in results:
        t = r.get("timings", {})
        row = {"building": r["building"], "event": r["event"], "status": r["status"], "reason": r.get("reason", ""),
               **r.get("row", {}), "identify_s": t.get("identify_s"), "assess_s": t.get("assess_s"),
               "total_s": t.get("total_s"), "total_cpu_s": t.get("total_cpu_s"), "worker": r.get("worker"),
               "digest": r.get("digest")}
        rows.append(row)
    rows.sort(key=risk_key)
    for i, row in enumerate(rows):
        row["rank"] = i + 1
    return rows


def columns(rows: list[dict]) -> list[str]:
    seen = {k: None for k in LEADING if any(k in r for r in rows)}
    for r in rows:
        for k in r:
            seen.setdefault(k, None)
    return list(seen)


def write_table(rows: list[dict], out: Path) -> list[Path]:
    """``results.csv`` (and ``results.parquet`` with pyarrow) in ``out``; returns the paths written."""
    cols = columns(rows)

    def w(tmp: Path):
        with open(tmp, "w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=cols, lineterminator="\n")
            wr.writeheader()
            for r in rows:
                wr.writerow({k: _cell(r.get(k)) for k in cols})
    written = [atomic_write(out / "results.csv", w)]
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:  # a table of an earlier run (with pyarrow) would now be stale
        (out / "results.parquet").unlink(missing_ok=True)
        return written
    data = {k: [r.get(k) for r in rows] for k in cols}
    table = pa.table({k: pa.array(v, from_pandas=True) if _uniform(v) else pa.array([_cell(x) for x in v])
                      for k, v in data.items()})
    written.append(atomic_write(out / "results.parquet", lambda tmp: pq.write_table(table, tmp)))
    return written


def _uniform(values) -> bool:
    kinds = {type(v) for v in values if v is not None}
    return len(kinds) <= 1 or kinds <= {int, float}


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return v


# ---------------------------------------------------------------------------- report
_CSS = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}table{border-collapse:collapse;"
        "font-size:13px}td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}th{background:#eee}"
        "td.l{text-align:left}.red{background:#f8d0d0}.yellow{background:#fbeec2}.green{background:#d8f0d8}"
        ".kpi{display:inline-block;margin:0 1.5em 1em 0}.kpi b{display:block;font-size:1.4em}figure{margin:1em 0}"
        "img{max-width:100%}")


def _short(v) -> str:
    """A number for the HTML table: 3 significant digits."""
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def _png(fig) -> str:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    try:
        fig.tight_layout()
        fig.savefig(buf, format="png", dpi=100)
    finally:
        plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def _label(r: dict) -> str:
    return f"{r['building']}@{r['event']}"


def plot_risk(rows: list[dict], top: int = 40):
    """P(collapse) at the own intensity, ranked (the ``top`` highest)."""
    import matplotlib.pyplot as plt
    ok = [r for r in rows if r["status"] == "ok"][:top]
    colors = {"red": "#c0392b", "yellow": "#e0a800", "green": "#2e8b57"}
    fig, ax = plt.subplots(figsize=(7.5, max(2.6, 0.25 * len(ok) + 1.2)))
    y = np.arange(len(ok))[::-1]
    p = [(_get(r, RISK_KEYS) or 0.0) for r in ok]
    ax.barh(y, p, color=[colors.get(str(r.get("indicator")), "#7f8c8d") for r in ok])
    ax.set_yticks(y, [_label(r) for r in ok], fontsize=8)
    ax.set_xlabel("P(collapse) at the building's own intensity")
    ax.set_xlim(0, max(0.05, max(p, default=0) * 1.15))
    ax.set_title("Buildings ranked by collapse risk (colour: re-occupancy indicator)")
    return fig


def plot_margin(rows: list[dict], top: int = 40):
    """Median collapse intensity with its band against the own intensity, per unit."""
    import matplotlib.pyplot as plt
    ok = [r for r in rows if r["status"] == "ok" and _get(r, CAPACITY_KEYS) is not None][:top]
    fig, ax = plt.subplots(figsize=(7.5, max(2.6, 0.25 * len(ok) + 1.2)))
    y = np.arange(len(ok))[::-1]
    med = np.array([_get(r, CAPACITY_KEYS) for r in ok])
    lo = np.array([r.get("collapse_median_band_lo") if r.get("collapse_median_band_lo") is not None else m
                   for r, m in zip(ok, med)], dtype=float)
    hi = np.array([r.get("collapse_median_band_hi") if r.get("collapse_median_band_hi") is not None else m
                   for r, m in zip(ok, med)], dtype=float)
    ax.errorbar(med, y, xerr=[med - lo, hi - med], fmt="o", color="#34495e", capsize=3,
                label="median collapse IM, band")
    own = [_get(r, OWN_KEYS) for r in ok]
    ax.plot([v if v is not None else np.nan for v in own], y, "x", color="#c0392b", ms=8, label="own record's IM")
    ax.set_yticks(y, [_label(r) for r in ok], fontsize=8)
    ax.set_xscale("log")
    from matplotlib.ticker import FormatStrFormatter
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(FormatStrFormatter("%g"))
    ax.tick_params(axis="x", which="minor", labelsize=7)
    label = next((str(r[k]) for r in ok for k in ("im_label", "im") if r.get(k)), "intensity")
    ax.set_xlabel(f"{label} [g]")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Collapse capacity against the intensity each building just had")
    return fig


def plot_cost(rows: list[dict]):
    """Compute time per unit: identification and assessment."""
    import matplotlib.pyplot as plt
    done = [r for r in rows if r.get("total_s") is not None]
    fig, ax = plt.subplots(figsize=(7.5, 3.2))
    x = np.arange(len(done))
    ident = np.array([r.get("identify_s") or 0.0 for r in done])
    ass = np.array([r.get("assess_s") or 0.0 for r in done])
    ax.bar(x, ident, label="identify", color="#5d8aa8")
    ax.bar(x, ass, bottom=ident, label="ensemble + IDA + decision", color="#e59866")
    ax.set_xticks(x, [_label(r) for r in done], rotation=90, fontsize=7)
    ax.set_ylabel("seconds on one worker")
    ax.legend(fontsize=8)
    ax.set_title("Compute time per building and event")
    return fig


def build_fleet_report(out: Path, rows: list[dict], meta: dict) -> Path:
    """Write ``out/report.html`` (self-contained: figures embedded) from the ranked ``rows``."""
    e = html.escape
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    decisions: dict[str, int] = {}
    for r in ok:
        decisions[str(r.get("indicator"))] = decisions.get(str(r.get("indicator")), 0) + 1
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(meta['name'])}</title>"
             f"<style>{_CSS}</style></head><body><h1>{e(meta['name'])}: portfolio risk</h1>"]
    kpis = [("units assessed", f"{len(ok)} / {len(rows)}"), ("failed", str(len(failed)))]
    kpis += [(f"indicator: {k}", str(v)) for k, v in sorted(decisions.items())]
    if meta.get("wall_s") is not None:
        kpis.append(("wall time of this run", f"{meta['wall_s']:.1f} s"))
    parts.append("<div>" + "".join(f"<span class='kpi'>{e(k)}<b>{e(v)}</b></span>" for k, v in kpis) + "</div>")
    engines = sorted({str(r.get("engine")) for r in ok})
    parts.append(f"<p>Assessment: {e(', '.join(engines) or 'none')}; IDA records: {meta.get('n_records')}; "
                 f"ensemble size: {meta.get('n_ensemble')}. hlaid {e(str(meta.get('hlaid_version')))}.</p>")
    if any(r.get("ensemble") == 0 for r in ok):
        parts.append("<p><b>ensemble: 0</b> rows are point clones (hlaid.uncertainty not installed): their band is "
                     "record-to-record only, without identification uncertainty.</p>")
    cols = [c for c in ("rank", "building", "event", "indicator", "p_collapse", "p_collapse_band_lo",
                        "p_collapse_band_hi", "own_im", "collapse_median", "collapse_median_band_lo",
                        "collapse_median_band_hi", "ensemble", "n_stories", "T1_s", "replay_r_min", "total_s")
            if any(c in r for r in ok)]
    cols += [c for c in columns(ok) if c.startswith("p_exceed_") and "_band" not in c]
    cols += [c for c in LOSS_COLUMNS if any(c in r for r in ok)]
    parts.append("<h2>Ranked by risk</h2><table><tr>" + "".join(f"<th>{e(header(c))}</th>" for c in cols) + "</tr>")
    for r in ok:
        cls = e(str(r.get("indicator", "")))
        parts.append(f"<tr class='{cls}'>" + "".join(
            f"<td class='l'>{e(str(r.get(c, '')))}</td>" if isinstance(r.get(c), str)
            else f"<td>{e(_short(r.get(c)))}</td>"
            for c in cols) + "</tr>")
    parts.append("</table>")
    rests = [(r, [f for f in str(r.get("basis_flags") or "").split(" | ") if f]) for r in ok]
    if any(f for _, f in rests):
        parts.append("<h2>What each figure rests on</h2><ul>" + "".join(
            f"<li>{e(str(r.get('building')))}@{e(str(r.get('event')))}: " + "; ".join(e(x) for x in f) + "</li>"
            for r, f in rests if f) + "</ul>")
    if failed:
        parts.append("<h2>Failed</h2><table><tr><th>building</th><th>event</th><th>reason</th></tr>")
        parts += [f"<tr><td class='l'>{e(r['building'])}</td><td class='l'>{e(r['event'])}</td>"
                  f"<td class='l'>{e(str(r.get('reason', '')))}</td></tr>" for r in failed]
        parts.append("</table>")
    figs = []
    if ok:
        figs += [("risk", plot_risk(rows), "P(collapse) at the own intensity, ranked")]
        if any(_get(r, CAPACITY_KEYS) is not None for r in ok):
            figs += [("margin", plot_margin(rows), "median collapse intensity (band) and the own record's intensity")]
    if any(r.get("total_s") is not None for r in rows):
        figs += [("cost", plot_cost(rows), "compute time per unit")]
    for alt, fig, cap in figs:
        parts.append(f"<figure><img alt='{alt}.png' src='data:image/png;base64,{_png(fig)}'>"
                     f"<figcaption>{e(cap)}</figcaption></figure>")
    parts.append("<p>Full table: <code>results.csv</code>; per-unit results with the clone: "
                 "<code>buildings/*.json</code>.</p></body></html>")
    return atomic_write(out / "report.html", lambda tmp: tmp.write_text("\n".join(parts)))


__all__ = ["table_rows", "write_table", "build_fleet_report", "risk_key", "columns"]
