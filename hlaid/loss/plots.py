"""Figures of the loss assessment: loss against intensity, repair cost distribution of the event."""

from __future__ import annotations

import numpy as np


def plot_loss_curve(stripes, own=None):
    """Repair cost ratio against intensity (mean, median and 90 % band over pelicun's realizations)
    and P(collapse), P(irreparable); the recorded event marked. ``stripes``/``own``: LossResults."""
    import matplotlib.pyplot as plt

    s = [r.summary for r in stripes]
    x = np.array([v["level_g"] for v in s])
    label = s[0]["im_label"]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10.5, 5.0), layout="constrained")
    lo = np.array([v["repair_cost_ratio_band"][0] for v in s])
    hi = np.array([v["repair_cost_ratio_band"][1] for v in s])
    ax.fill_between(x, lo, hi, color="C0", alpha=0.2, label=f"{s[0]['ci']:.0%} band")
    ax.plot(x, [v["repair_cost_ratio_median"] for v in s], "C0-o", ms=4, label="median")
    ax.plot(x, [v["repair_cost_ratio_mean"] for v in s], "k--", lw=1.5, label="mean (expected loss)")
    ax2.plot(x, [np.nan if v["p_collapse"] is None else v["p_collapse"] for v in s], "C3-o", ms=4, label="collapse")
    ax2.plot(x, [v["p_irreparable"] for v in s], "C1-s", ms=4, label="irreparable (residual drift)")
    ax2.plot(x, [np.nan if v["p_replacement"] is None else v["p_replacement"] for v in s], "C7:", lw=1.5,
             label="replacement (either)")
    if own is not None:
        o = own.summary
        for a in (ax, ax2):
            a.axvline(o["im"], color="k", ls=":", lw=1, label="recorded event" if a is ax2 else None)
        ax.plot([o["im"]], [o["repair_cost_ratio_median"]], "D", color="C2", ms=8, mec="k", clip_on=False, zorder=5,
                label=f"recorded event ({o['im']:.3g} g): median {o['repair_cost_ratio_median']:.1%}")
    right = max(float(x.max()), own.summary["im"] if own is not None else 0.0) * 1.08  # the event inside the axes
    for a, yl in ((ax, "repair cost / replacement cost [-]"), (ax2, "probability [-]")):
        a.set_xlabel(f"{label} [g]")
        a.set_ylabel(yl)
        a.set_xlim(0, right)
        a.set_ylim(0, 1.08)  # a marker at the replacement cost (1) stays whole
        a.grid(alpha=0.3)
        # below the axes: never over the curves
        a.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    ax.set_title("Repair cost against intensity (FEMA P-58, pelicun)", fontsize=10)
    ax2.set_title("Collapse and irreparable damage", fontsize=10)
    return fig


def plot_repair_cost(own, replacement_cost: float):
    """Distribution of the repair cost at the recorded event: histogram and the median, the band
    and the replacement cost marked. ``own``: the LossResult of the recorded event."""
    import matplotlib.pyplot as plt

    s = own.summary
    cost = np.asarray(own.sample["repair_cost"]) / 1e3
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.hist(cost, bins=40, color="C0", alpha=0.75, edgecolor="white")
    lo, hi = (v / 1e3 for v in s["repair_cost_band"])
    ax.axvline(s["repair_cost_median"] / 1e3, color="k", lw=2, label=f"median {s['repair_cost_median'] / 1e3:.4g} k")
    ax.axvspan(lo, hi, color="C1", alpha=0.12, label=f"{s['ci']:.0%} band {lo:.4g} - {hi:.4g} k")
    ax.axvline(replacement_cost / 1e3, color="C3", ls="--", lw=1.5,
               label=f"replacement {replacement_cost / 1e3:.4g} k ("
                     + ("P not assessed" if s.get("p_replacement") is None else f"P = {s['p_replacement']:.1%}") + ")")
    ax.set_xlabel(f"repair cost [thousand {s['cost_unit']}]")
    ax.set_ylabel("realizations")
    ax.set_title(f"Repair cost at the recorded event ({s['im_label']} = {s['im']:.3g} g, "
                 f"{s['n_realizations']} realizations)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


__all__ = ["plot_loss_curve", "plot_repair_cost"]
