"""The report's first section: what the decision rests on. P(collapse) at the intensity of every
event the clone was identified from (the building survived each), the clone's events as evidence
(members rejected for collapsing under them) and the flags a reader must know."""

from __future__ import annotations

import html

from ..summary import RunSummary
from .markup import fmt


def section(s: RunSummary) -> str:
    """Heading, the flags, P(collapse) at the recorded events and the survival counts ("" when
    the run has none of them)."""
    e = html.escape
    out = []
    if s.flags:
        out.append("<p><b>Read the numbers below with these in mind:</b></p><ul>"
                   + "".join(f"<li class='bad'>{e(f)}</li>" for f in s.flags) + "</ul>")
    if s.events:
        def band(b) -> str:
            return "" if b is None else f"{fmt(b[0], '.1%')} &ndash; {fmt(b[1], '.1%')}"
        rows = "".join(
            f"<tr><td class='l'>{e(r.name)}</td><td>{fmt(r.im, '.3g')}</td>"
            f"<td>{'not assessed' if r.p_collapse is None else fmt(r.p_collapse, '.1%')}</td>"
            f"<td>{band(r.p_collapse_band)}</td><td class='l'>{e(r.source or '')}</td></tr>" for r in s.events)
        out.append("<p>P(collapse | another record of the intensity of each recorded event): the undamaged clone's "
                   "IDA fragility at the event's intensity (the building survived every one; whether the clone "
                   "survives the event's own motion is listed below):</p>"
                   "<table><tr><th class='l'>event</th><th>IM [g]</th>"
                   "<th>P(collapse)</th><th>90 % band</th><th class='l'>fragility</th></tr>" + rows + "</table>")
    if s.basis is not None:
        from ...ida.basis import DecisionBasis

        lines = [x for x in DecisionBasis.from_dict(s.basis).lines()[1:]  # P(collapse) at the events: the table
                 if not (s.events and x.lstrip().startswith("P(collapse | another record"))]
        out.append("<p>What the figures rest on:</p><ul>" + "".join(f"<li>{e(x.strip())}</li>" for x in lines)
                   + "</ul>")
    v = s.survival
    if v is not None and (v.events or v.unchecked):
        said = (f"the identified clone {'survives' if v.nominal_survives else 'collapses under'} "
                f"{e(', '.join(v.events) if v.nominal_survives else str(v.nominal_collapsed_in))} with the collapse "
                "law in force" if v.nominal_survives is not None else "not checked")
        members = (f"; of {v.n_drawn} ensemble draws {v.n_rejected} collapsed under them and were rejected"
                   if v.n_drawn else "")
        out.append(f"<p>Survival as evidence: {said}{members}.</p>")
    if not out:
        return ""
    return "<h2>What the decision rests on</h2>" + "".join(out)


__all__ = ["section"]
