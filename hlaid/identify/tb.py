"""TensorBoard logging of an identification run (no-op without a log folder)."""

from __future__ import annotations

import numpy as np


class TBLogger:
    """Thin wrapper over :class:`torch.utils.tensorboard.SummaryWriter`."""

    def __init__(self, log_dir: str | None):
        self.writer = None
        if log_dir:
            from torch.utils.tensorboard import SummaryWriter
            self.writer = SummaryWriter(log_dir=str(log_dir))

    def scalar(self, tag: str, value: float, step: int = 0) -> None:
        if self.writer is not None and value is not None and np.isfinite(value):
            self.writer.add_scalar(tag, float(value), step)

    def text(self, tag: str, text: str, step: int = 0) -> None:
        if self.writer is not None:
            self.writer.add_text(tag, text, step)

    def confusion(self, tag: str, matrix: np.ndarray, edges: np.ndarray, step: int = 0) -> None:
        if self.writer is None:
            return
        from ..plots import plt
        fig, ax = plt.subplots(figsize=(4.5, 4))
        m = matrix / np.maximum(matrix.sum(axis=1, keepdims=True), 1)
        ax.imshow(m, cmap="Blues", vmin=0, vmax=1)
        labels = [f"{a:.2f}" for a in 0.5 * (edges[:-1] + edges[1:])]
        ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=6)
        ax.set_yticks(range(len(labels)), labels, fontsize=6)
        ax.set_xlabel("predicted bin centre")
        ax.set_ylabel("true bin centre")
        fig.tight_layout()
        self.writer.add_figure(tag, fig, step)

    def features(self, tag: str, X: np.ndarray, labels: np.ndarray, edges: np.ndarray, step: int = 0) -> None:
        """A few example feature vectors per class."""
        if self.writer is None or X.shape[0] == 0:
            return
        from ..plots import plt
        fig, ax = plt.subplots(figsize=(5, 3.5))
        cmap = plt.get_cmap("viridis")
        n = len(edges) - 1
        for c in range(n):
            rows = np.flatnonzero(labels == c)[:3]
            for r in rows:
                ax.plot(X[r], color=cmap(c / max(n - 1, 1)), lw=0.8, alpha=0.8)
        ax.set_xlabel("feature (segment; last: ke/k0)")
        ax.set_ylabel("value")
        fig.tight_layout()
        self.writer.add_figure(tag, fig, step)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
