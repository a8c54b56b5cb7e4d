"""The per-event stages of the paper's identification (section 2.2) over an explicit state.

One measurement becomes an :class:`Event` (:func:`analyse`: HLA, the yielding half cycles,
which stories are identifiable, the ground motion and the noise level), which no stage
changes. The state the stages pass on is an :class:`Estimate`: the story parameters and the
drift paths (with their half cycles) they were derived along. Every stage returns a new one::

    Event --first_estimate--> Estimate --follow_paths--> Estimate --regress--> Estimate
                                  (the classifier passes, :mod:`hlaid.identify.passes`, give alpha, p)

:func:`follow_paths` reconstructs the drift paths with the current estimate, analyses HLA's
half cycles, ke and k0 again along them and fits k0 along them; :func:`regress` gives
delta_eta and dy from the regressions of eq 12-17 for an alpha and p.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import _progress
from ..hla import HLAResult, run_hla
from ..hla.analysis import reanalyse_story
from ..hla.features import HalfCycleFeatures, half_cycle_features
from ..hla.result import StoryHLA
from ..measurement import Measurement, building_name, measured_ground
from ..model import Building, Damping
from ..motions import GroundMotion
from .config import IdentifyConfig
from .drift import reconstruct_drift
from .loopfit import fit_story_loop
from .regression import plausible_limits, story_delta_eta, story_yield_displacement


@dataclass(frozen=True, eq=False)
class Event:
    """One measurement as the stages see it.

    Attributes
    ----------
    measurement : the record
    hla : its hysteresis loop analysis
    features : per story the yielding half cycles along HLA's drift (with ke)
    identifiable : ``(story,)`` the stories that yielded in at least 3 half cycles
    alpha_max : ``(story,)`` the top of each story's alpha bins, ``inf(ke/k0)`` within 0.05-0.95
    ground : the measured ground motion, low-passed at HLA's upper corner
    noise : the record's noise level, a fraction of each channel's RMS
    """

    measurement: Measurement
    hla: HLAResult
    features: tuple[HalfCycleFeatures, ...]
    identifiable: np.ndarray
    alpha_max: np.ndarray
    ground: GroundMotion
    noise: float

    @property
    def n_stories(self) -> int:
        return self.hla.n_stories

    @property
    def peak_drift(self) -> np.ndarray:
        """``(story,)`` the peak drift along HLA's drift [mm]."""
        return np.array([np.max(np.abs(s.drift)) for s in self.hla.stories])


@dataclass(frozen=True, eq=False)
class Estimate:
    """The state between stages: the story parameters and the paths they were derived along.

    Attributes
    ----------
    k0, alpha, p, dy, delta_eta : ``(story,)`` the current values
    stories : per story the HLA the regressions see (along the current drift path)
    features : per story the yielding half cycles along that path
    regressions : per story the regressions' fits (None for a story not identifiable)
    """

    k0: np.ndarray
    alpha: np.ndarray
    p: np.ndarray
    dy: np.ndarray
    delta_eta: np.ndarray
    stories: tuple[StoryHLA, ...]
    features: tuple[HalfCycleFeatures, ...]
    regressions: tuple = ()

    def building(self, event: Event, damping_ratio: float) -> Building:
        """The estimate as a building (masses, heights and P-Delta of the measurement)."""
        meas = event.measurement
        return Building(mass=event.hla.mass, k0=self.k0, alpha=self.alpha, p=self.p, dy=self.dy,
                        delta_eta=self.delta_eta, height=meas.height, damping=Damping(ratio=damping_ratio),
                        pdelta=meas.pdelta_active if meas.height is not None else None, name=building_name(meas))

    def replace(self, **changes) -> Estimate:
        return dataclasses.replace(self, **changes)


def estimate_noise_rms(meas: Measurement) -> float:
    """Sensor noise as a fraction of channel RMS, from the flat spectrum floor above 0.6 x
    Nyquist (white noise extrapolated over the whole band); the median over channels."""
    from scipy import signal

    fs = 1.0 / meas.dt
    chans = np.column_stack([meas.ground_acc, meas.floor_acc])
    f, p = signal.welch(chans - chans.mean(axis=0), fs=fs, nperseg=min(1024, chans.shape[0]), axis=0)
    hf = f >= 0.6 * fs / 2
    if hf.sum() < 3:
        return 0.0
    noise_var = p[hf].mean(axis=0) * fs / 2
    rms2 = np.mean((chans - chans.mean(axis=0)) ** 2, axis=0)
    return float(np.median(np.sqrt(noise_var / rms2)))


def noise_level(meas: Measurement, cfg: IdentifyConfig) -> float:
    """The noise level of the training samples: the config's, else the measurement's own (known
    for simulated data), else estimated from the record's high-frequency floor."""
    if cfg.training.noise_rms is not None:
        return cfg.training.noise_rms
    if meas.noise_rms is not None:
        return meas.noise_rms
    return estimate_noise_rms(meas)


