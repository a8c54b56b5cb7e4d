"""``hlaid ida`` configuration: a YAML file validated against :class:`IDAConfig`."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from ..bounds import SEED, bounded, check_bounds, with_bounds
from ..config import load_config
from ..errors import InputError
from ..limits import check_count
from ..model.schema import STORY_BOUNDS, WEIGHT_KN
from ..units import check_units, kn_to_n

DEFAULT_EXCEEDANCE = (0.005, 0.01, 0.02, 0.04)
"""Drift-ratio limits whose probability of exceedance is reported (0.5, 1, 2, 4 %)."""


@dataclass(frozen=True, kw_only=True)
class IDAConfig:
    """Settings of an incremental dynamic analysis (units: IM in g, heights in mm, step in s).

    Attributes
    ----------
    records : a folder of AT2/text records, ``builtin-suite``, or a list of files (relative
        paths are taken from the config file's folder); the command line's ``--records`` wins
    units : acceleration units of text records (AT2 files state theirs)
    im : intensity measure, ``sa_t1`` (Sa(T1, 5%)) or ``pga``
    levels : IM levels [g], strictly increasing; None: ``n_levels`` levels in geometric steps up to
        the equal-displacement estimate of the median IM at the drift limit, from half that at the
        smallest exceedance limit (the small-drift fragilities rise at low intensities)
    drift_limit : collapse when a story's drift ratio exceeds it (0.10 is 10 %)
    slope_ratio : collapse when the IDA curve's slope drops below this fraction of the elastic slope
    exceedance_limits : drift ratios whose probability of exceedance is reported; None: 0.5, 1,
        2 and 4 % (those below the drift limit)
    refine : hunt (step up until collapse) and bisect (fill) the collapse intensity per record
    hunt_factor, max_hunt : hunting steps multiply the IM by ``hunt_factor``, at most ``max_hunt`` times
    tolerance, max_fill : bisect until the collapse bracket is narrower than ``tolerance`` x IM
    max_step : largest RK4 step [s]; each record gets ``ceil(dt / max_step)`` sub-steps
    pdelta : None: on when story heights are known; true/false force it
    heights_mm, gravity_kN : per-story heights and floor gravity loads replacing the clone's
    period : the period [s] of Sa instead of the clone's T1
    collapse : strength-loss model of the stories: a name of
        :data:`hlaid.model.collapse.COLLAPSE_MODELS` (``none``, ``steel-mrf``, ``rc-frame``,
        ``rc-frame-nonductile``) or a mapping ``{theta_p, theta_pc, kappa, theta_u}``; None: the
        clone's own ``collapse`` block, else ``none`` (no strength loss: collapse only at the
        drift limit or the slope criterion; a note says so), or the collapse law of the clone's
        structural system (``clone.system``, :data:`hlaid.systems.SYSTEMS`) when it names one
    start : ``undamaged``: every run starts at rest; ``carried``: from the state the clone's last
        event left it in (residual drift, hysteretic state, accumulated degradation and, with a
        collapse law, the largest drifts so far): the fragility of the building after that event;
        ``auto``: as the clone says (:func:`hlaid.events.start.resolve_start`)
    bootstrap, ci, seed : bootstrap resamples, confidence level and seed of the fragility intervals
    """

    records: str | list[str] | None = None
    units: str | None = None
    im: Literal["sa_t1", "pga"] = "sa_t1"
    levels: list[float] | None = bounded(None, lo=1e-6, hi=100.0, unit="g")
    n_levels: int = bounded(20, lo=2, hi="IDA_LEVELS")
    drift_limit: float = bounded(0.10, lo=1e-4, hi=0.5)
    slope_ratio: float = bounded(0.20, lo=1e-3, hi=1.0, hi_open=True)
    exceedance_limits: list[float] | None = bounded(None, lo=1e-5, hi=10.0, hi_open=True)
    refine: bool = True
    hunt_factor: float = bounded(1.5, lo=1.0, hi=100.0, lo_open=True)
    max_hunt: int = bounded(10, lo=0, hi="IDA_LEVELS")
    tolerance: float = bounded(0.02, lo=1e-4, hi=1.0, hi_open=True)
    max_fill: int = bounded(12, lo=0, hi="IDA_LEVELS")
    max_step: float = bounded(0.0025, lo=1e-6, hi=1.0, unit="s")
    pdelta: bool | None = None
    heights_mm: list[float] | None = with_bounds(STORY_BOUNDS["height"], None)
    gravity_kN: list[float] | None = bounded(None, lo=0.0, hi=WEIGHT_KN.hi, unit="kN")
    period: float | None = bounded(None, lo=1e-3, hi=100.0, unit="s")
    collapse: str | dict[str, float | str] | None = None
    start: Literal["undamaged", "carried", "auto"] = "undamaged"
    bootstrap: int = bounded(1000, lo=0, hi="BOOTSTRAP")
    ci: float = bounded(0.90, lo=0.01, hi=0.999)
    seed: int = with_bounds(SEED, 0)

    def __post_init__(self):
        check_bounds(self)
        check_units(self.units, "units")
        if self.levels is not None:
            check_count(len(self.levels), "IDA_LEVELS", "number of levels")
            check_levels(self.levels)
        if self.collapse is not None:
            from ..model.collapse import get_collapse_model
            get_collapse_model(self.collapse)
        for d in self.exceedance_limits or ():
            if not d < self.drift_limit:
                raise InputError(f"exceedance_limits: {d:g} is not below drift_limit = {self.drift_limit:g}")

    def replace(self, **changes) -> IDAConfig:
        """A copy with the given fields changed (None values are ignored)."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def gravity_load_n(self) -> list[float] | None:
        """The floor gravity loads [N] (``gravity_kN`` converted), or None."""
        return None if self.gravity_kN is None else [kn_to_n(v) for v in self.gravity_kN]

    def record_specs(self, base_dir: str | Path | None = None) -> list[str] | None:
        """The records, relative paths resolved against ``base_dir``."""
        if self.records is None:
            return None
        specs = [self.records] if isinstance(self.records, str) else list(self.records)
        out = []
        for s in specs:
            if base_dir is not None and not s.startswith("builtin") and not Path(s).is_absolute():
                s = str(Path(base_dir) / s)
            out.append(s)
        return out


def check_levels(levels) -> list[float]:
    """Validate IM levels: finite, positive, strictly increasing; returns them as floats."""
    try:
        lv = [float(v) for v in levels]
    except (TypeError, ValueError):
        raise InputError(f"levels must be numbers [g], got {levels!r}") from None
    if not lv:
        raise InputError("levels is empty; give increasing IM levels [g]")
    if not all(math.isfinite(v) and v > 0 for v in lv):
        raise InputError(f"levels must be positive IM values [g], got {lv}")
    bad = [i for i in range(1, len(lv)) if lv[i] <= lv[i - 1]]
    if bad:
        i = bad[0]
        raise InputError(f"levels must be strictly increasing; level {i + 1} ({lv[i]:g} g) is not above "
                         f"level {i} ({lv[i - 1]:g} g)")
    return lv


def load_ida_config(path) -> IDAConfig:
    """Load and validate an IDA config YAML (unknown keys and wrong types name file:line)."""
    return load_config(path, IDAConfig)
