"""The training samples of the alpha/p classifiers (:mod:`hlaid.identify.pathtrain` draws them)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrainingSet:
    """Samples of one story.

    Attributes
    ----------
    X : (sample, feature) features (segment slopes over ``k0``)
    alpha, p : (sample,) the values each sample was drawn with (the class targets)
    sim : (sample,) which draw each sample came from (the held-out split is by draw)
    """

    X: np.ndarray
    alpha: np.ndarray
    p: np.ndarray
    sim: np.ndarray

    def __len__(self) -> int:
        return int(self.X.shape[0])
