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
                        title: str = "", annotate: list[str] | None = None):
    """Time histories per story: ``series`` is a list of ``(time, story)`` arrays."""
    n = series[0].shape[1]
    fig, axes = story_axes(n, ncols=1, size=(11, 2.3), sharex=True)
    for i, ax in enumerate(axes):
        for s, lab in zip(series, labels):
            ax.plot(t[: s.shape[0]], s[:, i], lw=0.8, label=lab)
        ax.set_ylabel(f"story {i + 1}\n{ylabel}")
        ax.grid(alpha=0.3)
        if annotate:
            ax.text(0.99, 0.9, annotate[i], transform=ax.transAxes, ha="right", va="top", fontsize=9,
                    bbox={"fc": "white", "alpha": 0.7, "lw": 0})
    axes[0].legend(fontsize=8, loc="upper left")
    axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    return fig
