"""The losses' section of ``report.html`` (:func:`hlaid.run.report.build_report` embeds it). It lives beside
the report, not in :mod:`hlaid.loss`, whose run-folder step rebuilds the report (no import cycle)."""

from __future__ import annotations

import html

LOSS_FIGURES = [
    ("loss/repair_cost.png", "Repair cost at the measured record (FEMA P-58 through pelicun): distribution over the "
                             "realisations, median, 90 % band and the replacement cost marked."),
    ("loss/loss_curve.png", "Repair cost ratio against intensity (mean, median and 90 % band) and the probabilities "
                            "of collapse and irreparable damage at the IDA stripes; the measured record marked."),
]


def _f(v, pct=False) -> str:
    if v is None:
        return "&ndash;"
    return f"{v:.1%}" if pct else f"{v:.4g}"


def loss_html(loss: dict) -> str:
    """The losses at the measured record, the curve's end points and the assumptions."""
    e = html.escape
    cf, irr = loss["collapse_fragility"], loss["irreparable"]
    out = [f"<p>{e(loss['engine'])}; inventory: {e(loss['inventory'])}; floor area "
           f"{sum(loss['floor_area_m2']):.4g} m<sup>2</sup> in total; replacement cost "
           f"{loss['replacement_cost']:,.0f} USD<sub>2011</sub>, replacement time {loss['replacement_time']:,.0f} "
           f"worker-days; {loss['n_ensemble'] or 'no'} ensemble clones; {loss['realizations']} realisations per "
           f"assessment.</p>"]
    r = loss.get("recorded")
    if r:
        lo, hi = r["repair_cost_band"]
        rlo, rhi = r["repair_cost_ratio_band"]
        rows = [("repair cost, median", f"{r['repair_cost_median']:,.0f} {e(r['cost_unit'])}",
                 f"{lo:,.0f} &ndash; {hi:,.0f}"),
                ("repair cost / replacement cost", _f(r["repair_cost_ratio_median"], True),
                 f"{_f(rlo, True)} &ndash; {_f(rhi, True)}"),
                ("repair time, median (parallel / sequential)",
                 f"{r['repair_time_parallel_median']:,.0f} / {r['repair_time_sequential_median']:,.0f} "
                 "worker-days", ""),
                ("P(collapse)", _f(r["p_collapse"], True), ""),
                ("P(irreparable: residual drift)", _f(r["p_irreparable"], True), "")]
        out.append(f"<p>At the measured record ({e(r['im_label'])} = {r['im']:.3g} g; {r['n_demand_realisations']} "
                   f"demand realisations, {r['n_realizations']} loss realisations):</p><table><tr><th class='l'>"
                   "measure</th><th>value</th><th>90 % band</th></tr>"
                   + "".join(f"<tr><td class='l'>{a}</td><td>{b}</td><td>{c}</td></tr>" for a, b, c in rows)
                   + "</table>")
    out.append(f"<p>Collapse fragility: median {_f(cf.get('median_g'))} g, beta {_f(cf.get('beta'))} "
               f"({e(cf['source'])}); irreparable damage: residual drift ratio median {irr['median']:.2%}, "
               f"beta {irr['beta']:.2g} (FEMA P-58). Files: <code>loss/</code> (pelicun's inputs per assessment, "
               "<code>loss.json</code>, <code>loss_curve.csv</code>); method: docs/loss.md.</p>")
    out.append("<ul>" + "".join(f"<li>{e(a)}</li>" for a in loss["assumptions"]) + "</ul>")
    return "".join(out)


__all__ = ["LOSS_FIGURES", "loss_html"]
