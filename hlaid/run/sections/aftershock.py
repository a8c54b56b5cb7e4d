"""The report's aftershock section: the clone's collapse fragility before the event (undamaged)
and after it (from the state the event left it in), with the collapse law used and why."""

from __future__ import annotations

import html

CAPTION = ("Collapse fragility of the clone before the event (undamaged) and after it (every run from "
           "the residual drift, hysteretic state and degradation the event left): each record's collapse "
           "intensity and the lognormal fit.")


def _fit(ida: dict) -> dict:
    cf = ida.get("collapse_fragility") or {}
    return cf.get("capacities") or cf.get("counts") or {}


def _num(v, fmt: str = ".3g") -> str:
    return "&ndash;" if v is None else format(v, fmt)


def aftershock_html(before: dict, after: dict) -> str:
    """HTML of the section from the ``ida`` and ``ida_after`` blocks of ``summary.json``."""
    e = html.escape
    rows = []
    for name, ida in (("before the event (undamaged)", before), ("after the event (state carried)", after)):
        f = _fit(ida)
        ci = f.get("median_ci_g") or [None, None]
        rows.append(f"<tr><td class='l'>{e(name)}</td><td>{_num(f.get('median_g'))}</td>"
                    f"<td>{_num(ci[0])} &ndash; {_num(ci[1])}</td><td>{_num(f.get('beta'), '.2f')}</td>"
                    f"<td>{f.get('n_records')} ({f.get('n_censored', 0)})</td></tr>")
    m0, m1 = _fit(before).get("median_g"), _fit(after).get("median_g")
    change = "" if not (m0 and m1) else f"<p>The event moved the median collapse intensity by {m1 / m0 - 1:+.1%}.</p>"
    notes = [n for n in after.get("notes", []) if n.startswith(("collapse model", "start: carried"))]
    law = "".join(f"<li>{e(n)}</li>" for n in notes)
    return ("<table><tr><th class='l'>clone</th><th>median [g]</th><th>median interval [g]</th><th>beta</th>"
            "<th>records (censored)</th></tr>" + "".join(rows) + "</table>" + change
            + (f"<ul>{law}</ul>" if law else ""))


def aftershock_section(before: dict, after: dict, image: str) -> str:
    """The whole section: heading, table, notes and the figure (``image``: its ``<img>`` tag)."""
    return ("<h2>Aftershock: collapse fragility before and after the event</h2>" + aftershock_html(before, after)
            + f"<figure>{image}<figcaption>{html.escape(CAPTION)}</figcaption></figure>")
