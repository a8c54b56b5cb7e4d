"""The report's assessment section: the collapse fragility over the ensemble of clones drawn from
the identification uncertainty and, at the measured record's intensity, the re-occupancy
indicator, P(collapse) and the drift exceedances with their bands."""

from __future__ import annotations

import html

from ..summary import Assessment
from .markup import figure, fmt

FIGURE = "figures/fragility_band.png"
CAPTION = ("Collapse fragility over the ensemble of clones drawn from the identification uncertainty: median curve "
           "and band (identification and record sampling), the measured record's intensity marked (dashed) with "
           "P(collapse) there, coloured by the re-occupancy indicator.")
INDICATOR_CSS = {"green": "#1e8e3e", "yellow": "#d4a000", "red": "#c5221f"}
"""The indicator's colours (the section and the page's key figures)."""

NOTE = ("<p>Indicator (assumptions, docs/uncertainty.md): the worse of P(collapse) at the experienced intensity "
        "(red &ge; 10 %, ASCE 7-16's target at MCE<sub>R</sub>; yellow &ge; 2 %) and the residual drift ratio "
        "(red &ge; 1 %, yellow &ge; 0.5 %: FEMA P-58 residual-drift damage states DS3, DS2), each at the upper end "
        "of the ensemble; placards after ATC-20. The clones are undamaged at the start of each IDA.</p>")


def section(a: Assessment, image: str | None) -> str:
    """Heading, the ensemble's collapse fragility, the indicator and the figure (``image``: its ``<img>`` tag)."""
    return ("<h2>Collapse risk with identification uncertainty</h2>" + assessment_html(a) + "\n"
            + figure(image, CAPTION))


def assessment_html(a: Assessment) -> str:
    """The ensemble assessment: indicator, P(collapse) and drift exceedance at the measured record."""
    e = html.escape
    lo, hi = a.collapse_median_band
    ci = f"{a.ci:.0%}"
    out = [f"<p>IDA of {a.n_ensemble} clones drawn from the identification uncertainty over {a.n_records} "
           f"records. Median collapse {e(a.im_label)}: <b>{a.collapse_median:.3g} g</b> ({ci} band "
           f"{lo:.3g} &ndash; {hi:.3g} g).</p>"]
    if a.own_im is None or a.indicator not in INDICATOR_CSS:
        return "".join(out)
    colour = INDICATOR_CSS[a.indicator]
    plo, phi = a.p_collapse_band or (None, None)
    out.append(f"<p style='font-size:1.15em'><span style='display:inline-block;padding:.3em .8em;border-radius:5px;"
               f"background:{colour};color:white;font-weight:bold'>{e(a.indicator.upper())}</span> "
               f"{e(a.placard or '')}</p>")
    rows = [f"<tr><td class='l'>collapse</td><td>{fmt(a.p_collapse, '.1%')}</td>"
            f"<td>{fmt(plo, '.1%')} &ndash; {fmt(phi, '.1%')}</td></tr>"]
    for lim, p, band in zip(a.drift_limits, a.p_exceed, a.p_exceed_band or ()):
        rows.append(f"<tr><td class='l'>peak drift ratio &gt; {lim:.1%}</td><td>{fmt(p, '.1%')}</td>"
                    f"<td>{fmt(band[0], '.1%')} &ndash; {fmt(band[1], '.1%')}</td></tr>")
    out.append(f"<p>At the measured record's intensity, {e(a.im_label)} = {a.own_im:.3g} g:</p>"
               f"<table><tr><th class='l'>event</th><th>probability (mean of the ensemble)</th>"
               f"<th>{ci} band (5th &ndash; 95th percentile)</th></tr>"
               + "".join(rows) + "</table>")
    if a.own_residual_drift_median is not None:
        out.append(f"<p>The clones under the measured record: median peak drift ratio "
                   f"{fmt(a.own_peak_drift_median, '.1%')}, residual {fmt(a.own_residual_drift_median, '.1%')}.</p>")
    out.append("<ul>" + "".join(f"<li>{e(r)}</li>" for r in a.reasons) + "</ul>")
    out.append(NOTE)
    return "".join(out)


__all__ = ["section", "assessment_html", "FIGURE", "CAPTION", "INDICATOR_CSS"]
