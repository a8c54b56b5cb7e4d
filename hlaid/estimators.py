"""Identifiers behind one scikit-learn estimator interface.

``Identifier(**settings).fit(measurement)`` returns the identifier with ``clone_`` (a
:class:`~hlaid.clone.Clone`) and ``fit_seconds_``; ``predict(motion)`` replays the clone and
``score(measurement)`` rates it. Every identifier is a :class:`sklearn.base.BaseEstimator`:
``__init__`` stores its keyword parameters and nothing else, so ``get_params``,
``set_params`` and :func:`sklearn.base.clone` work, and fitted attributes end in ``_``.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Sequence

import numpy as np
import sklearn.exceptions
from sklearn.base import BaseEstimator

from .clone import Clone
from .measurement import Measurement, measured_ground
from .motions import GroundMotion
from .signal import bandpass, cap_corner
from .simulate import SimulationResult, simulate_response


class NotFittedError(sklearn.exceptions.NotFittedError):
    """The identifier has not been fitted yet (a scikit-learn ``NotFittedError``)."""


class BaseIdentifier(BaseEstimator):
    """Base class: ``__init__`` stores settings only; ``fit(measurement)`` sets ``clone_``."""

    def get_params(self, deep: bool = True) -> dict:
        """The ``__init__`` parameters, in the order of its signature (so that ``repr`` and the
        clone's provenance read like the call)."""
        params = super().get_params(deep=deep)
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {n: params.pop(n) for n in names} | params

    def set_params(self, **params) -> BaseIdentifier:
        known = self.get_params(deep=False)
        for k in params:
            if k not in known:
                raise ValueError(f"{type(self).__name__} has no parameter {k!r}; expected one of {list(known)}")
        super().set_params(**params)
        return self

    def __repr__(self, N_CHAR_MAX: int = 700) -> str:  # every parameter, not only those changed
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params(deep=False).items())
        return f"{type(self).__name__}({args})"

    def __sklearn_is_fitted__(self) -> bool:
        return hasattr(self, "clone_")

    def _check_fitted(self) -> None:
        if not hasattr(self, "clone_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit(measurement) first")

    def fit(self, measurement: Measurement) -> BaseIdentifier:  # pragma: no cover - abstract
        raise NotImplementedError

    def predict(self, motion: GroundMotion, *, scale: float = 1.0, substeps: int = 4) -> SimulationResult:
        """Replay the identified clone under ``motion`` (batch simulator)."""
        self._check_fitted()
        return simulate_response(self.clone_.building, motion, scale, substeps=substeps)

    def score(self, measurement: Measurement) -> float:
        """Mean correlation coefficient between the replayed and the measured floor
        accelerations (band 0.1-20 Hz)."""
        self._check_fitted()
        hi = cap_corner(20.0, measurement.dt)
        g = measured_ground(measurement, hi, name="")
        replayed = self.predict(g).acc
        assert replayed is not None  # predict keeps the histories
        acc = bandpass(replayed[0], measurement.dt, (0.1, hi))
        meas = bandpass(np.asarray(measurement.floor_acc), measurement.dt, (0.1, hi))
        from .identify.replaycheck import corrcoef
        return float(np.mean(corrcoef(acc, meas)))


class HLASVMIdentifier(BaseIdentifier):
    """The paper's method (:func:`hlaid.identify_clone`): HLA, eq 12-17 regressions,
    RBF SVMs coarse to fine, outer loop, then the refinement the config names.

    Parameters
    ----------
    config : :class:`~hlaid.identify.IdentifyConfig` or None for the defaults
    refine : a name in :data:`hlaid.identify.REFINERS` (overrides ``config.refine.method``;
        ``"none"``: the paper's method alone); None: as the config says
    cache_dir : classifier cache (None: the default cache; ``""``: none)
    tensorboard : TensorBoard folder or None

    Attributes
    ----------
    clone_ : the identified clone; result_ : the full IdentificationResult; fit_seconds_
    """

    def __init__(self, *, config=None, refine: str | None = None, cache_dir: str | None = None,
                 tensorboard: str | None = None):
        self.config = config
        self.refine = refine
        self.cache_dir = cache_dir
        self.tensorboard = tensorboard

    def fit(self, measurement: Measurement | Sequence[Measurement]) -> HLASVMIdentifier:
        """Identify the clone from one measurement, or from several of one building in time order
        (:func:`hlaid.identify_clone`)."""
        import dataclasses

        from .events.identify import identify_clone
        from .identify.config import IdentifyConfig
        cfg = self.config or IdentifyConfig()
        if self.refine is not None:
            cfg = dataclasses.replace(cfg, refine=dataclasses.replace(cfg.refine, method=self.refine))
        t0 = time.perf_counter()
        self.result_ = identify_clone(measurement, cfg, tensorboard=self.tensorboard, cache_dir=self.cache_dir)
        self.clone_: Clone = self.result_.clone
        self.fit_seconds_ = time.perf_counter() - t0
        return self
