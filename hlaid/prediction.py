"""A clone's prediction of an event it has not seen, against what the building recorded.

:func:`predict_event` replays a clone under an event's recorded ground motion, from the state its
last event left it in or undamaged (``start="auto"``, the default: carried unless an update
found the clone's last event better explained from an undamaged start), and compares the floor
displacements relative to the ground with the measured ones in one band (correlation ``r`` per
floor, peak inter-story drift errors per story). With the clone's uncertainty, an ensemble of
clones drawn from it gives a predictive band and the share of the measured response inside it.

The measured displacements are the file's where it has them, else the accelerations integrated
by HLA's own code; the clone's response goes through the same path (band-passed displacements,
or its absolute accelerations integrated alike), so a clone equal to the building scores 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import signal as sg
from .errors import InputError
from .measurement import Measurement
from .motions import GroundMotion
from .units import G_MM_S2

if TYPE_CHECKING:
    from .clone import Clone
    from .hla.config import HLAConfig

BAND_LEVEL = 0.9
"""Central probability of the predictive band."""


@dataclass(frozen=True, eq=False)
class EventPrediction:
    """A clone replayed under one event, against what was measured.

    Attributes
    ----------
    event : the event's name; source : its file
    start : ``"carried"`` (the clone's state after its last event) or ``"undamaged"``
    band_hz : band of the compared displacements [Hz]
    r : (floor,) correlation of predicted and measured displacement relative to the ground
    peak_drift_measured, peak_drift_predicted : (story,) peak inter-story drift [mm]
    peak_drift_error : (story,) ``predicted / measured - 1``
    r_true : (floor,) correlation of the predicted with the true displacement (simulated data,
        unfiltered; None for recorded data)
    coverage : (floor,) share of the measured displacement inside the predictive band (None
        without an ensemble); with :attr:`band_width`, the band's width
    n_ensemble : clones in the ensemble (0: none)
    status : the replay's simulator status (0 ok)
    time : (time,) [s]; disp_measured, disp_predicted : (time, floor) [mm]
    band_lower, band_upper : (time, floor) the predictive band [mm] (None without an ensemble)
    """

    event: str
    source: str
    start: str
    band_hz: tuple[float, float]
    pga_g: float
    r: np.ndarray
    peak_drift_measured: np.ndarray
    peak_drift_predicted: np.ndarray
    peak_drift_error: np.ndarray
    r_true: np.ndarray | None
    coverage: np.ndarray | None
    n_ensemble: int
    status: int
    time: np.ndarray = field(repr=False)
    disp_measured: np.ndarray = field(repr=False)
    disp_predicted: np.ndarray = field(repr=False)
    band_lower: np.ndarray | None = field(default=None, repr=False)
    band_upper: np.ndarray | None = field(default=None, repr=False)

    @property
    def r_mean(self) -> float:
        return float(np.mean(self.r))

    @property
    def band_width(self) -> np.ndarray | None:
        """(floor,) mean width of the predictive band over twice the measured RMS (None without
        an ensemble): read coverage with it, a band wider than the response covers anything."""
        if self.band_lower is None or self.band_upper is None:
            return None
        rms = np.sqrt(np.mean(self.disp_measured**2, axis=0))
        return np.mean(self.band_upper - self.band_lower, axis=0) / (2.0 * rms)

    def to_dict(self) -> dict:
        out = {"format": "hlaid-prediction", "version": 1, "event": self.event, "source": self.source or None,
               "start": self.start, "band_hz": list(self.band_hz), "pga_g": self.pga_g, "r": self.r.tolist(),
               "r_mean": self.r_mean, "peak_drift_measured": self.peak_drift_measured.tolist(),
               "peak_drift_predicted": self.peak_drift_predicted.tolist(),
               "peak_drift_error": self.peak_drift_error.tolist(),
               "r_true": None if self.r_true is None else self.r_true.tolist(), "n_ensemble": self.n_ensemble,
               "band_level": BAND_LEVEL if self.n_ensemble else None,
               "coverage": None if self.coverage is None else self.coverage.tolist(),
               "coverage_mean": None if self.coverage is None else float(np.mean(self.coverage)),
               "band_width": None if self.band_width is None else self.band_width.tolist(),
               "status": self.status}
        return out


def measured_displacement(meas: Measurement, band_hz, order: int = 4) -> tuple[np.ndarray, bool]:
    """``(time, floor)`` measured displacement relative to the ground in ``band_hz`` [mm]: the
    file's, band-passed, or the accelerations integrated twice; and whether it was integrated."""
    if meas.floor_disp is not None:
        return sg.bandpass(np.asarray(meas.floor_disp), meas.dt, band_hz, order), False
    rel = np.asarray(meas.floor_acc) - np.asarray(meas.ground_acc)[:, None]
    return sg.integrate_twice(sg.bandpass(rel, meas.dt, band_hz, order), meas.dt, band_hz, order)[1], True


def _compared(sim_disp: np.ndarray, sim_acc: np.ndarray, ground: np.ndarray, dt: float, band, integrated: bool,
              order: int) -> np.ndarray:
    """The clone's displacement as the measured one was obtained: band-passed, or its absolute
    accelerations integrated alike. ``sim_*`` ``(batch, time, floor)``."""
    if not integrated:
        return sg.bandpass(np.nan_to_num(sim_disp), dt, band, order, axis=1)
    rel = np.nan_to_num(sim_acc) - ground[None, :, None]
    out = np.empty_like(rel)
    for k in range(rel.shape[0]):
        out[k] = sg.integrate_twice(sg.bandpass(rel[k], dt, band, order), dt, band, order)[1]
    return out


def identification_misfit(clone: Clone) -> np.ndarray | float:
    """How far the clone's replays of its own events were from the measured displacements, per
    floor a fraction of their RMS: ``sqrt(2 (1 - R))`` of the replay's correlation ``R`` (the
    relative RMS difference of two signals of equal RMS), the mean over its events; 0 where the
    clone does not say."""
    d = clone.diagnostics or {}
    found = [e.get("R_measured") for e in ((d.get("joint") or {}).get("events") or []) if isinstance(e, dict)]
    if not found and isinstance(d.get("replay"), dict):
        found = [d["replay"].get("r_measured")]
    rs = [np.asarray(r, dtype=float) for r in found if isinstance(r, list) and r]
    if not rs or len({r.shape for r in rs}) != 1:
        return 0.0
    return np.mean([np.sqrt(np.clip(2.0 * (1.0 - r), 0.0, None)) for r in rs], axis=0)


def predict_event(clone: Clone, meas: Measurement, *, band_hz=None, start: str = "auto", n_ensemble: int = 0,
                  seed: int = 0, hla_config: HLAConfig | None = None, misfit: float | None = None) -> EventPrediction:
    """Replay ``clone`` under ``meas``'s ground motion and compare with what was measured.

    Parameters
    ----------
    clone : the clone (its stories must match the measurement's floors)
    meas : the event
    band_hz : band of the comparison [Hz] (None: HLA's band of ``meas`` under ``hla_config``,
        the default HLA settings when None); the ground motion is low-passed at its upper corner
    start : ``"carried"``: from the state the clone's last event left it in (undamaged where it
        has none); ``"undamaged"``: at rest; ``"auto"``: :meth:`hlaid.clone.Clone.initial_state`
    n_ensemble : clones drawn from ``clone.uncertainty`` for the predictive band (0: none). The
        band holds the central :data:`BAND_LEVEL` of the ensemble's predictions, widened on each
        side by the same quantile of a Gaussian error of ``misfit`` times each floor's predicted RMS:
        the parameters' uncertainty and the model's own misfit (as the clone replayed its events)
    seed : of the draws
    misfit : the model's error as a fraction of a floor's RMS, one number or ``(floor,)`` (None:
        :func:`identification_misfit`, what the clone missed its own events by)
    """
    from .hla.analysis import resolved_band
    from .hla.config import HLAConfig
    from .simulate import simulate_response

    b = clone.building
    src = meas.source or None
    if meas.n_floors != b.n_stories:
        raise InputError(f"{meas.n_floors} floor channels, but the clone has {b.n_stories} stories: the measurement "
                         "is not of this building", source=src)
    dt = meas.dt
    if band_hz is None:
        band_hz = resolved_band(meas, hla_config or HLAConfig())
    lo, hi = float(band_hz[0]), sg.cap_corner(float(band_hz[1]), dt)
    if not 0 <= lo < hi:
        raise InputError(f"band {lo:g}-{band_hz[1]:g} Hz; expected low < high, below the Nyquist frequency",
                         source=src)
    band = (lo, hi)
    order = (hla_config or HLAConfig()).preprocess.order
    ground = sg.bandpass(np.asarray(meas.ground_acc), dt, (0.0, hi), order)
    motion = GroundMotion(dt=dt, acc=ground, name=meas.name)
    y0 = clone.initial_state(start)
    buildings = [b]
    if n_ensemble:
        from .uncertainty.ensemble import clone_ensemble

        buildings += clone_ensemble(clone, n_ensemble, seed=seed)
    sim = simulate_response(buildings, motion, y0=y0)
    assert sim.disp is not None and sim.acc is not None
    measured, integrated = measured_displacement(meas, band, order)
    predicted = _compared(sim.disp, sim.acc, ground, dt, band, integrated, order)
    from .hla import preprocess as pp
    from .identify.replaycheck import corrcoef

    r = corrcoef(predicted[0], measured)
    r_true = None if meas.truth is None else corrcoef(np.nan_to_num(sim.disp[0]), meas.truth.disp)
    pm = np.max(np.abs(pp.story_drift(measured)), axis=0)
    pk = np.max(np.abs(pp.story_drift(predicted[0])), axis=0)
    lower = upper = coverage = None
    if n_ensemble:
        from scipy.stats import norm

        q = 0.5 * (1.0 - BAND_LEVEL)
        lower, upper = np.quantile(predicted[1:], [q, 1.0 - q], axis=0)
        sigma = identification_misfit(clone) if misfit is None else np.asarray(misfit, dtype=float)
        pad = float(norm.ppf(1.0 - q)) * np.asarray(sigma) * np.sqrt(np.mean(predicted[0] ** 2, axis=0))
        lower, upper = lower - pad, upper + pad
        coverage = np.mean((measured >= lower) & (measured <= upper), axis=0)
    return EventPrediction(event=meas.name, source=meas.source, start="undamaged" if y0 is None else "carried",
                           band_hz=band, pga_g=float(np.max(np.abs(meas.ground_acc)) / G_MM_S2), r=r,
                           peak_drift_measured=pm, peak_drift_predicted=pk, peak_drift_error=pk / pm - 1.0,
                           r_true=r_true, coverage=coverage, n_ensemble=int(n_ensemble), status=int(sim.status[0]),
                           time=np.arange(meas.n_samples) * dt, disp_measured=measured, disp_predicted=predicted[0],
                           band_lower=lower, band_upper=upper)
