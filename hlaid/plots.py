"""Plotting helpers shared by every command (matplotlib, headless)."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ._fileio import atomic_write  # noqa: E402


def story_axes(n: int, *, ncols: int | None = None, size=(4.2, 3.4), sharex=False, sharey=False,
               layout: str | None = None):
    """A figure with one panel per story; returns ``(fig, axes)`` with ``axes`` a flat list."""
    ncols = ncols or min(n, 3)
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(size[0] * ncols, size[1] * nrows), squeeze=False,
                             sharex=sharex, sharey=sharey, layout=layout)
    axes = axes.ravel().tolist()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes[:n]


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Save a figure atomically as PNG and close it."""
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
    finally:
        plt.close(fig)


def plot_loops(drift: np.ndarray, force: np.ndarray, *, title: str = "", force_label: str = "story force [kN]",
               force_scale: float = 1e-3, labels: list[str] | None = None):
    """Force-drift loops, one panel per story. ``drift``/``force`` are ``(time, story)`` or a
    list of such arrays drawn on top of each other (labelled)."""
    drifts = drift if isinstance(drift, list) else [drift]
    forces = force if isinstance(force, list) else [force]
    n = drifts[0].shape[1]
    fig, axes = story_axes(n)
    for i, ax in enumerate(axes):
        for j, (x, f) in enumerate(zip(drifts, forces)):
            ax.plot(x[:, i], f[:, i] * force_scale, lw=0.6 if j == 0 else 0.9,
                    label=labels[j] if labels else None, alpha=0.9)
        ax.set_title(f"story {i + 1}")
        ax.set_xlabel("inter-story drift [mm]")
        ax.set_ylabel(force_label)
        ax.grid(alpha=0.3)
        if labels:
            ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def plot_time_histories(t: np.ndarray, series: list[np.ndarray], labels: list[str], *, ylabel: str,
                        title: str = "", annotate: list[str] | None = None, panel: str = "story"):
    """Time histories, one panel per column: ``series`` is a list of ``(time, column)`` arrays whose
    columns are stories or floors (``panel`` names them: ``"story"`` or ``"floor"``)."""
    n = series[0].shape[1]
    fig, axes = story_axes(n, ncols=1, size=(11, 2.3), sharex=True)
    for i, ax in enumerate(axes):
        for s, lab in zip(series, labels):
            ax.plot(t[: s.shape[0]], s[:, i], lw=0.8, label=lab)
        ax.set_ylabel(f"{panel} {i + 1}\n{ylabel}")
        ax.grid(alpha=0.3)
        if annotate:
            ax.text(0.99, 0.9, annotate[i], transform=ax.transAxes, ha="right", va="top", fontsize=9,
                    bbox={"fc": "white", "alpha": 0.7, "lw": 0})
    axes[0].legend(fontsize=8, loc="upper left")
    axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    return fig


def plot_measured_predicted(time: np.ndarray, measured: np.ndarray, predicted: np.ndarray, r: np.ndarray, *,
                            label: str, title: str, levels: list[str] | None = None, pad_s: float = 3.0,
                            band: tuple[np.ndarray, np.ndarray, str] | None = None):
    """Measured (black) against predicted (dashed) floor displacement, one panel per floor with
    its R, over the strong part of the record (roof above 10 % of its peak, ``pad_s`` around).
    ``measured``/``predicted`` are ``(time, floor)`` [mm]; ``band`` ``(lower, upper, label)`` a
    predictive band drawn over the same window."""
    roof = np.abs(measured[:, -1])
    idx = np.flatnonzero(roof > 0.1 * roof.max())
    pad = int(pad_s / (time[1] - time[0]))
    w = slice(max(idx[0] - pad, 0), min(idx[-1] + pad, roof.size))
    fig, axes = story_axes(measured.shape[1], ncols=1, size=(9, 1.9), sharex=True)
    for i, ax in enumerate(axes):
        if band is not None:
            ax.fill_between(time[w], band[0][w, i], band[1][w, i], color="C3", alpha=0.2, lw=0,
                            label=band[2] if i == 0 else None)
        ax.plot(time[w], measured[w, i], color="k", lw=0.7, label="measured")
        ax.plot(time[w], predicted[w, i], color="C3", lw=0.7, ls="--", label=label)
        ax.set_xlim(time[w][0], time[w][-1])
        ax.set_ylabel(f"{levels[i] if levels else f'floor {i + 1}'}\n[mm]", fontsize=8)
        ax.text(0.99, 0.92, f"R = {r[i]:.3f}", transform=ax.transAxes, ha="right", va="top", fontsize=8,
                bbox={"fc": "white", "alpha": 0.8, "lw": 0})
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper left", ncol=3)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title, fontsize=10)
    return fig


def plot_prediction(p, *, title: str, levels: list[str] | None = None):
    """A clone's prediction of an event (:class:`hlaid.events.predict.Prediction`): measured
    against predicted floor displacement per floor, with the predictive band where there is one
    (over the same window as the traces)."""
    band = None if p.band is None else (p.band.lower, p.band.upper, f"{p.band.n_ensemble}-clone band")
    return plot_measured_predicted(p.time, p.disp_measured, p.disp_predicted, p.r, label=f"clone ({p.start} state)",
                                   title=f"{title} ({p.band_hz[0]:.2g}-{p.band_hz[1]:.2g} Hz)", levels=levels,
                                   band=band)

