"""Markdown tables of a validation run."""

from __future__ import annotations

import numpy as np

from .predict import StudyPrediction, nanmean
from .protocol import ValidationResult
from .schema import PaperTargets


def _f(x, fmt="{:.3f}") -> str:
    return "-" if x is None or not np.isfinite(x) else fmt.format(x)


def _pct(x) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{100 * x:+.0f}"


def _met(ok: bool | None) -> str:
    return "-" if ok is None else ("yes" if ok else "**no**")


def _row(*cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _rule(n: int) -> str:
    return "|" + "---|" * n


def _joined(values, fmt: str) -> str:
    return " / ".join(fmt.format(v) for v in values)


def _clone_table(result: ValidationResult) -> list[str]:
    out = [_row("structure", "identified from", "clone", "k0 per story [N/mm per unit mass]", "alpha", "p", "dy [mm]",
                "delta_eta", "damping", "f1 [Hz]", "time [s]"), _rule(11)]
    for c in result.clones:
        b, lin = c.clone.building, c.kind == "linear"
        shape = ["-"] * 4 if lin else [_joined(b.alpha, "{:.2f}"), _joined(b.p, "{:.2f}"), _joined(b.dy, "{:.1f}"),
                                       _joined(b.delta_eta, "{:.2f}")]
        out.append(_row(c.structure, c.event, "linear (fallback)" if lin else "nonlinear", _joined(b.k0, "{:.4g}"),
                        *shape, f"{b.damping.ratio:.3f}", f"{1.0 / b.periods()[0]:.2f}", f"{c.seconds:.0f}"))
    reasons = {f"{c.structure}/{c.event}": c.reason for c in result.clones if c.reason}
    if reasons:
        out += ["", "Linear clones, why: " + "; ".join(f"{k}: {v}" for k, v in reasons.items()) + "."]
    return out


def _prediction_table(ps: list[StudyPrediction], tg: PaperTargets) -> list[str]:
    n = ps[0].r.shape[0]
    rt = tg.r_per_floor if n == len(tg.r_per_floor) else None
    against = f" against the paper's {' / '.join(map(str, rt))}" if rt else ""
    out = [(f"Band {ps[0].band_hz[0]:.3g}-{ps[0].band_hz[1]:.3g} Hz. R per floor{against}, mean against {tg.r_mean}; "
            f"stiffness error against {100 * tg.stiffness_error:.1f} %. "
            "Peak-drift and stiffness errors in % per story. Wide band: the replay under the whole ground motion "
            "in the band the event's floor records hold (its band, drift R per story, peak-drift error per story)."),
           "", _row("clone from", "event", "PGA [g]", *[f"R {i + 1}" for i in range(n)], "R mean", "floors met",
                    "mean met", "R broadband", "peak drift error", "wide band: drift R, peak drift error",
                    "stiffness error", "mean", "met"),
           _rule(n + 12)]
    for p in ps:
        r_mean, se = float(np.mean(p.r)), nanmean(p.stiffness_error)
        floors = "-" if rt is None else f"{sum(r >= t for r, t in zip(p.r, rt))}/{n}"
        out.append(_row(f"{p.identified_from} ({p.kind})", f"{p.event} (self)" if p.self_replay else p.event,
                        f"{p.pga_g:.3f}", *[_f(r) for r in p.r], _f(r_mean), floors, _met(r_mean >= tg.r_mean),
                        _f(float(np.mean(p.r_broadband))), " / ".join(_pct(e) for e in p.peak_drift_error),
                        _wide(p.prediction.other_bands.get("records")),
                        " / ".join(_f(100 * e, "{:.1f}") for e in p.stiffness_error),
                        _f(None if se is None else 100 * se, "{:.1f}"),
                        _met(None if se is None else se <= tg.stiffness_error)))
    return out


def _wide(f) -> str:
    """The wide-band figures of a prediction (``BandFigures``), one cell."""
    if f is None:
        return "-"
    return (f"{f.band_hz[0]:.3g}-{f.band_hz[1]:.3g} Hz: " + " / ".join(_f(r) for r in f.drift_r) + ", "
            + " / ".join(_pct(e) for e in f.peak_drift_error))


def _summary_rows(name: str, ps: list[StudyPrediction], tg: PaperTargets) -> list[str]:
    """One row per clone, and with several clones: all of them, and the predictions of
    stronger events (PGA above the clone's own event) only."""
    groups = [(src, [p for p in ps if p.identified_from == src])
              for src in dict.fromkeys(p.identified_from for p in ps)]
    own_pga = {p.identified_from: p.pga_g for p in ps if p.self_replay}
    cross_all = [p for p in ps if not p.self_replay]
    stronger = [p for p in cross_all if p.pga_g > own_pga.get(p.identified_from, np.inf)]
    rows = list(groups)
    if len(groups) > 1:
        rows.append(("all", ps))
        if 0 < len(stronger) < len(cross_all):
            rows.append(("all, stronger events only", stronger))
    out = []
    for src, g in rows:
        cross = [p for p in g if not p.self_replay]
        own = [p for p in g if p.self_replay]
        r_self = _f(float(np.mean([np.mean(p.r) for p in own]))) if own else "-"
        if not cross:
            out.append(_row(name, src, 0, *["-"] * 7, r_self))
            continue
        r = np.array([p.r for p in cross])
        se = nanmean(np.array([p.stiffness_error for p in cross]))
        pe = float(np.mean(np.abs([p.peak_drift_error for p in cross])))
        out.append(_row(name, src, len(cross), f"{r.mean():.3f}", f"{r.min():.3f}", _met(r.mean() >= tg.r_mean),
                        f"{np.mean([p.r_broadband for p in cross]):.3f}", f"{100 * pe:.0f} %",
                        f"{_f(None if se is None else 100 * se, '{:.1f}')} %",
                        _met(None if se is None else se <= tg.stiffness_error), r_self))
    return out


def format_tables(result: ValidationResult) -> str:
    """Markdown tables of a validation run: clones, predictions per structure, summary (every
    number, each held against the paper's targets)."""
    tg = result.targets
    out = ["### Clones", "", *_clone_table(result)]
    names = list(dict.fromkeys(p.structure for p in result.predictions))
    for name in names:
        out += ["", f"### {name}", "", *_prediction_table([p for p in result.predictions if p.structure == name], tg)]
    out += ["", "### Summary (cross-event predictions; self-replays apart)", "",
            _row("structure", "clone from", "predictions", "mean R", "worst R", f"mean R >= {tg.r_mean}",
                 "mean R broadband", "mean abs peak-drift error", "mean stiffness error",
                 f"<= {100 * tg.stiffness_error:.1f} %", "self-replay R"), _rule(11)]
    for name in names:
        out += _summary_rows(name, [p for p in result.predictions if p.structure == name], tg)
    return "\n".join(out) + "\n"
