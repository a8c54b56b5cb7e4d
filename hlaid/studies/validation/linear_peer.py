"""A linear state-space peer of the clones: ``mdof``'s OKID-ERA or SRIM on the same records.

The peer is a discrete linear model from the ground acceleration (one input [mm/s^2]) to the
floor displacements relative to the ground (one output per floor [mm]): the quantity every
clone is judged on. Outputs are the file's measured displacements when it holds them, else
HLA's integration of the accelerations in the compared band (as :func:`.predict_event` does).
``mdof`` (BRACE2's system identification package) is an optional study dependency
(``pip install hlaid[peer]``); only :meth:`LinearPeer.fit` imports it.

- **Several events.** mdof identifies from one input/output record. Events are joined in
  time order into one record: each event's input and output divided by the RMS of its input
  (a linear model's input/output relation is unchanged; every event weighs alike, not the
  strongest alone), its ends tapered to zero over ``TAPER_S`` seconds, and events separated
  by zeros longer than the model's memory (``horizon`` samples at the decimated rate, and at
  least ``GAP_S``), so no regression row of OKID or SRIM spans two events. One event is used
  as it is.
- **Decimation.** mdof slices every ``decimation``-th sample; the signals are first low-passed
  (zero phase) at 0.45 of the decimated rate so nothing aliases. The prediction is brought
  back to the event's rate (polyphase interpolation) before it is compared.
- **Comparison.** :func:`compare_peer` is :func:`.predict_event`'s metric: R per floor of the
  band-passed displacement, and the peak inter-story drift error.

Shapes are time-first ``(time, floor)`` like :class:`~hlaid.measurement.Measurement`; mdof's
channel-first arrays stay inside this module.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from scipy import signal as ss

from ... import signal as sg
from ...errors import InputError
from ...hla import HLAConfig
from ...hla import preprocess as pp
from ...hla.analysis import floor_motion, resolved_band
from ...identify.replaycheck import corrcoef
from ...measurement import Measurement
from ...units import G_MM_S2

PEER_METHODS = ("okid-era", "srim")
"""mdof's input/output realizations the peer uses (OKID then ERA; SRIM)."""

TAPER_S = 2.0
"""Cosine taper [s] at both ends of each event when several are joined."""

GAP_S = 5.0
"""Shortest run of zeros [s] between joined events."""


@dataclass(frozen=True, kw_only=True)
class PeerSettings:
    """One point of the peer's grid.

    Attributes
    ----------
    method : ``"okid-era"`` or ``"srim"``
    order : model order (2 states per mode)
    horizon : OKID: the number of Markov parameters ``m``; SRIM: the prediction horizon (both
        in samples at the decimated rate)
    rcond : OKID's pseudo-inverse cut-off (relative to the largest singular value); unused
        by SRIM
    decimation : every ``decimation``-th sample is used
    """

    method: str = "okid-era"
    order: int = 4
    horizon: int = 100
    rcond: float = 3e-3
    decimation: int = 1

    def __post_init__(self):
        if self.method not in PEER_METHODS:
            raise InputError(f"peer method {self.method!r}; expected one of {', '.join(PEER_METHODS)}")
        for name, low in (("order", 1), ("horizon", 2), ("decimation", 1)):
            if int(getattr(self, name)) != getattr(self, name) or getattr(self, name) < low:
                raise InputError(f"peer {name} = {getattr(self, name)!r}; expected an integer >= {low}")
        if not 0.0 < self.rcond < 1.0:
            raise InputError(f"peer rcond = {self.rcond!r}; expected 0 < rcond < 1")

    def label(self) -> str:
        tail = f" rcond {self.rcond:g}" if self.method == "okid-era" else ""
        h = "m" if self.method == "okid-era" else "horizon"
        return f"{self.method.upper()} n{self.order} {h} {self.horizon}{tail} /{self.decimation}"

    def options(self) -> dict[str, Any]:
        """mdof's keyword arguments."""
        if self.method == "okid-era":
            return {"method": "okid-era", "order": self.order, "m": self.horizon, "rcond": self.rcond}
        return {"method": "srim", "order": self.order, "horizon": self.horizon}


