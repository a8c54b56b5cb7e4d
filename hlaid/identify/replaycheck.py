"""Checking a clone against the measurement it came from: replayed displacement and stiffness."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hla import HLAResult
from ..measurement import Measurement, measured_ground
from ..model import Building
from ..record import FitReplay
from ..signal import bandpass
from ..simulate import simulate_response


@dataclass(frozen=True)
class ReplayCheck:
    """Replay of a clone on the measured ground motion.

    Attributes
    ----------
    r_measured : (story,) correlation coefficient between the measured (integrated,
        band-passed) and the replayed floor displacement relative to the ground
    r_true : (story,) the same against the true displacement (simulated data only)
    stiffness_error : (story,) mean relative difference between the clone's ke(t) and the
        HLA's ke(t) over the half cycles
    disp : (time, floor) replayed floor displacements [mm]; ke : (time, story) clone ke(t)
    """

    r_measured: np.ndarray
    r_true: np.ndarray | None
    stiffness_error: np.ndarray
    disp: np.ndarray
    ke: np.ndarray

    def to_dict(self) -> dict:
        return {"r_measured": self.r_measured.tolist(),
                "r_true": None if self.r_true is None else self.r_true.tolist(),
                "stiffness_error": self.stiffness_error.tolist()}

    def record(self, name: str | None = None) -> FitReplay:
        """What the clone keeps of it (:class:`~hlaid.record.FitReplay`), for the event ``name``."""
        return FitReplay.from_dict({"name": name or None, **self.to_dict()})


def corrcoef(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Column-wise Pearson correlation of two ``(time, k)`` arrays."""
    a = a - a.mean(axis=0)
    b = b - b.mean(axis=0)
    return np.sum(a * b, axis=0) / np.sqrt(np.sum(a * a, axis=0) * np.sum(b * b, axis=0))


def replay_check(building: Building, measurement: Measurement, hla_result: HLAResult,
                 y0: np.ndarray | None = None) -> ReplayCheck:
    """Replay ``building`` under the measured ground motion (from the state ``y0``, None: at rest)
    and compare with HLA and data."""
    from ..hla.analysis import floor_motion

    dt = measurement.dt
    band = hla_result.band_hz
    ground = measured_ground(measurement, band[1])
    r = simulate_response(building, ground, y0=y0)
    assert r.disp is not None and r.eta is not None  # simulate keeps the histories by default
    disp = r.disp[0]
    _, _, _, meas_disp = floor_motion(measurement, hla_result.config)
    r_meas = corrcoef(bandpass(disp, dt, band), meas_disp)
    r_true = None if measurement.truth is None else corrcoef(disp, measurement.truth.disp)
    ke = building.elastic_stiffness(r.eta[0])
    err = []
    for i, s in enumerate(hla_result.stories):
        hc = s.half_cycles
        err.append(float(np.mean(np.abs(ke[hc.start, i] / hc.ke - 1.0))) if len(hc) else np.nan)
    return ReplayCheck(r_measured=r_meas, r_true=r_true, stiffness_error=np.asarray(err), disp=disp, ke=ke)
