"""Config schemas shared by several commands: the building, its damping and a ground motion.

Relative file paths in a config are resolved against the folder of the config file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from .errors import InputError
from .io import read
from .limits import check_count
from .model import Building, Damping
from .model.params import check_story_value
from .motions import GroundMotion


@dataclass(frozen=True, kw_only=True)
class StorySpec:
    """One story, bottom to top: mass (``mass_t``) or weight (``weight_kN``) and its spring."""

    k0: float
    alpha: float
    p: float
    dy: float
    delta_eta: float
    weight_kN: float | None = None
    mass_t: float | None = None
    height_mm: float | None = None
    gravity_kN: float | None = None

    def __post_init__(self):
        if (self.weight_kN is None) == (self.mass_t is None):
            raise InputError("give exactly one of mass_t or weight_kN")
        for name in ("k0", "alpha", "p", "dy", "delta_eta"):
            check_story_value(name, getattr(self, name))
        check_story_value("mass", self.mass_t if self.mass_t is not None else self.weight_kN)
        if self.height_mm is not None:
            check_story_value("height", self.height_mm)
        if self.gravity_kN is not None:
            check_story_value("gravity_load", self.gravity_kN)

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

    def build(self, source: str | None = None) -> Building:
        return Building.from_stories([s.as_dict() for s in self.stories], damping=self.damping, pdelta=self.pdelta,
                                     name=self.name, source=source)


@dataclass(frozen=True, kw_only=True)
class MotionSpec:
    """A ground motion: ``builtin:NAME`` or a file, optionally scaled to a PGA or by a factor."""

    file: str
    pga_g: float | None = None
    scale: float | None = None
    units: str | None = None
    dt: float | None = None
    column: int | None = None
    format: Literal["at2", "text", "csv"] | None = None

    def __post_init__(self):
        if self.pga_g is not None and self.scale is not None:
            raise InputError("give pga_g or scale, not both")
        if self.pga_g is not None and not self.pga_g > 0:
            raise InputError(f"pga_g = {self.pga_g}; expected a positive value")

    def load(self, base_dir: str | Path | None = None) -> GroundMotion:
        """Read (and scale) the record; relative paths are taken from ``base_dir``."""
        spec = self.file
        if not spec.startswith("builtin:") and base_dir is not None and not Path(spec).is_absolute():
            spec = str(Path(base_dir) / spec)
        gm = read(spec, "motion", units=self.units, dt=self.dt, column=self.column, format=self.format)
        if self.pga_g is not None:
            gm = gm.scaled_to_pga(self.pga_g)
        elif self.scale is not None:
            gm = gm.scaled(self.scale)
        return gm
