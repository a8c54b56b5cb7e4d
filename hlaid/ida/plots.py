"""Figures of an IDA: curves with fractiles, collapse fragility, drift-limit exceedance.

The figures read an :class:`~hlaid.ida.IDAResult` through :class:`IDACurves`, what they use of
it (``IDAResult.save`` draws them, so this module does not import the result's).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ..model import Building
from ..plots import plt
from .fragility import FRACTILES, LognormalFragility


class IDACurves(Protocol):
    """What the figures read of an IDA result (:class:`~hlaid.ida.IDAResult` is one)."""

    @property
    def building(self) -> Building: ...
    @property
    def levels(self) -> np.ndarray: ...
    @property
    def point_im(self) -> np.ndarray: ...
    @property
    def collapse_im(self) -> np.ndarray: ...
    @property
    def censored_im(self) -> np.ndarray: ...
    @property
    def drift_limit(self) -> float: ...
    @property
    def exceedance_limits(self) -> tuple: ...
    @property
    def im_label(self) -> str: ...
    @property
    def n_records(self) -> int: ...
    def curve(self, r: int) -> tuple[np.ndarray, np.ndarray]: ...
    def fractiles(self, im_values=None, q=FRACTILES) -> np.ndarray: ...
    def exceedance(self, limits=None, im_values=None) -> np.ndarray: ...
    def collapse_table(self) -> np.ndarray: ...
    def collapse_fragility(self, method: str = ..., *, n_boot: int = ..., ci: float = ...,
                           seed: int | None = ...) -> LognormalFragility: ...
    def limit_fragility(self, limit: float, *, n_boot: int = ..., ci: float = ...,
                        seed: int | None = ...) -> LognormalFragility: ...


def plot_ida_curves(res: IDACurves, *, title: str | None = None):
    """IDA curves of every record (thin) with the 16/50/84 % fractiles of the records' peak drift
    ratio at each intensity (thick).

    Drift ratio in % on x, IM in g on y; a record's collapse is drawn as a flatline at its
    collapse intensity. Returns the figure.
    """
    fig, ax = plt.subplots(figsize=(7.2, 5.4))
    xmax = 100 * res.drift_limit * 1.15
    for r in range(res.n_records):
        im, edp = res.curve(r)
        ax.plot(100 * edp, im, color="0.6", lw=0.7, marker=".", ms=2.5)
        if np.isfinite(res.collapse_im[r]):
            ax.plot([100 * edp[-1], xmax], [res.collapse_im[r]] * 2, color="0.6", lw=0.7, ls="--")
    x = np.linspace(0.0, float(np.nanmax(res.point_im)), 200)[1:]
    fr = res.fractiles(x)
    for i, (q, color) in enumerate(zip(FRACTILES, ("tab:blue", "tab:red", "tab:green"))):
        ok = np.isfinite(fr[i])
        what = "median" if q == 50 else f"{q} % fractile"
        ax.plot(100 * fr[i][ok], x[ok], color=color, lw=2.2, label=f"{what} of the records' peak drift at an IM")
    ax.axvline(100 * res.drift_limit, color="k", lw=0.8, ls=":", label=f"drift limit {res.drift_limit:.0%}")
    ax.set_xlim(0, xmax)
    ax.set_ylim(0, None)
    ax.set_xlabel("peak inter-story drift ratio [%]")
    ax.set_ylabel(f"{res.im_label} [g]")
    ax.set_title(title or f"IDA curves: {res.building.name or 'clone'}, {res.n_records} records")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return fig


def plot_fragility(res: IDACurves, *, n_boot: int = 1000, ci: float = 0.90, seed: int | None = 0):
    """Collapse fragility: the records' collapse intensities (empirical CDF), the fraction
    collapsed at each grid level, both lognormal MLE fits, and a bootstrap band of the
    capacity fit. Returns the figure."""
    from .fragility import fit_capacities
    fig, ax = plt.subplots(figsize=(7.2, 5.0))
    cap, cen = res.collapse_im, res.censored_im
    obs = np.isfinite(cap)
    top = float(np.nanmax(np.concatenate([cap, cen, res.levels]))) * 1.3
    x = np.linspace(top / 400, top, 400)
    if obs.any():
        s = np.sort(cap[obs])
        ax.plot(s, (np.arange(s.size) + 0.5) / res.n_records, "o", ms=4, color="k",
                label="collapse IM of each record")
    frac = res.collapse_table().mean(axis=0)
    ax.plot(res.levels, frac, "s", ms=4, mfc="none", color="tab:purple", label="fraction collapsed at a level")
    for method, color in (("capacities", "tab:red"), ("counts", "tab:purple")):
        try:
            f = res.collapse_fragility(method, n_boot=0)
        except ValueError:
            continue
        ax.plot(x, f.probability(x), color=color, lw=2,
                label=f"MLE ({method}): median {f.median:.3g} g, beta {f.beta:.2f}")
    if n_boot > 0 and obs.sum() >= 2:
        rng = np.random.default_rng(seed)
        curves = []
        for _ in range(n_boot):
            idx = rng.integers(0, res.n_records, res.n_records)
            o = obs[idx]
            try:
                m, b = fit_capacities(cap[idx][o], cen[idx][~o])
            except ValueError:
                continue
            curves.append(_cdf(x, m, b))
        if len(curves) >= 10:
            lo, hi = np.percentile(np.array(curves), [50 * (1 - ci), 50 * (1 + ci)], axis=0)
            ax.fill_between(x, lo, hi, color="tab:red", alpha=0.18, lw=0, label=f"{ci:.0%} bootstrap band")
    ax.set_xlim(0, top)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel(f"{res.im_label} [g]")
    ax.set_ylabel("probability of collapse")
    ax.set_title(f"Collapse fragility ({res.n_records} records)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return fig


def plot_fragility_before_after(before: IDACurves, after: IDACurves, *, title: str | None = None):
    """Collapse fragility of a clone undamaged (``before``) and from the state its last event left
    it in (``after``, the aftershock fragility): each record's collapse intensity and the
    lognormal MLE of the capacities. Returns the figure."""
    fig, ax = plt.subplots(figsize=(7.2, 5.0))
    caps = [r.collapse_im for r in (before, after)]
    top = float(np.nanmax(np.concatenate([*caps, before.levels, after.levels, before.censored_im,
                                          after.censored_im]))) * 1.3
    x = np.linspace(top / 400, top, 400)
    for res, cap, name, color in ((before, caps[0], "before the event (undamaged)", "tab:blue"),
                                  (after, caps[1], "after the event (state carried)", "tab:red")):
        obs = np.isfinite(cap)
        if obs.any():
            s = np.sort(cap[obs])
            ax.plot(s, (np.arange(s.size) + 0.5) / res.n_records, "o", ms=4, color=color, alpha=0.7)
        try:
            f = res.collapse_fragility("capacities", n_boot=0)
        except ValueError:
            ax.plot([], [], "o", color=color, label=f"{name}: not fitted")
            continue
        ax.plot(x, f.probability(x), color=color, lw=2, label=f"{name}: median {f.median:.3g} g, beta {f.beta:.2f}")
    ax.set_xlim(0, top)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel(f"{before.im_label} [g]")
    ax.set_ylabel("probability of collapse")
    ax.set_title(title or f"Collapse fragility before and after the event ({before.n_records} records)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return fig


def plot_exceedance(res: IDACurves, *, n_boot: int = 0):
    """Probability of exceeding each drift-ratio limit vs IM: fractions at the grid levels
    (markers) and lognormal MLE fits of the records' IM capacities (lines)."""
    fig, ax = plt.subplots(figsize=(7.2, 5.0))
    top = float(res.levels[-1])
    x = np.linspace(top / 400, top, 400)
    exc = res.exceedance()
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, d in enumerate(res.exceedance_limits):
        c = colors[j % len(colors)]
        ax.plot(res.levels, exc[j], "o", ms=4, color=c)
        try:
            f = res.limit_fragility(d, n_boot=n_boot)
            ax.plot(x, f.probability(x), color=c, lw=1.8,
                    label=f"drift > {100 * d:g}%: median {f.median:.3g} g, beta {f.beta:.2f}")
        except ValueError:
            ax.plot([], [], "o", color=c, label=f"drift > {100 * d:g}% (not fitted)")
    ax.set_xlim(0, top)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel(f"{res.im_label} [g]")
    ax.set_ylabel("probability of exceedance")
    ax.set_title("Drift-limit exceedance")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return fig


def _cdf(x, median, beta):
    from scipy import stats
    return stats.norm.cdf(np.log(x / median) / beta)
