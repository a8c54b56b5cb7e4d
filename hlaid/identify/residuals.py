"""The residuals of replays against one measurement: what every refinement minimises.

A :class:`ReplayResiduals` is built once per measurement (its band-passed floor accelerations,
their scale, the ground motion the replays are driven by, and, for the errors-in-variables
criterion, the whitening by the tangent of one building's replay) and then maps any batch of
buildings to their residuals. It holds no parameter vector and no optimiser: a fit over several
measurements of one building stacks the residuals of several of them.

Accelerations are compared because they carry white sensor noise only, not the integration
errors of displacements; replay and measurement are band-passed alike.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import _progress
from .._threads import blas_threads
from ..errors import InputError
from ..measurement import Measurement, measured_ground
from ..model import Building
from ..signal import bandpass, cap_corner
from ..simulate import simulate_response
from .eiv import TangentWhitener, ground_memory, tangent_whitener

_CHUNK = 8
"""Replays band-passed together: filtering a whole Jacobian batch at once (0.2 GB for 101 replays
of a 20-story building) spent up to 4x longer allocating than filtering."""

CRITERIA = ("ignore", "tangent")
"""How the ground sensor's noise enters the residuals: ignored (least squares) or weighted out
through the replay's tangent (errors in variables, :mod:`hlaid.identify.eiv`)."""


class ReplayResiduals:
    """Normalised residuals of replays against one measurement's floor accelerations.

    Parameters
    ----------
    measurement : ground and floor accelerations
    band_hz : band of the compared accelerations [Hz] (its upper corner capped by the Nyquist rule)
    substeps : RK4 sub-steps per sample of the replays (they define the optimum)
    ground_noise : a name in :data:`CRITERIA`. ``"tangent"``: the residuals whitened against the
        ground noise carried to the floors by the time-varying tangent of the replay of ``at``
        (:func:`hlaid.identify.eiv.tangent_whitener`; every channel's noise a common fraction
        of its RMS). They are then low-passed only (``band_hz[0]`` is not used: with a high-pass
        the optimum moved) and compared at every ``stride``-th sample, three samples per period
        of the upper corner, with one more channel, the ground correction's
    at : with ``"tangent"``, the building whose replay's tangent weights the residuals
    tangent_substeps : RK4 sub-steps of the tangent's replay (a weighting: 2 do)
    memory_s : seconds of the floors' response kept after each ground sample in the tangent;
        None: :func:`~hlaid.identify.eiv.ground_memory` of ``at``
    max_mb : raise :class:`~hlaid.errors.TangentTooLargeError` where the tangent would take more
        than this many MiB (None: only the hard limit)
    at_state : ``(4*story,)`` the state the replay of ``at`` starts from, for its tangent (None:
        at rest)

    Attributes
    ----------
    channels : residual columns (the floors, and the ground correction's with ``"tangent"``)
    stride : samples between compared samples
    n_residuals : residuals per building, ``(samples / stride) * channels``
    """

    def __init__(self, measurement: Measurement, *, band_hz=(0.1, 20.0), substeps: int = 4,
                 ground_noise: str = "ignore", at: Building | None = None, tangent_substeps: int = 2,
                 memory_s: float | None = None, max_mb: float | None = None, at_state: np.ndarray | None = None):
        if ground_noise not in CRITERIA:
            raise InputError(f"ground_noise = {ground_noise!r}; expected one of {', '.join(map(repr, CRITERIA))}")
        dt = measurement.dt
        self.dt, self.substeps, self.criterion = dt, int(substeps), ground_noise
        self.hi = hi = cap_corner(band_hz[1], dt)
        if ground_noise == "tangent":  # its noise model has no high-pass (with one the optimum moved)
            band_hz = (0.0, band_hz[1])
        self.lo = float(band_hz[0])
        self.ground = measured_ground(measurement, hi)
        self.target = bandpass(np.asarray(measurement.floor_acc), dt, (self.lo, hi))
        self.scale = np.sqrt(np.mean(self.target**2, axis=0))
        self.whitener: TangentWhitener | None = None
        self.stride = 1
        if ground_noise == "tangent":
            if at is None:
                raise InputError("ground_noise = 'tangent' needs the building the tangent is taken at")
            _progress.step("[identify] tangent of the replay to the ground motion (errors in the input)")
            self.stride = max(int(1.0 / (3.0 * hi * dt)), 1)  # the low-passed residuals, sampled at 3x their corner
            memory = ground_memory(at) if memory_s is None else memory_s
            with blas_threads(1):  # its block products: 2-5x faster than on two threads beside other work
                self.whitener = tangent_whitener(at, measurement, self.ground, hi, self.scale, memory,
                                                 tangent_substeps, self.stride, max_mb, y0=at_state)
        self.channels = measurement.n_floors + (self.whitener is not None)
        self.n_residuals = len(range(0, self.target.shape[0], self.stride)) * self.channels

    def __call__(self, buildings: Sequence[Building], substeps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Residuals of ``buildings`` ``(batch, n_residuals)`` (rows time-major) and their plain
        costs ``(batch,)``: half the sum of squared normalised residuals before any whitening.
        A replay that diverged gets residuals of 1e3 and an infinite plain cost.

        ``substeps`` : RK4 sub-steps of these replays (default the object's)."""
        res, plain, _ = self.run(buildings, substeps)
        return res, plain

    def run(self, buildings: Sequence[Building], substeps: int | None = None, *, y0: np.ndarray | None = None,
            tail_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`__call__`, the replays starting from ``y0`` ``(batch, 4*story)`` (None: at
        rest) and running ``tail_s`` seconds of free vibration past the record, and the state
        each ends in ``(batch, 4*story)`` (NaN where a replay diverged)."""
        r = simulate_response(list(buildings), self.ground, substeps=self.substeps if substeps is None else substeps,
                              outputs="acc", y0=y0, free_vibration=tail_s)
        n_time = self.target.shape[0]
        acc = r.acc
        assert acc is not None  # outputs="acc" keeps them
        acc = acc[:, :n_time] if acc.shape[1] > n_time else acc
        acc[r.status != 0] = 0.0  # only a stopped replay has NaN (after its stop); no copy of the rest
        res = np.empty((len(buildings), self.n_residuals))
        plain = np.empty(len(buildings))

        def chunk(i):  # a few replays at a time: the same values, without fresh large temporaries
            part = bandpass(acc[i:i + _CHUNK], self.dt, (self.lo, self.hi), axis=1)
            part -= self.target[None]
            part /= self.scale
            plain[i:i + _CHUNK] = 0.5 * np.sum(part.reshape(len(part), -1) ** 2, axis=1)
            if self.whitener is not None:
                part = self.whitener(part[:, ::self.stride])
            res[i:i + _CHUNK] = part.reshape(len(part), -1)

        starts = range(0, len(buildings), _CHUNK)
        with blas_threads(1):  # the whitener's products, one thread each: the chunks share the cores
            if len(starts) == 1:
                chunk(0)
            else:  # scipy's filter releases the GIL: the chunks share the cores (disjoint rows of res)
                with ThreadPoolExecutor(min(len(starts), os.cpu_count() or 1)) as ex:
                    list(ex.map(chunk, starts))
        res[r.status != 0] = 1e3  # a diverged trial is far from the data
        plain[r.status != 0] = np.inf
        final = np.array(r.final_state, dtype=float)
        final[r.status != 0] = np.nan
        return res, plain, final
