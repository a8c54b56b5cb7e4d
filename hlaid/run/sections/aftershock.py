"""The report's aftershock section: the clone's collapse fragility before the event (undamaged)
and after it (from the state the event left it in), with the collapse law used and why."""

from __future__ import annotations

import html

from ..summary import Fragility, IDASummary
from .markup import figure, fmt

FIGURE = "figures/aftershock.png"
CAPTION = ("Collapse fragility of the clone before the event (undamaged) and after it (every run from "
           "the residual drift, hysteretic state and degradation the event left): each record's collapse "
           "intensity and the lognormal fit.")


def aftershock_html(before: IDASummary, after: IDASummary) -> str:
    """HTML of the section from the ``ida`` and ``ida_after`` blocks of the run summary."""
    e = html.escape
    rows = []
    for name, ida in (("before the event (undamaged)", before), ("after the event (state carried)", after)):
        f = ida.collapse_fit or Fragility()
        ci = f.median_ci_g or (None, None)
        rows.append(f"<tr><td class='l'>{e(name)}</td><td>{fmt(f.median_g, '.3g')}</td>"
                    f"<td>{fmt(ci[0], '.3g')} &ndash; {fmt(ci[1], '.3g')}</td><td>{fmt(f.beta, '.2f')}</td>"
                    f"<td>{f.n_records} ({f.n_censored or 0})</td></tr>")
    m0, m1 = (ida.collapse_fit.median_g if ida.collapse_fit else None for ida in (before, after))
    change = "" if not (m0 and m1) else f"<p>The event moved the median collapse intensity by {m1 / m0 - 1:+.1%}.</p>"
    notes = [n for n in after.notes if n.startswith(("collapse model", "start: carried"))]
    law = "".join(f"<li>{e(n)}</li>" for n in notes)
    return ("<table><tr><th class='l'>clone</th><th>median [g]</th><th>median interval [g]</th><th>beta</th>"
            "<th>records (censored)</th></tr>" + "".join(rows) + "</table>" + change
            + (f"<ul>{law}</ul>" if law else ""))


def section(before: IDASummary, after: IDASummary, image: str | None) -> str:
    """The whole section: heading, table, notes and the figure (``image``: its ``<img>`` tag)."""
    return ("<h2>Aftershock: collapse fragility before and after the event</h2>" + aftershock_html(before, after)
            + figure(image, CAPTION))


__all__ = ["section", "aftershock_html", "FIGURE", "CAPTION"]