def peer_grid(*, methods: Sequence[str] = PEER_METHODS, orders: Sequence[int] = (2, 4, 6, 8, 12),
              horizons: Sequence[int] = (50, 100), rconds: Sequence[float] = (1e-3, 3e-3, 1e-2),
              decimations: Sequence[int] = (1,)) -> list[PeerSettings]:
    """Every combination (``rconds`` for OKID-ERA only)."""
    out = []
    for method, n, h, d in itertools.product(methods, orders, horizons, decimations):
        for rc in (rconds if method == "okid-era" else rconds[:1]):
            out.append(PeerSettings(method=method, order=n, horizon=h, rcond=rc, decimation=d))
    return out


def max_decimation(dt: float, band_hz: tuple[float, float]) -> int:
    """The largest decimation that keeps ``band_hz[1]`` under the analysis corner
    (:func:`hlaid.signal.max_corner`) of the decimated rate."""
    return max(1, int(sg.max_corner(dt) / band_hz[1]))


def peer_signals(meas: Measurement, hla_config: HLAConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(ground_acc (time,), relative floor displacement (time, floor))`` the peer is fitted to."""
    if meas.floor_disp is not None:
        return np.asarray(meas.ground_acc, dtype=float), np.asarray(meas.floor_disp, dtype=float)
    return np.asarray(meas.ground_acc, dtype=float), floor_motion(meas, hla_config)[3]


def _antialiased(x: np.ndarray, dt: float, decimation: int) -> np.ndarray:
    if decimation == 1:
        return x
    return sg.lowpass(x, dt, sg.MAX_CORNER_RATIO / (dt * decimation))


def joined_record(pieces: Sequence[tuple[np.ndarray, np.ndarray]], dt: float, horizon: int,
                  decimation: int) -> tuple[np.ndarray, np.ndarray]:
    """One ``(input (time,), output (time, floor))`` record from several events' (see the
    module's docstring); one event is returned as it is."""
    if len(pieces) == 1:
        return pieces[0]
    taper = int(round(TAPER_S / dt))
    gap = max(int(round(GAP_S / dt)), 2 * horizon * decimation)
    us, ys = [], []
    for u, y in pieces:
        scale = float(np.sqrt(np.mean(u**2)))
        if not scale > 0:
            raise InputError("an event's ground acceleration is zero; it cannot identify a peer")
        w = ss.windows.tukey(u.size, alpha=min(1.0, 2.0 * taper / u.size))
        us += [w * u / scale, np.zeros(gap)]
        ys += [w[:, None] * y / scale, np.zeros((gap, y.shape[1]))]
    return np.concatenate(us[:-1]), np.concatenate(ys[:-1])


class LinearPeer:
    """mdof's linear state-space model of a structure, identified from one or several events.

    Parameters
    ----------
    settings : the grid point (:class:`PeerSettings`)
    hla_config : how relative displacements are made when the file has none
    stabilize : remove unstable discrete modes after the realization (mdof's ``stabilize``)

    Attributes
    ----------
    realization_ : mdof's ``Realization`` (A, B, C, D at the decimated rate)
    dt_ : sample interval of the events [s]
    n_floors_ : outputs
    """

    def __init__(self, settings: PeerSettings | None = None, *, hla_config: HLAConfig | None = None,
                 stabilize: bool = True):
        self.settings = settings
        self.hla_config = hla_config
        self.stabilize = stabilize

    @property
    def _s(self) -> PeerSettings:
        return self.settings or PeerSettings()

    def fit(self, events: Sequence[Measurement]) -> LinearPeer:
        """Identify from ``events`` (in time order, one sample interval and floor count)."""
        import mdof

        if not events:
            raise InputError("a peer needs at least one event")
        dt, nf = events[0].dt, events[0].n_floors
        for m in events[1:]:
            if abs(m.dt / dt - 1.0) > 1e-6 or m.n_floors != nf:
                raise InputError(f"events differ: dt {m.dt:g} s, {m.n_floors} floors; expected {dt:g} s, {nf} floors",
                                 source=m.source or None)
        s, cfg = self._s, self.hla_config or HLAConfig()
        u, y = joined_record([peer_signals(m, cfg) for m in events], dt, s.horizon, s.decimation)
        d = s.decimation
        u, y = _antialiased(u, dt, d)[::d], _antialiased(y, dt, d)[::d]
        real = mdof.system(u[None, :], y.T, dt=dt * d, **s.options())
        self.realization_ = real.stabilize() if self.stabilize else real
        self.dt_, self.n_floors_ = dt, nf
        return self

    def predict(self, meas: Measurement) -> np.ndarray:
        """``(time, floor)`` floor displacement relative to the ground [mm] under ``meas``'s
        ground acceleration, from rest, at ``meas``'s rate."""
        if not hasattr(self, "realization_"):
            raise InputError("the peer is not fitted; call fit(events) first")
        if abs(meas.dt / self.dt_ - 1.0) > 1e-6:
            raise InputError(f"dt {meas.dt:g} s; the peer was identified at {self.dt_:g} s", source=meas.source or None)
        d = self._s.decimation
        u = _antialiased(np.asarray(meas.ground_acc, dtype=float), meas.dt, d)[::d]
        y = np.real(np.asarray(self.realization_.predict(u[None, :]))).T
        if d > 1:
            y = ss.resample_poly(y, d, 1, axis=0)
        n = meas.n_samples
        return np.pad(y[:n], ((0, max(0, n - y.shape[0])), (0, 0)), mode="edge")


@dataclass(frozen=True, eq=False)
class PeerPrediction:
    """The peer under one event, against what was measured (:func:`.predict_event`'s metric).

    Attributes
    ----------
    event : the predicted event's name
    pga_g : its peak ground acceleration [g]
    band_hz : band of the compared displacements [Hz]
    r : (floor,) correlation of predicted and measured band-passed displacement
    peak_drift_measured, peak_drift_predicted : (story,) [mm]
    peak_drift_error : (story,) ``predicted / measured - 1``
    time, disp_measured, disp_predicted : (time,), (time, floor) [s, mm] (not serialised)
    """

    event: str
    pga_g: float
    band_hz: tuple[float, float]
    r: np.ndarray
    peak_drift_measured: np.ndarray
    peak_drift_predicted: np.ndarray
    peak_drift_error: np.ndarray
    time: np.ndarray = field(repr=False)
    disp_measured: np.ndarray = field(repr=False)
    disp_predicted: np.ndarray = field(repr=False)

    @property
    def r_mean(self) -> float:
        return float(np.mean(self.r))

    def summary(self) -> dict:
        return {"event": self.event, "pga_g": self.pga_g, "band_hz": list(self.band_hz), "r": self.r.tolist(),
                "r_mean": self.r_mean, "peak_drift_measured": self.peak_drift_measured.tolist(),
                "peak_drift_predicted": self.peak_drift_predicted.tolist(),
                "peak_drift_error": self.peak_drift_error.tolist()}


def compare_peer(peer: LinearPeer, meas: Measurement, hla_config: HLAConfig, band_hz: tuple[float, float], *,
                 event: str = "") -> PeerPrediction:
    """``peer`` under ``meas`` against what was measured, band-passed in ``band_hz``."""
    import dataclasses

    cfg = dataclasses.replace(hla_config, preprocess=dataclasses.replace(hla_config.preprocess, band_hz=band_hz))
    dm = floor_motion(meas, cfg)[3]
    dp = sg.bandpass(peer.predict(meas), meas.dt, band_hz, cfg.preprocess.order)
    pm = np.max(np.abs(pp.story_drift(dm)), axis=0)
    pk = np.max(np.abs(pp.story_drift(dp)), axis=0)
    return PeerPrediction(event=event, pga_g=float(np.max(np.abs(meas.ground_acc)) / G_MM_S2), band_hz=band_hz,
                          r=corrcoef(dp, dm), peak_drift_measured=pm, peak_drift_predicted=pk,
                          peak_drift_error=pk / pm - 1.0, time=meas.time, disp_measured=dm, disp_predicted=dp)


@dataclass(frozen=True, eq=False)
class PeerCase:
    """The peer identified on some events predicting another: the grid point chosen by its
    self-fit (mean R of its replay of the identification events, all it may see) and, apart,
    the oracle (the grid point best on this very prediction: the peer's ceiling, not a result).

    Attributes
    ----------
    structure : structure name
    identified_on : the identification events, in time order
    chosen, self_r, prediction : the self-fit choice, its self-fit R, its prediction
    oracle, oracle_prediction : the best grid point on this prediction, and its prediction
    n_grid, n_failed : grid points tried, and those that failed (mdof error, unstable output)
    """

    structure: str
    identified_on: tuple[str, ...]
    chosen: PeerSettings
    self_r: float
    prediction: PeerPrediction
    oracle: PeerSettings
    oracle_prediction: PeerPrediction
    n_grid: int
    n_failed: int

    def summary(self) -> dict:
        return {"structure": self.structure, "identified_on": list(self.identified_on),
                "event": self.prediction.event, "chosen": self.chosen.label(), "self_r": self.self_r,
                "prediction": self.prediction.summary(), "oracle": self.oracle.label(),
                "oracle_prediction": self.oracle_prediction.summary(), "n_grid": self.n_grid,
                "n_failed": self.n_failed}


def _evaluate(args) -> tuple[float, list[PeerPrediction]] | None:
    """One grid point: fit, self-fit R, predictions; None when mdof or the model fails."""
    s, train, targets, hla_config = args
    try:
        peer = LinearPeer(s, hla_config=hla_config).fit([m for _, m in train])
        own = [compare_peer(peer, m, hla_config, compared_band(m, hla_config), event=n).r_mean for n, m in train]
        preds = [compare_peer(peer, m, hla_config, compared_band(m, hla_config), event=n) for n, m in targets]
    except InputError:
        raise
    except (ArithmeticError, AssertionError, ValueError, np.linalg.LinAlgError):
        return None  # mdof refuses some (method, order, horizon) on some records
    self_r = float(np.mean(own))
    if not np.isfinite(self_r) or not all(np.isfinite(p.r_mean) for p in preds):
        return None
    return self_r, preds


def compared_band(meas: Measurement, hla_config: HLAConfig) -> tuple[float, float]:
    """The config's band, else the one HLA chooses for ``meas`` (as :func:`.predict_event`)."""
    return cast("tuple[float, float]", tuple(resolved_band(meas, hla_config)))


def peer_cases(structure: str, train: Sequence[tuple[str, Measurement]],
               targets: Sequence[tuple[str, Measurement]], grid: Sequence[PeerSettings], hla_config: HLAConfig, *,
               mapper: Callable = map) -> list[PeerCase]:
    """For every grid point: fit on ``train`` (``(name, event)`` in time order), replay the
    identification events and predict each of ``targets`` (compared in
    :func:`compared_band`); one :class:`PeerCase` per target.

    ``mapper(function, iterable)`` evaluates the grid points (``map``; a process pool's
    ``imap`` to use several cores).
    """
    rows = [(s, *res) for s, res in zip(grid, mapper(_evaluate, [(s, train, targets, hla_config) for s in grid]))
            if res is not None]
    failed = len(grid) - len(rows)
    if not rows:
        raise InputError(f"{structure}: every one of the {len(grid)} peer settings failed on {[n for n, _ in train]}")
    best = max(rows, key=lambda row: row[1])
    out = []
    for j in range(len(targets)):
        oracle = max(rows, key=lambda row: row[2][j].r_mean)
        out.append(PeerCase(structure=structure, identified_on=tuple(n for n, _ in train), chosen=best[0],
                            self_r=best[1], prediction=best[2][j], oracle=oracle[0],
                            oracle_prediction=oracle[2][j], n_grid=len(grid), n_failed=failed))
    return out
