"""The state a building is left in by the earthquakes it went through.

A clone learns from a building's events in time order and carries what each event left behind
into the next: its accumulated degradation, its residual drift and the hysteretic displacement
that goes with it. :class:`BuildingState` is that state at rest, per story, in the simulator's
own variables. This module is the one owner of the simulator's state vector layout
(:mod:`hlaid.model.building`): per story ``[u, v, z, e]`` blocks of ``story`` values each
(floor displacement, velocity, hysteretic displacement, hysteretic work), with the collapse
memory ``[xp, xn]`` appended when the building has a collapse law; nothing else slices it:

- ``drift``: the residual inter-story drift [mm];
- ``z``: the hysteretic displacement [mm] (at rest ``alpha k0 x + (1 - alpha) k0 z`` is the
  story's residual force, near zero);
- ``work``: the signed hysteretic work per unit ``(1 - alpha) k0``, ``integral(z dx)`` [mm^2],
  which sets the degradation ``eta`` (:meth:`BuildingState.eta`);
- ``peak_positive``, ``peak_negative``: the largest drift of each story in each direction over
  the events [mm] (>= 0): the strength-loss memory of a collapse law.

A state is tied to the building it was simulated with: a clone stores the two together.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..model import Building, equations
from .schema import STATE_BOUNDS

SETTLE_LIMITS_S = (2.0, 10.0)
"""Free vibration after an event before the next one: four first-mode decay times of the
building, within these bounds [s]."""


def settle_time(building: Building, decay_times: float = 4.0,
                limits: tuple[float, float] = SETTLE_LIMITS_S) -> float:
    """Seconds of free vibration that bring ``building`` to rest: ``decay_times`` first-mode decay
    times ``T1 / (2 pi zeta)`` (an elastic oscillation decays by ``exp(decay_times)``), within
    ``limits``."""
    zeta = building.damping.ratio if building.damping.kind != "none" else 0.0
    t1 = float(building.periods()[0])
    return float(np.clip(decay_times * t1 / (2.0 * np.pi * zeta) if zeta > 0 else np.inf, *limits))


def at_rest(y: np.ndarray, n_stories: int) -> np.ndarray:
    """A copy of the state vector(s) ``y`` ``(..., 4*story)`` or ``(..., 6*story)`` with every
    velocity set to zero: the building once the free vibration after an event has died out."""
    out = np.array(y, dtype=float, copy=True)
    out[..., n_stories:2 * n_stories] = 0.0
    return out


@dataclass(frozen=True, eq=False)
class BuildingState:
    """Per-story state of a building at rest after its events.

    Attributes
    ----------
    drift : (story,) residual inter-story drift [mm]
    z : (story,) hysteretic displacement [mm]
    work : (story,) hysteretic work ``integral(z dx)`` [mm^2]
    peak_positive, peak_negative : (story,) largest past drift per direction [mm], >= 0
    events : names of the events that led to it, in time order
    """

    drift: np.ndarray
    z: np.ndarray
    work: np.ndarray
    peak_positive: np.ndarray
    peak_negative: np.ndarray
    events: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self):
        n = np.asarray(self.drift).shape
        for name in ("drift", "z", "work", "peak_positive", "peak_negative"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.ndim != 1 or v.shape != n or not np.all(np.isfinite(v)):
                raise InputError(f"state.{name}: expected {n[0] if n else '?'} finite values, one per story")
            STATE_BOUNDS[name].check(f"state.{name}", v)
            object.__setattr__(self, name, v)

    @property
    def n_stories(self) -> int:
        return int(self.drift.shape[0])

    @classmethod
    def at_rest(cls, n_stories: int) -> BuildingState:
        """The undamaged building: no residual drift, no work done."""
        z = np.zeros(n_stories)
        return cls(drift=z, z=z, work=z, peak_positive=z, peak_negative=z)

    @classmethod
    def from_vector(cls, y: np.ndarray, *, peaks: tuple[np.ndarray, np.ndarray] | None = None,
                    events: tuple[str, ...] = ()) -> BuildingState:
        """The state of a simulator state vector ``y`` ``(4*story,)`` or ``(6*story,)``
        (velocities are dropped: the building is taken at rest). ``peaks``: the largest drift
        per direction, when ``y`` has no collapse memory."""
        y = np.asarray(y, dtype=float).reshape(-1)
        if y.size % 4 and y.size % 6:
            raise InputError(f"state vector of {y.size} values; expected 4 or 6 per story")
        n = y.size // 6 if y.size % 4 else y.size // 4
        if y.size == 6 * n and peaks is None:
            peaks = (y[4 * n:5 * n], y[5 * n:6 * n])
        u = y[:n]
        drift = u - np.concatenate([[0.0], u[:-1]])
        pp, pn = peaks if peaks is not None else (np.abs(drift), np.abs(drift))
        return cls(drift=drift, z=y[2 * n:3 * n], work=y[3 * n:4 * n], peak_positive=np.maximum(pp, 0.0),
                   peak_negative=np.maximum(pn, 0.0), events=tuple(events))

    def vector(self, collapse: bool = False) -> np.ndarray:
        """The simulator's initial state ``[u, v = 0, z, e]`` (``(4*story,)``), with the collapse
        memory ``[xp, xn]`` appended when ``collapse`` (``(6*story,)``)."""
        u = np.cumsum(self.drift)
        y = np.concatenate([u, np.zeros(self.n_stories), self.z, self.work])
        return np.concatenate([y, self.peak_positive, self.peak_negative]) if collapse else y

    def eta(self, building: Building) -> np.ndarray:
        """``(story,)`` the degradation ``eta = 1 + delta_eta eps`` this state gives ``building``."""
        return equations.degradation(self.work, building.alpha, building.k0, building.mass, building.delta_eta)

    def elastic_stiffness(self, building: Building) -> np.ndarray:
        """``(story,)`` the unloading stiffness ``ke = alpha k0 + (1 - alpha) k0 / eta`` [N/mm]."""
        a, k0 = np.asarray(building.alpha), np.asarray(building.k0)
        return a * k0 + (1.0 - a) * k0 / self.eta(building)

    def unloaded(self) -> BuildingState:
        """The same degradation and drift memory with no residual drift and no hysteretic
        displacement: the building as the events left its stiffness, displaced back to its
        origin (the start of an elastic probe)."""
        zero = np.zeros(self.n_stories)
        return BuildingState(drift=zero, z=zero, work=self.work, peak_positive=self.peak_positive,
                             peak_negative=self.peak_negative, events=self.events)

    def is_at_rest(self) -> bool:
        """No residual drift, no hysteretic work: the undamaged start."""
        return not (np.any(self.drift) or np.any(self.z) or np.any(self.work))

    def to_dict(self) -> dict:
        return {"drift": self.drift.tolist(), "z": self.z.tolist(), "work": self.work.tolist(),
                "peak_positive": self.peak_positive.tolist(), "peak_negative": self.peak_negative.tolist(),
                "events": list(self.events)}

    @classmethod
    def from_dict(cls, d: dict) -> BuildingState:
        try:
            return cls(drift=np.asarray(d["drift"], float), z=np.asarray(d["z"], float),
                       work=np.asarray(d["work"], float), peak_positive=np.asarray(d["peak_positive"], float),
                       peak_negative=np.asarray(d["peak_negative"], float),
                       events=tuple(str(e) for e in d.get("events", ())))
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"state: {err}; expected drift, z, work, peak_positive, peak_negative "
                             "(one number per story each)") from None
