"""Config schemas shared by several commands: the building, its damping, a ground motion, and the
``hlaid simulate`` config (a building, a motion, the sensors).

Relative file paths in a config are resolved against the folder of the config file. This module
imports no heavy library: a config is checked (every number against the bounds of its field,
:mod:`hlaid.bounds`) before the simulator, torch or scipy is loaded.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from .bounds import SEED, bounded, check_bounds, with_bounds
from .config import load_config
from .errors import InputError
from .limits import check_count
from .model.schema import STORY_BOUNDS, WEIGHT_KN, Damping
from .units import check_units

if TYPE_CHECKING:
    from .model import Building
    from .motions import GroundMotion

@dataclass(frozen=True, kw_only=True)
class StorySpec:
    """One story, bottom to top: mass (``mass_t``) or weight (``weight_kN``) and its spring."""

    k0: float = with_bounds(STORY_BOUNDS["k0"])
    alpha: float = with_bounds(STORY_BOUNDS["alpha"])
    p: float = with_bounds(STORY_BOUNDS["p"])
    dy: float = with_bounds(STORY_BOUNDS["dy"])
    delta_eta: float = with_bounds(STORY_BOUNDS["delta_eta"])
    weight_kN: float | None = with_bounds(WEIGHT_KN, None)
    mass_t: float | None = with_bounds(STORY_BOUNDS["mass"], None)
    height_mm: float | None = with_bounds(STORY_BOUNDS["height"], None)
    gravity_kN: float | None = bounded(None, lo=0.0, hi=WEIGHT_KN.hi, unit="kN")

    def __post_init__(self):
        if (self.weight_kN is None) == (self.mass_t is None):
            raise InputError("give exactly one of mass_t or weight_kN")
        check_bounds(self)

    def as_dict(self) -> dict:
        return {k: v for k, v in vars(self).items() if v is not None}


@dataclass(frozen=True, kw_only=True)
class BuildingSpec:
    """A shear building: stories bottom to top, damping, P-Delta (default: when heights are known)."""

    stories: list[StorySpec]
    damping: Damping = field(default_factory=Damping)
    pdelta: bool | None = None
    name: str = ""

    def __post_init__(self):
        if not self.stories:
            raise InputError("stories: at least one story is needed")
        check_count(len(self.stories), "STORIES", "stories")
        self.damping.check_modes(len(self.stories))

    def build(self, source: str | None = None) -> Building:
        from .model import Building
        return Building.from_stories([s.as_dict() for s in self.stories], damping=self.damping, pdelta=self.pdelta,
                                     name=self.name, source=source)


@dataclass(frozen=True, kw_only=True)
class MotionSpec:
    """A ground motion: ``builtin:NAME`` or a file, optionally scaled to a PGA or by a factor."""

    file: str
    pga_g: float | None = bounded(None, lo=1e-4, hi=10.0, unit="g")
    scale: float | None = bounded(None, lo=1e-6, hi=1e4)
    units: str | None = None
    dt: float | None = bounded(None, lo=1e-5, hi=0.2, unit="s")
    column: int | None = bounded(None, lo=0, hi=10_000)
    format: Literal["at2", "text", "csv"] | None = None

    def __post_init__(self):
        if self.pga_g is not None and self.scale is not None:
            raise InputError("give pga_g or scale, not both")
        check_bounds(self)
        check_units(self.units, "motion.units")

    def path(self, base_dir: str | Path | None = None) -> str:
        """``file``, a relative path taken from ``base_dir``."""
        spec = self.file
        if not spec.startswith("builtin:") and base_dir is not None and not Path(spec).is_absolute():
            spec = str(Path(base_dir) / spec)
        return spec

    def load(self, base_dir: str | Path | None = None) -> GroundMotion:
        """Read (and scale) the record; relative paths are taken from ``base_dir``."""
        from .io import read
        gm = read(self.path(base_dir), "motion", units=self.units, dt=self.dt, column=self.column,
                  format=self.format)
        if self.pga_g is not None:
            gm = gm.scaled_to_pga(self.pga_g)
        elif self.scale is not None:
            gm = gm.scaled(self.scale)
        return gm


@dataclass(frozen=True, kw_only=True)
class MeasurementSpec:
    """Sampling and noise of simulated accelerometers (the rate within 5 Hz and ``HLAID_MAX_RATE_HZ``)."""

    rate_hz: float = bounded(200.0, lo=5.0, hi="RATE_HZ", unit="Hz")
    noise_rms: float = bounded(0.10, lo=0.0, hi=10.0, hi_open=True)
    substeps: int = bounded(4, lo=1, hi=64)

    def __post_init__(self):
        check_bounds(self)


@dataclass(frozen=True, kw_only=True)
class SimulationConfig:
    """``hlaid simulate`` config: a building, a ground motion, the sensors and a seed."""

    building: BuildingSpec
    motion: MotionSpec
    measurement: MeasurementSpec = field(default_factory=MeasurementSpec)
    seed: int = with_bounds(SEED, 0)

    def __post_init__(self):
        check_bounds(self)


def load_simulation_config(path) -> SimulationConfig:
    """Load and validate an ``hlaid simulate`` config (no heavy library is imported)."""
    return load_config(path, SimulationConfig)
