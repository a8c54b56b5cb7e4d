"""Results of hysteresis loop analysis: per-story dataclasses, NPZ + JSON on disk."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._fileio import write_json, write_npz
from ..config import config_to_dict
from .config import HLAConfig

HALF_CYCLE_COLUMNS = ("start", "end", "t_start", "t_end", "direction", "drift_increment", "peak_drift", "ke",
                      "ke_raw", "ke_std", "residual_drift", "energy", "energy_before", "damping_coefficient")


@dataclass(frozen=True, eq=False)
class HalfCycleTable:
    """One row per complete half cycle of a story; every field is ``(half_cycle,)``.

    Attributes
    ----------
    start, end : first and last sample index (inclusive); ``t_start``, ``t_end`` [s]
    direction : +1 when the drift increases over the half cycle, -1 when it decreases
    drift_increment : ``|x[end] - x[start]|`` [mm]
    peak_drift : largest ``|x|`` within the half cycle [mm]
    ke : elastic (unloading) stiffness after the reversal [N/mm], smoothed over half cycles
        (``stiffness.ke_smoothing``)
    ke_raw : the least-squares slope of this half cycle alone; ``ke_std`` its standard error
    residual_drift : drift where the elastic branch crosses zero force [mm]
    energy : ``integral(f dx)`` over the half cycle [N mm]
    energy_before : work ``integral(f dx)`` done on the story up to where this half cycle's
        force crosses zero (dissipated energy so far) [N mm]
    damping_coefficient : velocity coefficient fitted with ``damping: regression`` [N s/mm] (else NaN)
    """

    start: np.ndarray
    end: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    direction: np.ndarray
    drift_increment: np.ndarray
    peak_drift: np.ndarray
    ke: np.ndarray
    ke_raw: np.ndarray
    ke_std: np.ndarray
    residual_drift: np.ndarray
    energy: np.ndarray
    energy_before: np.ndarray
    damping_coefficient: np.ndarray

    def __len__(self) -> int:
        return int(self.start.shape[0])

    @property
    def bounds(self) -> np.ndarray:
        """``(half_cycle, 2)`` inclusive start and end sample indices."""
        return np.stack([self.start, self.end], axis=1)

    def select(self, mask: np.ndarray) -> HalfCycleTable:
        return HalfCycleTable(**{c: getattr(self, c)[mask] for c in HALF_CYCLE_COLUMNS})

    def replace(self, **kw) -> HalfCycleTable:
        return dataclasses.replace(self, **kw)

    def rows(self) -> list[dict]:
        return [{c: getattr(self, c)[i].item() for c in HALF_CYCLE_COLUMNS} for i in range(len(self))]


@dataclass(frozen=True, eq=False)
class StoryHLA:
    """Hysteresis loop analysis of one story. Time series are ``(time,)``.

    Attributes
    ----------
    story : 1-based story number
    force : story restoring force ``f`` [N] (per unit total mass [N/t] when mass-normalised),
        low-passed only
    force_fit : the same force band-passed exactly like the drift, on which every slope
        (ke, k(t), features) is fitted
    drift : inter-story drift ``x`` [mm]; ``drift_velocity`` ``dx`` [mm/s]
    k : tangent stiffness ``k(t)`` [N/mm], NaN outside half cycles
    ke : elastic stiffness ``ke(t)`` [N/mm], held over each half cycle, NaN outside
    k0 : initial stiffness [N/mm]
    yielded : whether the story left the elastic range
    half_cycles : the half-cycle table
    """

    story: int
    force: np.ndarray
    force_fit: np.ndarray
    drift: np.ndarray
    drift_velocity: np.ndarray
    k: np.ndarray
    ke: np.ndarray
    k0: float
    yielded: bool
    half_cycles: HalfCycleTable

    def summary(self) -> dict:
        hc = self.half_cycles
        return {"story": self.story, "k0": self.k0, "yielded": self.yielded, "n_half_cycles": len(hc),
                "peak_drift": float(np.max(np.abs(self.drift))),
                "final_ke_over_k0": float(hc.ke[-1] / self.k0) if len(hc) else None,
                "min_ke_over_k0": float(np.nanmin(hc.ke) / self.k0) if len(hc) else None}


@dataclass(frozen=True, eq=False)
class HLAResult:
    """Hysteresis loop analysis of every story of a building.

    Attributes
    ----------
    dt : sample interval [s]
    stories : per-story results, bottom to top
    mass : floor masses used [t] (relative masses summing to 1 when ``mass_normalised``)
    mass_normalised : forces are per unit total mass [N/t] and stiffnesses k/M [N/mm/t]
    damping : how the damping share was handled (``none``, ``rayleigh``, ``regression``)
    pdelta_corrected : whether the P-Delta share was added back to the story forces
    config : the settings used
    band_hz : the band-pass corners used [Hz]
    source : the measurement's file or label
    """

    dt: float
    stories: tuple[StoryHLA, ...]
    mass: np.ndarray
    mass_normalised: bool
    damping: str
    pdelta_corrected: bool
    config: HLAConfig
    band_hz: tuple[float, float] = (0.0, 0.0)
    source: str = ""

    @property
    def n_stories(self) -> int:
        return len(self.stories)

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.stories[0].drift.shape[0]) * self.dt

    @property
    def k0(self) -> np.ndarray:
        return np.array([s.k0 for s in self.stories])

    def stacked(self, name: str) -> np.ndarray:
        """A per-story time series stacked to ``(time, story)``."""
        return np.stack([getattr(s, name) for s in self.stories], axis=1)

    @property
    def units(self) -> dict:
        if self.mass_normalised:
            return {"force": "N/t (per unit total mass)", "stiffness": "N/mm/t (k/M)", "drift": "mm", "time": "s"}
        return {"force": "N", "stiffness": "N/mm", "drift": "mm", "time": "s"}

    def summary(self) -> dict:
        return {"format": "hlaid-hla", "version": 1, "source": self.source, "dt": self.dt,
                "n_samples": int(self.stories[0].drift.shape[0]), "mass_normalised": self.mass_normalised,
                "mass": self.mass.tolist(), "damping": self.damping, "pdelta_corrected": self.pdelta_corrected,
                "band_hz": list(self.band_hz),
                "units": self.units, "stories": [s.summary() for s in self.stories],
                "config": config_to_dict(self.config)}

    def save(self, out_dir: str | os.PathLike, *, force: bool = False) -> dict[str, Path]:
        """Write ``hla.npz`` (time series and half-cycle tables) and ``hla.json`` (summary);
        existing files are replaced only with ``force``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {"dt": np.float64(self.dt), "mass": self.mass}
        for name in ("force", "force_fit", "drift", "drift_velocity", "k", "ke"):
            arrays[name] = self.stacked(name)
        arrays["k0"] = self.k0
        for s in self.stories:
            for c in HALF_CYCLE_COLUMNS:
                arrays[f"story{s.story}_hc_{c}"] = getattr(s.half_cycles, c)
        summary = self.summary()
        summary["half_cycles"] = {f"story{s.story}": s.half_cycles.rows() for s in self.stories}
        return {"npz": write_npz(out / "hla.npz", arrays, force=force),
                "json": write_json(out / "hla.json", summary, force=force)}

    def replace(self, **kw) -> HLAResult:
        return dataclasses.replace(self, **kw)
