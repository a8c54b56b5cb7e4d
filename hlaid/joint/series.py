"""A building's events replayed in time order, each from the state the previous one left.

An engineer monitoring a building gets one event after another. Each event's replay starts from
the state the previous one left the building in (its degradation, residual drift and hysteretic
displacement, after a free vibration that lets it come to rest: :class:`EventSeries`), so the
events are one history of one building. Each event's residuals are weighed by what they hold:
``w^2 = n_eff / sum r^2`` at the current building, ``n_eff`` their effective number of
independent samples (:func:`effective_samples`: a first-mode-dominated misfit of a 40 s record
holds a few dozen, not thousands).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..identify.residuals import ReplayResiduals
from ..measurement import Measurement
from ..model import Building
from ..model.state import BuildingState, at_rest, settle_time
from ..signal import lowpass

REPLAY_RATE_RATIO = 16.0
"""Replays of a fit run at least this many samples per period of the fitted band's upper corner:
a record sampled far above its band (a shake table at 256 Hz fitted below 2.5 Hz) is low-passed
and decimated first (:func:`at_replay_rate`), a sixth of the work with the same residuals."""

WIDE_RATE_RATIO = 4.0
"""Samples per period of the upper corner of a band that reaches the higher modes (the records'
band, :func:`hlaid.joint.fit.wide_band`), at least :data:`WIDE_RATE_HZ`: the band is represented
up to its corner (Nyquist at twice it; the ground's linear interpolation between samples loses
0.3 dB at 0.4 of the corner, the frame's second mode, 0.9 dB at 0.7, its third, 1.8 dB at the
corner, where the band's filter has already halved it) and the clone's modes up to 10 Hz are
integrated at ``omega h <= 0.33`` by four RK4 steps a sample at 48 Hz. On the steel frame
(0.1-12.8 Hz at 256 Hz): a fifth of the samples, 1.2 times those of its first-mode band's fit."""

WIDE_RATE_HZ = 48.0
"""The lowest replay rate of a wide band's fit [Hz] (:data:`WIDE_RATE_RATIO`)."""


def at_replay_rate(meas: Measurement, hi_hz: float, ratio: float = REPLAY_RATE_RATIO) -> Measurement:
    """``meas`` low-passed at ``hi_hz`` and decimated to at least ``ratio`` samples per period of
    ``hi_hz`` (:data:`REPLAY_RATE_RATIO`; with :data:`WIDE_RATE_RATIO` at least
    :data:`WIDE_RATE_HZ`) (``meas`` itself where it is not sampled above that); its floor
    displacements, where it has them, alike."""
    rate = ratio * hi_hz if ratio >= REPLAY_RATE_RATIO else max(ratio * hi_hz, WIDE_RATE_HZ)
    factor = int(1.0 / (rate * meas.dt))
    if factor < 2:
        return meas
    ground = lowpass(np.asarray(meas.ground_acc), meas.dt, hi_hz)[::factor]
    floor = lowpass(np.asarray(meas.floor_acc), meas.dt, hi_hz)[::factor]
    disp = None if meas.floor_disp is None else lowpass(np.asarray(meas.floor_disp), meas.dt, hi_hz)[::factor].copy()
    return dataclasses.replace(meas, dt=meas.dt * factor, ground_acc=ground.copy(), floor_acc=floor.copy(),
                               floor_disp=disp, truth=None)


def effective_samples(r: np.ndarray) -> float:
    """Effective number of independent samples of residuals ``r`` ``(time, channel)``: per
    channel the spectral degrees of freedom ``2 (sum S)^2 / sum S^2`` of its spectrum ``S``
    (``2 B T`` for noise of bandwidth ``B`` over ``T`` seconds, ``N`` for white noise), taken
    from the periodogram ``P`` as ``4 (sum P)^2 / sum P^2`` (a Gaussian's periodogram ordinates
    have ``E P^2 = 2 S^2``), summed and scaled by the channels' effective count over their number
    (``(sum l)^2 / sum l^2`` of the eigenvalues of their covariance: floors that move as one mode
    count once)."""
    r = np.asarray(r, dtype=float)
    if r.ndim == 1:
        r = r[:, None]
    P = np.abs(np.fft.rfft(r - r.mean(axis=0), axis=0)) ** 2
    dof = 4.0 * P.sum(axis=0) ** 2 / np.maximum((P**2).sum(axis=0), 1e-300)
    lam = np.clip(np.linalg.eigvalsh(np.atleast_2d(np.cov(r.T))), 0.0, None)
    channels = lam.sum() ** 2 / max(float((lam**2).sum()), 1e-300) if lam.sum() > 0 else 1.0
    return float(min(dof.sum() * channels / r.shape[1], r.shape[0] * r.shape[1]))


class EventSeries:
    """Residuals of replays against a building's events in time order, each replay starting
    where the previous one left the building.

    Parameters
    ----------
    events : one :class:`~hlaid.identify.residuals.ReplayResiduals` per event, oldest first
    y0 : ``(4*story,)`` the state before the first event (None: at rest)
    tail_s : free vibration after each event [s] (None: :func:`settle_time` of each building)

    Attributes
    ----------
    weights : ``(event,)`` each event's residuals are multiplied by its weight (1 until
        :meth:`reweigh`)
    n_residuals, channels, substeps, criterion : as a single event's, ``n_residuals`` summed
    """

    def __init__(self, events: Sequence[ReplayResiduals], *, y0: np.ndarray | None = None,
                 tail_s: float | None = None):
        if not events:
            raise InputError("an event series needs at least one event")
        self.events = list(events)
        self.y0 = None if y0 is None else np.asarray(y0, dtype=float)
        self.tail_s = tail_s
        self.weights = np.ones(len(self.events))
        self.substeps = self.events[0].substeps
        self.criterion = self.events[0].criterion
        self.channels = self.events[0].channels
        self.n_residuals = int(sum(e.n_residuals for e in self.events))

    def run(self, buildings: Sequence[Building], substeps: int | None = None
            ) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
        """Per event the residuals of ``buildings`` ``(batch, n)`` (unweighted), the summed plain
        costs ``(batch,)`` and per event the state each building ends it in ``(batch, 4*story)``."""
        tails = [self.tail_s if self.tail_s is not None else settle_time(b) for b in buildings]
        tail = float(max(tails))
        y = None if self.y0 is None else np.broadcast_to(self.y0, (len(buildings), self.y0.size)).copy()
        parts, finals = [], []
        plain = np.zeros(len(buildings))
        n = buildings[0].n_stories
        for ev in self.events:
            res, pl, final = ev.run(buildings, substeps, y0=y, tail_s=tail)
            parts.append(res)
            plain += pl
            final = at_rest(final, n)  # the free vibration has died out
            bad = ~np.all(np.isfinite(final), axis=1)
            final[bad] = 0.0 if y is None else y[bad]
            finals.append(final)
            y = final
        return parts, plain, finals

    def __call__(self, buildings: Sequence[Building], substeps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        parts, plain, _ = self.run(buildings, substeps)
        return np.concatenate([w * r for w, r in zip(self.weights, parts)], axis=1), plain

    def reweigh(self, building: Building) -> list[dict]:
        """Set each event's weight from its residuals at ``building``: ``w^2 = n_eff / sum r^2``
        (the misfit's mean square as its variance, :func:`effective_samples` as its count).
        Returns per event ``n_eff`` and the RMS of its residuals."""
        parts, _, _ = self.run([building])
        info = []
        for k, (ev, r) in enumerate(zip(self.events, parts)):
            r = r[0].reshape(-1, ev.channels)
            n_eff = effective_samples(r)
            ss = float(np.sum(r**2))
            self.weights[k] = np.sqrt(n_eff / ss) if ss > 0 else 1.0
            info.append({"n_eff": n_eff, "rms": float(np.sqrt(np.mean(r**2)))})
        return info

    def states(self, building: Building, names: Sequence[str] = ()) -> list[BuildingState]:
        """The state ``building`` is left in after each event (names: the events' labels)."""
        _, _, finals = self.run([building])
        labels = list(names) or [f"event {k + 1}" for k in range(len(finals))]
        peaks = _peak_drifts(self, building)
        return [BuildingState.from_vector(f[0], peaks=pk, events=tuple(labels[:k + 1]))
                for k, (f, pk) in enumerate(zip(finals, peaks))]


def _peak_drifts(series: EventSeries, building: Building) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per event the largest drift per direction up to its end ``((story,), (story,))`` [mm]."""
    from ..simulate import simulate_response

    y = series.y0
    n = building.n_stories
    pp, pn = np.zeros(n), np.zeros(n)
    out = []
    tail = series.tail_s if series.tail_s is not None else settle_time(building)
    for ev in series.events:
        r = simulate_response(building, ev.ground, substeps=series.substeps, y0=y, free_vibration=tail)
        drift = np.nan_to_num(np.asarray(r.drift)[0])
        pp, pn = np.maximum(pp, drift.max(axis=0)), np.maximum(pn, (-drift).max(axis=0))
        out.append((pp.copy(), pn.copy()))
        y = at_rest(r.final_state[0], n)
    return out


def event_series(at: Building, events: Sequence[Measurement], band_hz, ground_noise: str, substeps: int,
                 jac_substeps: int, y0, max_mb, compare: str = "acc") -> EventSeries:
    """The event series with each event's residuals (for ``"tangent"`` whitened along ``at``'s
    replay from the state carried into that event); ``compare``: what each event's residuals
    compare (:data:`hlaid.joint.compare.COMPARES`; other than ``"acc"``, least squares)."""
    from .compare import StoryResiduals

    units: list = []
    y = y0
    tail = settle_time(at)
    for m in events:
        if compare != "acc":
            units.append(StoryResiduals(m, compare=compare, band_hz=band_hz, substeps=substeps))
            continue
        unit = ReplayResiduals(m, band_hz=band_hz, substeps=substeps, ground_noise=ground_noise, at=at,
                               tangent_substeps=jac_substeps, max_mb=max_mb, at_state=y)
        units.append(unit)
        if ground_noise == "tangent":
            _, _, final = unit.run([at], y0=None if y is None else y[None], tail_s=tail)
            y = at_rest(final[0], at.n_stories)
    return EventSeries(units, y0=y0)


def state_after(building: Building, measurements: Sequence[Measurement], band_hz, names: Sequence[str] = (),
                y0: np.ndarray | None = None) -> BuildingState:
    """The state ``building`` is left in by ``measurements`` replayed in order (from ``y0``)."""
    series = event_series(building, measurements, band_hz, "ignore", 4, 2, y0, None)
    return series.states(building, names)[-1]
