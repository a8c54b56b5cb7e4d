"""Figures of hysteresis loop analysis: loops by half cycle, stiffness evolution."""

from __future__ import annotations

import numpy as np
from matplotlib import cm
from matplotlib.collections import LineCollection

from ..measurement import Measurement, Truth
from ..plots import story_axes
from .result import HLAResult


def _force_unit(result: HLAResult) -> tuple[float, str]:
    """Scale and label of the story force: kN, or per tonne of floor mass (N/t) when the masses are
    unknown (a mass-normalised analysis: equal or given mass ratios, total mass 1 t)."""
    return (1.0, "story force / total mass [N/t]\n(floor masses unknown)") if result.mass_normalised else \
        (1e-3, "story force [kN]")


WIDE_HZ = 20.0
"""Upper corner of the wide band a narrow-band analysis's loops are shown beside."""


def wide_band(meas: Measurement, result: HLAResult) -> HLAResult | None:
    """The same analysis with the upper band corner at :data:`WIDE_HZ` (capped below Nyquist),
    when the analysis band ends well below it (a first-mode band smooths loops into ellipses; the
    wide band shows the yielding, residual drift and higher modes the records hold); else None."""
    import dataclasses

    from ..signal import cap_corner
    from .analysis import run_hla

    lo, hi = result.band_hz
    top = cap_corner(WIDE_HZ, meas.dt)
    if hi >= 0.5 * top:
        return None
    cfg = result.config
    return run_hla(meas, dataclasses.replace(cfg, preprocess=dataclasses.replace(cfg.preprocess, band_hz=(lo, top))))


def plot_loops(result: HLAResult, *, max_cycles: int | None = None, wide: HLAResult | None = None):
    """Force-drift loops of every story, each half cycle in its own colour (time: dark to light);
    with ``wide`` (:func:`wide_band`) a second row: the same story's loop in that wider band."""
    scale, label = _force_unit(result)
    n_st = result.n_stories
    if wide is None:
        fig, axes = story_axes(n_st, layout="constrained")
    else:
        from ..plots import plt
        fig, grid = plt.subplots(2, n_st, figsize=(4.2 * n_st, 6.8), squeeze=False, layout="constrained")
        axes = grid[0].tolist()
        for s, w, ax in zip(result.stories, wide.stories, grid[1]):
            ax.plot(w.drift, w.force * scale, color="0.35", lw=0.5)
            ax.set_title(f"story {s.story}: wide band {wide.band_hz[0]:.2g}-{wide.band_hz[1]:.3g} Hz",
                         fontsize=9)
            ax.set_xlabel("inter-story drift [mm]")
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
    for s, ax in zip(result.stories, axes):
        hc = s.half_cycles
        n = len(hc) if max_cycles is None else min(len(hc), max_cycles)
        segs = [np.column_stack([s.drift[a:b + 1], s.force[a:b + 1] * scale]) for a, b in hc.bounds[:n]]
        lc = LineCollection(segs, cmap=cm.viridis, linewidths=0.8)
        lc.set_array(np.arange(n))
        ax.add_collection(lc)
        ax.autoscale()
        band = f", band {result.band_hz[0]:.2g}-{result.band_hz[1]:.3g} Hz" if wide is not None else ""
        ax.set_title(f"story {s.story}: {len(hc)} half cycles" + ("" if s.yielded else " (elastic)") + band,
                     fontsize=9 if wide is not None else None)
        ax.set_xlabel("inter-story drift [mm]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    cb = fig.colorbar(lc, ax=axes, shrink=0.8, pad=0.01)
    cb.set_label("half cycle")
    fig.suptitle("HLA: story restoring force against drift")
    return fig


def plot_stiffness(result: HLAResult, truth: Truth | None = None, *, clone_ke: np.ndarray | None = None):
    """Stiffness evolution of every story: ke(t) per half cycle (raw slopes and the pooled
    estimate), the tangent stiffness k(t), k0; the truth ``alpha k0 + (1-alpha) k0 / eta(t)``
    when known, and a clone's ke(t) ``(time, story)`` when given."""
    from ..plots import plt  # noqa: F401  (backend set there)

    t = result.time
    fig, axes = story_axes(result.n_stories, ncols=1, size=(11, 2.6), sharex=True)
    unit = "k / total mass [N/mm/t]" if result.mass_normalised else "stiffness [kN/mm]"
    k_unit = "N/mm/t" if result.mass_normalised else "kN/mm"
    sc = 1.0 if result.mass_normalised else 1e-3
    for i, (s, ax) in enumerate(zip(result.stories, axes)):
        hc = s.half_cycles
        ax.plot(t, s.k * sc, color="0.75", lw=0.5, label="k(t) tangent")
        ax.plot(hc.t_start, hc.ke_raw * sc, ".", color="C0", ms=3, alpha=0.6, label="ke per half cycle (raw)")
        ax.step(hc.t_start, hc.ke * sc, where="post", color="C0", lw=1.5, label="ke(t) HLA")
        ax.axhline(s.k0 * sc, color="C0", ls=":", lw=1, label="k0 (each story's, in its panel)")
        ax.text(0.995, 0.97, f"story {s.story}: k0 = {s.k0 * sc:.4g} {k_unit}", transform=ax.transAxes, ha="right",
                va="top", fontsize=8, color="C0", bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})
        if truth is not None:
            b = truth.building
            ke_true = b.alpha[i] * b.k0[i] + (1 - b.alpha[i]) * b.k0[i] / truth.eta[:, i]
            ax.plot(t, ke_true * sc, color="k", lw=1, label="ke(t) true")
        if clone_ke is not None:
            ax.plot(t[: clone_ke.shape[0]], clone_ke[:, i] * sc, color="C3", lw=1, ls="--", label="ke(t) clone")
        lo = np.nanmin(hc.ke_raw) if len(hc) else s.k0
        hi = s.k0
        for line in ([ke_true] if truth is not None else []) + ([clone_ke[:, i]] if clone_ke is not None else []):
            v = np.asarray(line, float)
            v = v[np.isfinite(v)]
            if v.size:  # the truth's and the clone's lines stay inside the panel
                lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
        ax.set_ylim(max(0.0, 0.5 * min(lo, s.k0) * sc), 1.25 * hi * sc)
        ax.set_ylabel(f"story {s.story}\n{unit}")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=3, loc="lower left")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("HLA: stiffness evolution")
    return fig