def analyse(meas: Measurement, cfg: IdentifyConfig) -> Event:
    """The HLA stage: HLA of ``meas`` and what the other stages need of it (an event where no story
    yielded in 3 half cycles has none identifiable: the paper's method cannot run on it)."""
    _progress.step(f"[identify] hysteresis loop analysis{' of ' + meas.name if meas.name else ''}")
    res = run_hla(meas, cfg.hla)
    yield_ratio = cfg.resolved().yield_ratio
    features = tuple(half_cycle_features(s, cfg.training.n_segments, yield_ratio=yield_ratio, with_ke=True)
                     for s in res.stories)
    identifiable = np.array([s.yielded and len(F) >= 3 for s, F in zip(res.stories, features)])
    ke_min = np.array([np.nanmin(s.half_cycles.ke) / s.k0 if len(s.half_cycles) else 1.0 for s in res.stories])
    return Event(measurement=meas, hla=res, features=features, identifiable=identifiable,
                 alpha_max=np.clip(np.nan_to_num(ke_min, nan=1.0), 0.05, 0.95),
                 ground=measured_ground(meas, res.band_hz[1]), noise=noise_level(meas, cfg))


def first_estimate(event: Event, cfg: IdentifyConfig) -> Estimate:
    """Along HLA's drift, k0 from HLA, alpha half its top bin (0.1 where not identifiable), p
    mid-range, and the regressions' delta_eta and dy for them."""
    n = event.n_stories
    est = Estimate(k0=event.hla.k0.copy(), alpha=np.zeros(n), p=np.zeros(n), dy=np.zeros(n), delta_eta=np.zeros(n),
                   stories=tuple(event.hla.stories), features=event.features)
    return regress(event, est, np.where(event.identifiable, 0.5 * event.alpha_max, 0.1),
                   np.full(n, 0.5 * sum(cfg.bins.p_range)))


def regress(event: Event, est: Estimate, alpha: np.ndarray, p: np.ndarray) -> Estimate:
    """The regressions stage: ``est`` with ``alpha``, ``p`` and the delta_eta (eq 12-14) and dy
    (eq 15-17) they give along its paths, held within the plausible limits of a story's loops.
    A story that did not yield borrows delta_eta from the identified ones (the median) and gets
    a dy above the largest drift it reached."""
    n, mass, ok = event.n_stories, event.hla.mass, event.identifiable
    de, dy = np.zeros(n), np.zeros(n)
    info: list[dict | None] = []
    for i, s in enumerate(est.stories):
        if not ok[i]:
            info.append(None)
            continue
        fd = story_delta_eta(s, mass=mass[i], alpha=alpha[i], k0=est.k0[i])
        fy = story_yield_displacement(s, est.features[i], alpha=alpha[i], p=p[i], k0=est.k0[i])
        de[i] = max(fd.value, 0.0) if np.isfinite(fd.value) else 0.0
        dy[i] = fy.value if np.isfinite(fy.value) and fy.value > 0 else np.max(np.abs(s.drift)) / 3.0
        info.append({"delta_eta": vars(fd), "dy": vars(fy)})
        de_max, dy_max = plausible_limits(s, mass=mass[i], alpha=alpha[i], k0=est.k0[i])
        de[i], dy[i] = min(de[i], de_max), min(dy[i], dy_max)  # a regression on a poor alpha cannot run away
    for i, s in enumerate(event.hla.stories):
        if not ok[i]:
            de[i] = float(np.median(de[ok]))
            dy[i] = max(1.2 * float(np.max(np.abs(s.drift))), 1e-3)
    return est.replace(alpha=np.asarray(alpha, dtype=float), p=np.asarray(p, dtype=float), dy=dy, delta_eta=de,
                       regressions=tuple(info))


def follow_paths(event: Event, est: Estimate, cfg: IdentifyConfig) -> Estimate:
    """The drift-path stage: the paths reconstructed with ``est``'s building (HLA's drift above
    ``training.crossover_hz``, its replay below), HLA's half cycles, ke and k0 analysed again
    along them (HLA's kept for a story whose path lost its yielding half cycles), the
    regressions along them, k0 fitted along them (:func:`fit_k0`) and the regressions again."""
    res = event.hla
    paths = reconstruct_drift(res, event.ground, est.building(event, cfg.damping_ratio),
                              crossover_hz=cfg.training.crossover_hz)
    k0, stories, features = est.k0.copy(), [], []
    for i, s in enumerate(res.stories):
        story = reanalyse_story(s, paths[:, i], s.force, res.dt, cfg.hla, res.band_hz)
        feats = half_cycle_features(story, cfg.training.n_segments,
                                    yield_ratio=cfg.resolved().yield_ratio)
        if event.identifiable[i] and (len(feats) < 3 or not np.isfinite(story.k0) or story.k0 <= 0):
            story, feats = s, event.features[i]  # the path lost the yielding half cycles: keep HLA's
        elif event.identifiable[i]:
            k0[i] = story.k0
        stories.append(story)
        features.append(feats)
    est = regress(event, est.replace(k0=k0, stories=tuple(stories), features=tuple(features)), est.alpha, est.p)
    est = fit_k0(event, est)
    return regress(event, est, est.alpha, est.p)


def fit_k0(event: Event, est: Estimate) -> Estimate:
    """k0 of every identifiable story by least squares of the story law along its path against
    the measured force, the other parameters held (:mod:`hlaid.identify.loopfit`)."""
    k0 = est.k0.copy()
    for i, s in enumerate(est.stories):
        if not event.identifiable[i]:
            continue
        end = int(np.max(s.half_cycles.end)) + 1 if len(s.half_cycles) else s.drift.shape[0]
        fit = fit_story_loop(s.drift, s.force, event.hla.dt, float(event.hla.mass[i]),
                             {"k0": k0[i], "alpha": est.alpha[i], "p": est.p[i], "dy": est.dy[i],
                              "delta_eta": est.delta_eta[i]}, free=("k0",), window=slice(0, end))
        k0[i] = fit.params["k0"]
    return est.replace(k0=k0)
