"""The report's loss section: FEMA P-58 through pelicun at the measured record (repair cost and
time, P(collapse), P(irreparable)), the collapse and irreparable-damage fragilities used, the
assumptions and the loss figures."""

from __future__ import annotations

import html
from collections.abc import Callable

from ..summary import LossSummary
from .markup import figure, fmt

FIGURES = [
    ("loss/repair_cost.png", "Repair cost at the measured record (FEMA P-58 through pelicun): distribution over the "
                             "realizations, median, 90 % band and the replacement cost marked."),
    ("loss/loss_curve.png", "Repair cost ratio against intensity (mean, median and 90 % band) and the probabilities "
                            "of collapse and irreparable damage at the IDA stripes; the measured record marked."),
]


def required_figures(loss: LossSummary) -> list[str]:
    """The loss figures a run folder with this block holds."""
    return ([FIGURES[0][0]] if loss.recorded else []) + ([FIGURES[1][0]] if loss.curve else [])


def section(loss: LossSummary, image: Callable[[str], str | None]) -> str:
    """Heading, the losses and the figures (``image(rel)``: the ``<img>`` tag of a figure, None when absent)."""
    figs = [(image(rel), cap) for rel, cap in FIGURES]
    return "\n".join(["<h2>Losses (FEMA P-58 through pelicun)</h2>" + loss_html(loss),
                      *(figure(img, cap) for img, cap in figs if img is not None)])


def loss_html(loss: LossSummary) -> str:
    """The losses at the measured record, the curve's end points and the assumptions."""
    e = html.escape
    cf, irr = loss.collapse_fragility, loss.irreparable
    out = [f"<p>{e(loss.engine)}; inventory: {e(loss.inventory)}; floor area "
           f"{sum(loss.floor_area_m2):.4g} m<sup>2</sup> in total; replacement cost "
           f"{loss.replacement_cost:,.0f} USD<sub>2011</sub>, replacement time {loss.replacement_time:,.0f} "
           f"worker-days; {loss.n_ensemble or 'no'} ensemble clones; {loss.realizations} realizations per "
           f"assessment.</p>"]
    r = loss.recorded
    if r:
        lo, hi = r.repair_cost_band
        rlo, rhi = r.repair_cost_ratio_band
        rows = [("repair cost, median", f"{r.repair_cost_median:,.0f} {e(r.cost_unit)}",
                 f"{lo:,.0f} &ndash; {hi:,.0f}"),
                ("repair cost / replacement cost", fmt(r.repair_cost_ratio_median, ".1%"),
                 f"{fmt(rlo, '.1%')} &ndash; {fmt(rhi, '.1%')}"),
                ("repair time, median (parallel / sequential)",
                 f"{r.repair_time_parallel_median:,.0f} / {r.repair_time_sequential_median:,.0f} worker-days", ""),
                ("P(collapse)", "not assessed" if r.p_collapse is None else fmt(r.p_collapse, ".1%"), ""),
                ("P(irreparable: residual drift)", fmt(r.p_irreparable, ".1%"), "")]
        out.append(f"<p>At the measured record ({e(r.im_label)} = {r.im:.3g} g; {r.n_demand_realizations} "
                   f"demand realizations, {r.n_realizations} loss realizations):</p><table><tr><th class='l'>"
                   "measure</th><th>value</th><th>90 % band</th></tr>"
                   + "".join(f"<tr><td class='l'>{a}</td><td>{b}</td><td>{c}</td></tr>" for a, b, c in rows)
                   + "</table>")
    out.append(f"<p>Collapse fragility: median {fmt(cf.median_g)} g, beta {fmt(cf.beta)} "
               f"({e(cf.source)}); irreparable damage: residual drift ratio median {irr.median:.2%}, "
               f"beta {irr.beta:.2g} (FEMA P-58). Files: <code>loss/</code> (pelicun's inputs per assessment, "
               "<code>loss.json</code>, <code>loss_curve.csv</code>); method: docs/loss.md.</p>")
    out.append("<ul>" + "".join(f"<li>{e(a)}</li>" for a in loss.assumptions) + "</ul>")
    return "".join(out)


__all__ = ["FIGURES", "required_figures", "section", "loss_html"]
