"""A clone's prediction of an event, against what the building recorded.

:func:`predict_event` replays a clone under an event's recorded ground motion from the start
:func:`~hlaid.events.start.resolve_start` gives (``"auto"``: the state its last event left it
in, unless an update found the building recovered between events) and compares the floor
displacements relative to the ground with the measured ones in one band: correlation ``r`` per
floor, and per story the drift's correlation and the peak inter-story drift error. With the
clone's uncertainty, an ensemble of clones drawn from it gives a predictive band and the share of
the measured response inside it (:class:`PredictiveBand`); against HLA of the event, the clone's
elastic stiffness along the record (:class:`HLACheck`, the validation study's comparison).

The default band is the one the records hold (:func:`hlaid.identify.auto.records_band`: the
clone is used under the whole ground motion, so it is judged on every frequency the event holds,
its higher modes with its first); the figures in HLA's band of the event (its first-mode band on
a frame) are given beside them (:attr:`Prediction.other_bands`), from the same replay, and where
the record's floor displacements hold it, the residual drift each story is left with.

The measured displacements go through HLA's own preprocessing
(:func:`hlaid.hla.analysis.floor_motion`: the file's displacements band-passed where it has them,
else the accelerations integrated), and the clone's response through the same path, so a clone
equal to the building scores 1.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from .. import _progress
from .. import signal as sg
from ..errors import InputError
from ..measurement import Measurement
from ..motions import GroundMotion
from ..units import G_MM_S2
from .start import resolve_start

if TYPE_CHECKING:
    from ..clone import Clone
    from ..hla import HLAConfig, HLAResult
    from ..model import Building

BAND_LEVEL = 0.9
"""Central probability of the predictive band."""


@dataclass(frozen=True, eq=False)
class PredictiveBand:
    """The band of an ensemble of clones drawn from a clone's uncertainty.

    Attributes
    ----------
    n_ensemble : clones drawn
    level : its central probability
    lower, upper : (time, floor) the band [mm]
    coverage : (floor,) share of the measured displacement inside it
    width : (floor,) its mean width over twice the measured RMS (read coverage with it: a band
        wider than the response covers anything)
    """

    n_ensemble: int
    level: float
    lower: np.ndarray = field(repr=False)
    upper: np.ndarray = field(repr=False)
    coverage: np.ndarray
    width: np.ndarray


@dataclass(frozen=True, eq=False)
class HLACheck:
    """The clone's replay against HLA of the event.

    Attributes
    ----------
    hla : HLA of the event (None where it failed: too weak or too short)
    stiffness_error : (story,) mean over HLA's half cycles of ``|ke_clone / ke_HLA - 1|`` (NaN
        without HLA)
    r_broadband : (floor,) ``r`` with the band's upper corner raised to 20 Hz (below 0.45 of the
        sampling rate): what the measured displacement holds above the compared band counts
    drift, force, ke : (time, story) the clone's drift [mm], spring force [N] and elastic
        stiffness ke(t) [N/mm]
    """

    hla: HLAResult | None = field(repr=False)
    stiffness_error: np.ndarray
    r_broadband: np.ndarray
    drift: np.ndarray = field(repr=False)
    force: np.ndarray = field(repr=False)
    ke: np.ndarray = field(repr=False)


@dataclass(frozen=True, eq=False)
class BandFigures:
    """A prediction's figures in one band.

    Attributes
    ----------
    band_hz : the band [Hz]
    r : (floor,) correlation of predicted and measured displacement relative to the ground
    drift_r : (story,) correlation of predicted and measured story drift
    peak_drift_measured, peak_drift_predicted : (story,) peak story drift in the band [mm]
    peak_drift_error : (story,) ``predicted / measured - 1``
    """

    band_hz: tuple[float, float]
    r: np.ndarray
    drift_r: np.ndarray
    peak_drift_measured: np.ndarray
    peak_drift_predicted: np.ndarray
    peak_drift_error: np.ndarray

    @classmethod
    def of(cls, band, measured: np.ndarray, predicted: np.ndarray) -> BandFigures:
        """The figures of ``(time, floor)`` measured and predicted displacements in ``band``."""
        from ..hla import preprocess as pp
        from ..identify.replaycheck import corrcoef

        xm, xp = pp.story_drift(measured), pp.story_drift(predicted)
        pm, pk = np.max(np.abs(xm), axis=0), np.max(np.abs(xp), axis=0)
        return cls(band_hz=(float(band[0]), float(band[1])), r=corrcoef(predicted, measured), drift_r=corrcoef(xp, xm),
                   peak_drift_measured=pm, peak_drift_predicted=pk, peak_drift_error=pk / pm - 1.0)

    def to_dict(self) -> dict:
        e = self.peak_drift_error
        return {"band_hz": list(self.band_hz), "r": self.r.tolist(), "r_mean": float(np.mean(self.r)),
                "drift_r": self.drift_r.tolist(), "drift_r_mean": float(np.mean(self.drift_r)),
                "peak_drift_measured": self.peak_drift_measured.tolist(),
                "peak_drift_predicted": self.peak_drift_predicted.tolist(), "peak_drift_error": e.tolist(),
                "peak_drift_error_mean_abs": float(np.mean(np.abs(e))),
                "peak_drift_error_worst": float(e[int(np.argmax(np.abs(e)))])}


BAND_NAMES = {"records": "the band the event's floor records hold (the default)", "given": "the band given",
              "hla": "HLA's band of the event (its first-mode band on a frame)"}
"""The bands a prediction names (``prediction.json``'s ``band`` and ``other_bands``)."""


@dataclass(frozen=True, eq=False)
class Prediction:
    """A clone replayed under one event, against what was measured.

    Attributes
    ----------
    event : the event's name; source : its file
    start : ``"carried"`` or ``"undamaged"`` (as resolved); start_reason : why
    band_hz : band of the compared displacements [Hz]
    pga_g : peak ground acceleration of the event [g]
    r : (floor,) correlation of predicted and measured displacement relative to the ground
    drift_r : (story,) correlation of predicted and measured inter-story drift
    peak_drift_measured, peak_drift_predicted : (story,) peak inter-story drift [mm] (in the band)
    peak_drift_error : (story,) ``predicted / measured - 1``
    r_true : (floor,) correlation of the predicted with the true displacement (simulated data,
        unfiltered; None for recorded data)
    status : the replay's simulator status (0 ok)
    time : (time,) [s]; disp_measured, disp_predicted : (time, floor) [mm]
    band : the ensemble's predictive band (None without one)
    hla_check : the replay against HLA of the event (None unless asked for)
    band_name : which band ``band_hz`` is (:data:`BAND_NAMES`)
    other_bands : the same replay's figures in other bands, by name (``"hla"``: HLA's band of
        the event, where it differs from ``band_hz``)
    residual_drift_measured, residual_drift_predicted : (story,) the change of each story's drift
        over the event [mm], from its first to its last second (the measured floor displacements
        and the replay low-passed at the band's upper corner, not high-passed); None where the
        record has no floor displacements
    """

    event: str
    source: str
    start: str
    start_reason: str
    band_hz: tuple[float, float]
    pga_g: float
    r: np.ndarray
    drift_r: np.ndarray
    peak_drift_measured: np.ndarray
    peak_drift_predicted: np.ndarray
    peak_drift_error: np.ndarray
    r_true: np.ndarray | None
    status: int
    time: np.ndarray = field(repr=False)
    disp_measured: np.ndarray = field(repr=False)
    disp_predicted: np.ndarray = field(repr=False)
    band: PredictiveBand | None = None
    hla_check: HLACheck | None = None
    band_name: str = "given"
    other_bands: dict = field(default_factory=dict)
    residual_drift_measured: np.ndarray | None = None
    residual_drift_predicted: np.ndarray | None = None

    @property
    def residual_drift_error(self) -> np.ndarray | None:
        """(story,) predicted less measured residual drift [mm] (None without floor displacements)."""
        if self.residual_drift_measured is None or self.residual_drift_predicted is None:
            return None
        return self.residual_drift_predicted - self.residual_drift_measured

    @property
    def r_mean(self) -> float:
        return float(np.mean(self.r))

    @property
    def drift_r_mean(self) -> float:
        """The story-drift correlation, mean over the stories."""
        return float(np.mean(self.drift_r))

    @property
    def peak_drift_error_mean_abs(self) -> float:
        """``|peak_drift_error|``, mean over the stories."""
        return float(np.mean(np.abs(self.peak_drift_error)))

    @property
    def peak_drift_error_worst(self) -> float:
        """The story's ``peak_drift_error`` of largest magnitude (signed)."""
        return float(self.peak_drift_error[int(np.argmax(np.abs(self.peak_drift_error)))])

    @property
    def roof_error(self) -> float:
        """``predicted / measured - 1`` of the peak roof displacement relative to the ground in
        the band: the amplitude part of every story's peak-drift error."""
        m = float(np.max(np.abs(self.disp_measured[:, -1])))
        return float(np.max(np.abs(self.disp_predicted[:, -1])) / m - 1.0) if m > 0 else float("nan")

    def to_dict(self) -> dict:
        """``prediction.json``'s content (the arrays over time go to ``prediction.npz``)."""
        b = self.band
        return {"format": "hlaid-prediction", "version": 1, "event": self.event, "source": self.source or None,
                "start": self.start, "start_reason": self.start_reason, "band_hz": list(self.band_hz),
                "pga_g": self.pga_g, "r": self.r.tolist(), "r_mean": self.r_mean, "drift_r": self.drift_r.tolist(),
                "drift_r_mean": self.drift_r_mean, "peak_drift_measured": self.peak_drift_measured.tolist(),
                "peak_drift_predicted": self.peak_drift_predicted.tolist(),
                "peak_drift_error": self.peak_drift_error.tolist(),
                "peak_drift_error_mean_abs": self.peak_drift_error_mean_abs,
                "peak_drift_error_worst": self.peak_drift_error_worst, "roof_error": _finite(self.roof_error),
                "r_true": None if self.r_true is None else self.r_true.tolist(),
                "n_ensemble": 0 if b is None else b.n_ensemble, "band_level": None if b is None else b.level,
                "coverage": None if b is None else b.coverage.tolist(),
                "coverage_mean": None if b is None else float(np.mean(b.coverage)),
                "band_width": None if b is None else b.width.tolist(), "status": self.status,
                "band": self.band_name, "band_meaning": BAND_NAMES.get(self.band_name, self.band_name),
                "other_bands": {k: {**v.to_dict(), "meaning": BAND_NAMES.get(k, k)}
                                for k, v in self.other_bands.items()},
                "residual_drift_measured": _list(self.residual_drift_measured),
                "residual_drift_predicted": _list(self.residual_drift_predicted),
                "residual_drift_error": _list(self.residual_drift_error)}

    def arrays(self) -> dict[str, np.ndarray]:
        """``prediction.npz``'s content: ``time`` and the ``(time, floor)`` displacements [mm]
        (with the band's edges where there is one)."""
        out = {"time": self.time, "disp_measured": self.disp_measured, "disp_predicted": self.disp_predicted}
        if self.band is not None:
            out.update(band_lower=self.band.lower, band_upper=self.band.upper)
        return out


def _list(x) -> list | None:
    return None if x is None else np.asarray(x, dtype=float).tolist()


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def identification_misfit(clone: Clone) -> np.ndarray | float:
    """How far the clone's replays of its own events were from the measured displacements, per
    floor a fraction of their RMS: ``sqrt(2 (1 - R))`` of the replay's correlation ``R`` (the
    relative RMS difference of two signals of equal RMS), the mean over its events; 0 where the
    clone does not say."""
    rs = [np.asarray(r.r_measured, dtype=float) for r in clone.fit_replays if r.r_measured]
    if not rs or len({r.shape for r in rs}) != 1:
        return 0.0
    return np.mean([np.sqrt(np.clip(2.0 * (1.0 - r), 0.0, None)) for r in rs], axis=0)


def predict_event(clone: Clone, meas: Measurement, *, band_hz=None, start: str = "auto", n_ensemble: int = 0,
                  seed: int = 0, hla_config: HLAConfig | None = None, misfit: float | None = None,
                  input_lowpass_hz: float | None = None, check_hla: bool = False) -> Prediction:
    """Replay ``clone`` under ``meas``'s ground motion and compare with what was measured.

    Parameters
    ----------
    clone : the clone (its stories must match the measurement's floors)
    meas : the event
    band_hz : band of the comparison [Hz] (None: the band ``meas``'s floor records hold,
        :func:`hlaid.identify.auto.records_band`, its low corner HLA's where the displacements
        compared are integrated accelerations, whose drift HLA's high-pass removes; the figures
        in HLA's band of ``meas`` under ``hla_config``, the band the clone was identified in
        where it was one band, a first-mode band say, else the record's own from its spectrum,
        are given beside them)
    start : ``"carried"``, ``"undamaged"`` or ``"auto"`` (:func:`~hlaid.events.start.resolve_start`)
    n_ensemble : clones drawn from ``clone.uncertainty`` for the predictive band (0: none), those
        that collapse under the clone's own events rejected (:func:`hlaid.events.evidence.survivors`). The
        band holds the central :data:`BAND_LEVEL` of the ensemble's predictions, widened on each
        side by the same quantile of a Gaussian error of ``misfit`` times each floor's predicted RMS:
        the parameters' uncertainty and the model's own misfit (as the clone replayed its events)
    seed : of the draws
    hla_config : HLA settings of the measured displacements (its preprocessing; default: those the
        clone was identified with, :func:`clone_hla_config`, else HLA's defaults). Its ``"auto"``
        settings are the clone's, or chosen from ``meas`` (:func:`hlaid.hla.resolve_hla`)
    misfit : the model's error as a fraction of a floor's RMS, one number or ``(floor,)`` (None:
        :func:`identification_misfit`, what the clone missed its own events by)
    input_lowpass_hz : low-pass of the ground motion (None: the band's upper corner)
    check_hla : also compare the clone's elastic stiffness with HLA of the event (:class:`HLACheck`)
    """
    from ..hla import HLAConfig, resolve_hla
    from ..simulate import simulate_response

    b = clone.building
    src = meas.source or None
    if meas.n_floors != b.n_stories:
        raise InputError(f"{meas.n_floors} floor channels, but the clone has {b.n_stories} stories: the measurement "
                         "is not of this building", source=src)
    cfg = hla_config or clone_hla_config(clone) or HLAConfig()
    if cfg.unresolved():  # "auto" settings: as the clone was identified, else from this record
        cfg = clone_hla_config(clone) or resolve_hla(meas, cfg).config
    cfg, band, hla_band, band_name, res = _comparison_band(meas, cfg, band_hz, check_hla)
    hi_in = sg.cap_corner(input_lowpass_hz or band[1], meas.dt)
    ground = GroundMotion(dt=meas.dt, acc=sg.bandpass(np.asarray(meas.ground_acc), meas.dt, (0.0, hi_in),
                                                      cfg.preprocess.order), name=meas.name)
    resolved = resolve_start(clone, start)
    buildings = [b] + (_survivors(clone, n_ensemble, seed) if n_ensemble else [])
    sim = simulate_response(buildings, ground, y0=resolved.vector(collapse=b.collapse is not None))
    assert sim.disp is not None and sim.acc is not None
    compare = _Comparison(meas, cfg, sim, ground)
    measured, predicted = compare(band)
    from ..hla import preprocess as pp
    from ..identify.replaycheck import corrcoef

    xm, xp = pp.story_drift(measured), pp.story_drift(predicted[0])
    pm, pk = np.max(np.abs(xm), axis=0), np.max(np.abs(xp), axis=0)
    others = _other_bands(clone, meas, compare, band, hla_band, band_name, start=start, cfg=cfg, misfit=misfit)
    res_m, res_p = _residual_drift(meas, sim, resolved, hi_in)
    r_true = None if meas.truth is None else corrcoef(np.nan_to_num(sim.disp[0]), meas.truth.disp)
    pband = None if not n_ensemble else _band(clone, measured, predicted, misfit, len(buildings) - 1)
    check = None if not check_hla else _hla_check(clone, res, sim, compare, band, xp)
    return Prediction(event=meas.name, source=meas.source, start=resolved.name, start_reason=resolved.reason,
                      band_hz=band, pga_g=float(np.max(np.abs(meas.ground_acc)) / G_MM_S2),
                      r=corrcoef(predicted[0], measured), drift_r=corrcoef(xp, xm), peak_drift_measured=pm,
                      peak_drift_predicted=pk, peak_drift_error=pk / pm - 1.0, r_true=r_true,
                      status=int(sim.status[0]), time=meas.time, disp_measured=measured, disp_predicted=predicted[0],
                      band=pband, hla_check=check, band_name=band_name, other_bands=others,
                      residual_drift_measured=res_m, residual_drift_predicted=res_p)


RESIDUAL_WINDOW_S = 1.0
"""The residual drift of an event: the mean drift over its last second less that over its first."""


def _residual_drift(meas: Measurement, sim, start, hi_hz: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(story,)`` measured and replayed change of each story's drift over the event [mm] (the
    measured floor displacements and the replay low-passed at ``hi_hz``; the replay's from the
    drift it starts with, the record's from its first second); None where the record has no
    floor displacements or is shorter than two windows."""
    if meas.floor_disp is None or sim.disp is None:
        return None, None
    n = max(int(round(RESIDUAL_WINDOW_S / meas.dt)), 1)
    if 2 * n > meas.n_samples:
        return None, None
    dm = np.diff(sg.lowpass(np.asarray(meas.floor_disp, dtype=float), meas.dt, hi_hz), axis=1, prepend=0.0)
    dp = np.diff(sg.lowpass(np.nan_to_num(np.asarray(sim.disp[0], dtype=float)), meas.dt, hi_hz), axis=1, prepend=0.0)
    x0 = np.zeros(meas.n_floors) if start.state is None else np.asarray(start.state.drift, dtype=float)
    measured = dm[-n:].mean(axis=0) - dm[:n].mean(axis=0)
    predicted = dp[-n:].mean(axis=0) - x0
    return measured, predicted


def clone_hla_config(clone: Clone) -> HLAConfig | None:
    """The HLA settings ``clone`` was identified with (its ``settings``' ``hla`` section, as
    chosen from its records), None where it does not keep them or they are not a valid config."""
    from ..config import config_from_dict
    from ..errors import ConfigError
    from ..hla import HLAConfig

    d = None if clone.settings is None else clone.settings.value("hla")
    if not isinstance(d, dict):
        return None
    try:
        cfg = config_from_dict(HLAConfig, d, source="the clone's HLA settings")
    except (ConfigError, InputError):
        return None
    return None if cfg.unresolved() else cfg


def _comparison_band(meas: Measurement, cfg: HLAConfig, band_hz, check_hla: bool
                     ) -> tuple[HLAConfig, tuple[float, float], tuple[float, float], str, HLAResult | None]:
    """The band a prediction compares in (see :func:`predict_event`'s ``band_hz``): ``(cfg in that
    band, band, HLA's band of meas, its name, HLA of meas where check_hla)``."""
    from ..hla.analysis import resolved_band
    from ..identify.auto import records_band

    hla_band = resolved_band(meas, cfg)
    band_name = "given"
    if band_hz is None:  # with check_hla, HLA's band of the event, as HLA of it is compared
        band_hz, band_name = (hla_band, "hla") if check_hla else (records_band(meas), "records")
        p = cfg.preprocess
        if band_name == "records" and (p.displacement == "integrate" or meas.floor_disp is None):
            band_hz = (max(float(band_hz[0]), float(hla_band[0])), band_hz[1])  # integrated: HLA's high-pass
    lo, hi = float(band_hz[0]), sg.cap_corner(float(band_hz[1]), meas.dt)
    if not 0 <= lo < hi:
        raise InputError(f"band {lo:g}-{band_hz[1]:g} Hz; expected low < high, below the Nyquist frequency",
                         source=meas.source or None)
    cfg = _with_band(cfg, (lo, hi))
    res = _hla_of(meas, cfg) if check_hla else None
    band = (lo, hi) if res is None else cast("tuple[float, float]", tuple(res.band_hz))
    return _with_band(cfg, band), band, cast("tuple[float, float]", tuple(hla_band)), band_name, res


def _survivors(clone: Clone, n: int, seed: int) -> list[Building]:
    """``n`` clones drawn from ``clone``'s uncertainty, those that collapse under its own events
    rejected (:func:`hlaid.events.evidence.survivors`)."""
    from .evidence import survivors

    surv = survivors(clone, n, seed=seed)
    for note in surv.notes:
        _progress.debug(note)
    return list(surv.members)


def _other_bands(clone: Clone, meas: Measurement, compare, band, hla_band, band_name: str, *, start: str,
                 cfg: HLAConfig, misfit) -> dict[str, BandFigures]:
    """The figures beside a prediction's: in HLA's band of ``meas`` (where it differs) and, where
    the prediction is not in it, in the band the records hold (the whole ground motion's replay)."""
    others = {}
    h_lo, h_hi = float(hla_band[0]), sg.cap_corner(float(hla_band[1]), meas.dt)
    if band_name != "hla" and (h_lo, h_hi) != tuple(band) and 0 <= h_lo < h_hi:
        m2, p2 = compare((h_lo, h_hi))
        others["hla"] = BandFigures.of((h_lo, h_hi), m2, p2[0])
    if band_name != "records":  # the whole ground motion's replay, in the band the records hold
        w = predict_event(clone, meas, start=start, hla_config=cfg, misfit=misfit)
        others["records"] = BandFigures(band_hz=w.band_hz, r=w.r, drift_r=w.drift_r,
                                        peak_drift_measured=w.peak_drift_measured,
                                        peak_drift_predicted=w.peak_drift_predicted,
                                        peak_drift_error=w.peak_drift_error)
    return others


def _with_band(cfg: HLAConfig, band) -> HLAConfig:
    return dataclasses.replace(cfg, preprocess=dataclasses.replace(cfg.preprocess, band_hz=tuple(band)))


def _hla_of(meas: Measurement, cfg: HLAConfig) -> HLAResult | None:
    """HLA of the event (None where the record is too weak or too short for it)."""
    from ..hla import run_hla

    try:
        return run_hla(meas, cfg)
    except InputError as exc:
        _progress.warn(f"{meas.name or 'the event'}: HLA failed ({exc}); no stiffness comparison")
        return None


class _Comparison:
    """Measured and replayed floor displacements relative to the ground in a band, the replay's
    taken as the measured ones were: band-passed displacements where the data hold them, else its
    absolute accelerations integrated by HLA's code (:func:`hlaid.hla.analysis.floor_motion`)."""

    def __init__(self, meas: Measurement, cfg: HLAConfig, sim, ground: GroundMotion):
        p = cfg.preprocess
        self.meas, self.cfg, self.sim, self.ground = meas, cfg, sim, ground
        self.integrated = p.displacement == "integrate" or (p.displacement == "auto" and meas.floor_disp is None)

    def __call__(self, band) -> tuple[np.ndarray, np.ndarray]:
        """``(time, floor)`` measured and ``(batch, time, floor)`` replayed displacements [mm]."""
        from ..hla.analysis import floor_motion

        c = _with_band(self.cfg, band)
        measured = floor_motion(self.meas, c)[3]
        if not self.integrated:
            return measured, sg.bandpass(np.nan_to_num(self.sim.disp), self.meas.dt, band, c.preprocess.order, axis=1)
        twins = [dataclasses.replace(self.meas, ground_acc=self.ground.acc, floor_acc=np.nan_to_num(a),
                                     floor_disp=None, truth=None, mass=None) for a in self.sim.acc]
        return measured, np.stack([floor_motion(t, c)[3] for t in twins])


def _band(clone: Clone, measured: np.ndarray, predicted: np.ndarray, misfit, n_ensemble: int) -> PredictiveBand:
    """The ensemble's central :data:`BAND_LEVEL` band, widened by the model's own misfit."""
    from scipy.stats import norm

    q = 0.5 * (1.0 - BAND_LEVEL)
    lower, upper = np.quantile(predicted[1:], [q, 1.0 - q], axis=0)
    sigma = identification_misfit(clone) if misfit is None else np.asarray(misfit, dtype=float)
    pad = float(norm.ppf(1.0 - q)) * np.asarray(sigma) * np.sqrt(np.mean(predicted[0] ** 2, axis=0))
    lower, upper = lower - pad, upper + pad
    rms = np.sqrt(np.mean(measured**2, axis=0))
    return PredictiveBand(n_ensemble=int(n_ensemble), level=BAND_LEVEL, lower=lower, upper=upper,
                          coverage=np.mean((measured >= lower) & (measured <= upper), axis=0),
                          width=np.mean(upper - lower, axis=0) / (2.0 * rms))


def _hla_check(clone: Clone, res: HLAResult | None, sim, compare: _Comparison, band, drift: np.ndarray) -> HLACheck:
    """The clone's ke(t) against HLA's half cycles and the broadband correlation."""
    from ..identify.replaycheck import corrcoef

    b = clone.building
    ke = b.elastic_stiffness(np.nan_to_num(cast(np.ndarray, sim.eta)[0], nan=1.0))
    err = np.full(b.n_stories, np.nan)
    if res is not None:
        for i, s in enumerate(res.stories):
            hc = s.half_cycles
            if len(hc):
                err[i] = float(np.mean(np.abs(ke[hc.start, i] / hc.ke - 1.0)))
    measured, predicted = compare((band[0], max(band[1], sg.cap_corner(20.0, compare.meas.dt))))
    return HLACheck(hla=res, stiffness_error=err, r_broadband=corrcoef(predicted[0], measured), drift=drift,
                    force=np.nan_to_num(cast(np.ndarray, sim.force)[0]), ke=ke)


__all__ = ["BAND_LEVEL", "BAND_NAMES", "BandFigures",
           "HLACheck", "Prediction", "PredictiveBand", "identification_misfit", "predict_event"]
