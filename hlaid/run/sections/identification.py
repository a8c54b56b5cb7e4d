"""The report's identification section: the identified parameters per story (with the 90 %
interval, the truth and the error when known, and the paper's method alone), the outer
iterations and the stiffness-evolution error of the clone against HLA."""

from __future__ import annotations

import html

from ..summary import ParameterRow, RunSummary
from .markup import fmt

UNITS = {"k0": "N/mm", "alpha": "-", "p": "-", "dy": "mm", "delta_eta": "s<sup>2</sup>/m<sup>2</sup>"}
"""The unit of each parameter in the report's table (HTML)."""

MASS_NORMALISED = ("The floor masses are unknown: the clone is mass-normalised (equal or given mass ratios, the "
                   "total mass 1 t), so its stiffness k0 is in N/mm per tonne of that total mass (N/mm/t) and the "
                   "story forces of the loop figure are per tonne of it (N/t); periods, drifts, alpha, p, dy and "
                   "delta_eta are those of the building.")


def section(s: RunSummary) -> str:
    """Heading, parameter table and the identification's figures of merit."""
    errors = ", ".join(f"{v:.1%}" for v in s.replay.stiffness_error)
    return "\n".join(["<h2>Identified parameters</h2>",
                      parameter_table(s.parameters, s.paper_method or (), mass_normalised=bool(s.mass_normalised)),
                      f"<p>{MASS_NORMALISED}</p>" if s.mass_normalised else "",
                      f"<p>Outer iterations: {s.outer_iterations}. Stiffness-evolution error (clone against HLA) "
                      f"per story: {errors}.</p>"])


def unit(parameter: str, mass_normalised: bool = False) -> str:
    """The HTML unit of ``parameter`` (k0 per tonne for a mass-normalised clone)."""
    if parameter == "k0" and mass_normalised:
        return "N/mm/t"
    return UNITS.get(parameter, "-")


def parameter_table(rows: tuple[ParameterRow, ...], paper_rows: tuple[ParameterRow, ...], *,
                    mass_normalised: bool = False) -> str:
    """One row per parameter and story, with its unit: identified, interval, truth, error, the paper's
    method alone."""
    paper = {(r.parameter, r.story): r for r in paper_rows}
    has_truth = any(r.true is not None for r in rows)
    has_iv = any(r.interval is not None and r.interval[0] is not None for r in rows)
    head = "<tr><th class='l'>parameter</th><th class='l'>unit</th><th>story</th><th>identified</th>"
    head += "<th>90 % interval</th>" if has_iv else ""
    head += "<th>true</th><th>error</th>" if has_truth else ""
    head += "<th>paper method alone</th>" + ("<th>its error</th>" if has_truth else "") + "</tr>"
    body = []
    for r in rows:
        pr = paper.get((r.parameter, r.story))
        cells = [f"<td class='l'>{html.escape(r.parameter)}</td><td class='l'>{unit(r.parameter, mass_normalised)}</td>"
                 f"<td>{r.story}</td><td>{fmt(r.identified)}</td>"]
        if has_iv:
            lo, hi = r.interval or (None, None)
            cells.append("<td>&ndash;</td>" if lo is None or hi is None else f"<td>{fmt(lo)} &ndash; {fmt(hi)}</td>")
        if has_truth:
            cls = "ok" if r.error is not None and r.error <= 0.03 else "bad"
            cells.append(f"<td>{fmt(r.true)}</td><td class='{cls}'>{fmt(r.error, '.1%')}</td>")
        cells.append(f"<td>{fmt(pr.identified if pr else None)}</td>")
        if has_truth:
            cells.append(f"<td>{fmt(pr.error if pr else None, '.1%')}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return "<table>" + head + "".join(body) + "</table>"


__all__ = ["section", "parameter_table"]
