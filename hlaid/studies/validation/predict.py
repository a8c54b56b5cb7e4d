"""A clone replayed under a recorded event and compared with what was measured."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from ... import _progress
from ... import signal as sg
from ...clone import Clone
from ...errors import InputError
from ...hla import HLAConfig, HLAResult, run_hla
from ...hla import preprocess as pp
from ...hla.analysis import floor_motion, resolved_band
from ...identify.replaycheck import corrcoef
from ...measurement import Measurement
from ...motions import GroundMotion
from ...simulate import simulate_response
from ...units import G_MM_S2


@dataclass(frozen=True, eq=False)
class Prediction:
    """A clone replayed under one event, against what was measured.

    Attributes
    ----------
    structure, identified_from, event, kind : which clone, which event
    self_replay : the event the clone was identified from
    pga_g : peak ground acceleration of the event [g]
    band_hz : band of the compared displacements [Hz]
    r : (floor,) correlation of predicted and measured displacement relative to the ground
    r_broadband : (floor,) the same with the band's upper corner raised to 20 Hz (below 0.45
        of the sampling rate): what the measured displacement holds above the compared band
        counts against the clone
    peak_drift_measured, peak_drift_predicted : (story,) peak inter-story drift [mm] (band-passed)
    peak_drift_error : (story,) ``predicted / measured - 1``
    stiffness_error : (story,) mean over HLA half cycles of ``|ke_clone / ke_HLA - 1|`` (NaN
        when HLA of the event failed)
    status : simulator status (0 ok, 2 diverged)
    time, disp_measured, disp_predicted : (time,), (time, floor) [s, mm] (not serialised)
    drift_predicted, force_predicted, ke_clone : (time, story) clone drift, spring force, ke(t)
    hla : the HLA of the event (None when it failed)
    """

    structure: str
    identified_from: str
    event: str
    kind: str
    self_replay: bool
    pga_g: float
    band_hz: tuple[float, float]
    r: np.ndarray
    r_broadband: np.ndarray
    peak_drift_measured: np.ndarray
    peak_drift_predicted: np.ndarray
    peak_drift_error: np.ndarray
    stiffness_error: np.ndarray
    status: int
    time: np.ndarray = field(repr=False)
    disp_measured: np.ndarray = field(repr=False)
    disp_predicted: np.ndarray = field(repr=False)
    drift_predicted: np.ndarray = field(repr=False)
    force_predicted: np.ndarray = field(repr=False)
    ke_clone: np.ndarray = field(repr=False)
    hla: HLAResult | None = field(default=None, repr=False)

    def summary(self) -> dict:
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in
                (("structure", self.structure), ("identified_from", self.identified_from), ("event", self.event),
                 ("kind", self.kind), ("self_replay", self.self_replay), ("pga_g", self.pga_g),
                 ("band_hz", list(self.band_hz)), ("r", self.r), ("r_mean", float(np.mean(self.r))),
                 ("r_broadband", self.r_broadband),
                 ("peak_drift_measured", self.peak_drift_measured), ("peak_drift_predicted", self.peak_drift_predicted),
                 ("peak_drift_error", self.peak_drift_error), ("stiffness_error", self.stiffness_error),
                 ("stiffness_error_mean", _nanmean(self.stiffness_error)), ("status", self.status))}


def _nanmean(x) -> float | None:
    x = np.asarray(x, dtype=float)
    return float(np.nanmean(x)) if np.isfinite(x).any() else None


def _with_band(cfg: HLAConfig, band) -> HLAConfig:
    return cfg if band is None else dataclasses.replace(
        cfg, preprocess=dataclasses.replace(cfg.preprocess, band_hz=tuple(band)))


def predict_event(clone: Clone, meas: Measurement, hla_config: HLAConfig, *, compare_band_hz=None,
                  input_lowpass_hz: float | None = None, labels: tuple[str, str, str, str] = ("", "", "", ""),
                  self_replay: bool = False) -> Prediction:
    """Replay ``clone`` under ``meas``'s ground motion and compare with what was measured.

    Parameters
    ----------
    clone : the clone (its masses must be the ones ``hla_config`` gives ``meas``)
    meas : the event
    hla_config : HLA settings of the structure (mass ratios, damping handling, band)
    compare_band_hz : band of the comparison and of the event's HLA (None: HLA's band)
    input_lowpass_hz : low-pass of the ground motion (None: the band's upper corner)
    labels : ``(structure, identified_from, event, kind)``
    """
    cfg = _with_band(hla_config, compare_band_hz)
    dt = meas.dt
    try:
        res = run_hla(meas, cfg)
        band = tuple(res.band_hz)
    except InputError as exc:  # too weak or too short for HLA: no stiffness comparison
        _progress.warn(f"{labels[0]}/{labels[2]}: HLA failed ({exc}); no stiffness comparison")
        res, band = None, tuple(resolved_band(meas, cfg))
        cfg = _with_band(cfg, band)
    hi_in = sg.cap_corner(input_lowpass_hz or band[1], dt)
    ground = GroundMotion(dt=dt, acc=sg.bandpass(np.asarray(meas.ground_acc), dt, (0.0, hi_in), cfg.preprocess.order),
                          name=meas.name)
    sim = simulate_response(clone.building, ground)  # full outputs: acc, eta and force are set
    # the clone's response goes through what the measured one went through: its displacement
    # band-passed when the data hold displacements, else its accelerations integrated
    integrated = cfg.preprocess.displacement == "integrate" or (cfg.preprocess.displacement == "auto" and
                                                               meas.floor_disp is None)
    twin = dataclasses.replace(meas, ground_acc=ground.acc, floor_acc=np.nan_to_num(cast(np.ndarray, sim.acc)[0]),
                               floor_disp=None, truth=None, mass=None)

    def compare(b):
        c = _with_band(cfg, b)
        _, _, _, dm = floor_motion(meas, c)
        if integrated:
            dp = floor_motion(twin, c)[3]
        else:
            dp = sg.bandpass(np.nan_to_num(sim.disp[0]), dt, b, c.preprocess.order)
        return dm, dp

    disp_meas, dp = compare(band)
    r = corrcoef(dp, disp_meas)
    r_broad = corrcoef(*compare((band[0], max(band[1], sg.cap_corner(20.0, dt)))))
    xm, xp = pp.story_drift(disp_meas), pp.story_drift(dp)
    pm, pk = np.max(np.abs(xm), axis=0), np.max(np.abs(xp), axis=0)
    ke = clone.building.elastic_stiffness(np.nan_to_num(cast(np.ndarray, sim.eta)[0], nan=1.0))
    err = np.full(clone.building.n_stories, np.nan)
    if res is not None:
        for i, s in enumerate(res.stories):
            hc = s.half_cycles
            if len(hc):
                err[i] = float(np.mean(np.abs(ke[hc.start, i] / hc.ke - 1.0)))
    return Prediction(structure=labels[0], identified_from=labels[1], event=labels[2], kind=labels[3],
                      self_replay=self_replay, pga_g=float(np.max(np.abs(meas.ground_acc)) / G_MM_S2),
                      band_hz=cast("tuple[float, float]", band),
                      r=r, r_broadband=r_broad, peak_drift_measured=pm, peak_drift_predicted=pk,
                      peak_drift_error=pk / pm - 1.0,
                      stiffness_error=err, status=int(sim.status[0]), time=meas.time, disp_measured=disp_meas,
                      disp_predicted=dp, drift_predicted=xp,
                      force_predicted=np.nan_to_num(cast(np.ndarray, sim.force)[0]), ke_clone=ke, hla=res)
