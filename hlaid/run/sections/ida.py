"""The report's IDA section: intensity measure, EDP and collapse criteria, then the collapse and
drift-limit fragilities (median and dispersion with their bootstrap intervals) and the IDA's notes."""

from __future__ import annotations

import html

from ..summary import Fragility, IDASummary
from .markup import fmt


def section(ida: IDASummary) -> str:
    """Heading, settings, fragility table and notes."""
    e = html.escape
    im, crit = ida.intensity_measure, ida.collapse_criteria
    period = f" at T1 = {im.period_s:.3f} s" if im.period_s else ""
    label = e(str(next((v for v in (im.label, im.name) if v is not None), "?")))
    n_runs = "?" if ida.n_runs is None else ida.n_runs
    head = (f"<p>Intensity measure {label}{period}; EDP: {e(str(ida.edp))}; "
            f"collapse when a story's drift ratio exceeds {crit.drift_limit:.0%} or the IDA slope falls "
            f"below {crit.slope_ratio:.0%} of the elastic slope; {n_runs} analyses of "
            f"{len(ida.records)} records.</p>")
    rows: list[tuple[str, Fragility]] = []
    if ida.collapse_fit is not None:
        rows.append(("collapse", ida.collapse_fit))
    for lim, d in sorted((ida.drift_limits or {}).items(), key=lambda kv: float(kv[0])):
        if d.fragility is not None:
            rows.append((f"drift ratio > {float(lim):.1%}", d.fragility))
    out = "<h2>Incremental dynamic analysis</h2>" + head
    if not rows:
        return out
    tab = ["<table><tr><th class='l'>limit state</th><th>median [g]</th><th>median interval [g]</th><th>beta</th>"
           "<th>beta interval</th><th>records (censored)</th></tr>"]
    for name, f in rows:
        mci, bci = f.median_ci_g or (None, None), f.beta_ci or (None, None)
        tab.append(f"<tr><td class='l'>{e(name)}</td><td>{fmt(f.median_g)}</td>"
                   f"<td>{fmt(mci[0])} &ndash; {fmt(mci[1])}</td><td>{fmt(f.beta)}</td>"
                   f"<td>{fmt(bci[0])} &ndash; {fmt(bci[1])}</td>"
                   f"<td>{f.n_records} ({f.n_censored or 0})</td></tr>")
    ci = next((f.ci for _, f in rows if f.ci), None)
    tab.append("</table>" + (f"<p>Intervals: {ci:.0%} bootstrap.</p>" if ci else ""))
    notes = "".join(f"<li>{e(n)}</li>" for n in ida.notes)
    return out + "".join(tab) + (f"<ul>{notes}</ul>" if notes else "")


__all__ = ["section"]
