"""The ``loss:`` block of ``hlaid run`` / ``hlaid fleet`` configs and the settings of ``hlaid loss``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..bounds import SEED, bounded, check_bounds, with_bounds
from ..errors import InputError


@dataclass(frozen=True, kw_only=True)
class LossConfig:
    """Settings of the FEMA P-58 loss assessment (docs/loss.md).

    system : default component inventory and replacement values: ``steel-moment-frame`` or ``rc-frame``
        (:data:`hlaid.loss.inventory.INVENTORIES`)
    inventory : the user's inventory CSV (pelicun's component assignment format) instead of the
        system's; relative paths from the config's folder
    floor_area_m2 : floor area [m2] of every story (one number) or per story, bottom to top; None:
        the clone's floor masses / the system's areal mass (refused for a mass-normalised clone)
    replacement_cost_usd, replacement_time_worker_days : of the whole building; None: the system's
        values per m2 x total floor area
    irreparable_median, irreparable_beta : FEMA P-58's residual drift fragility (median residual
        drift ratio 1 %, dispersion 0.3)
    realizations : pelicun's sample size per assessment
    seed : pelicun's seed
    levels : IM levels [g] of the loss curve against intensity (IDA stripes); None: the IDA's grid
        levels; [] none
    """

    system: str = "steel-moment-frame"
    inventory: str | None = None
    floor_area_m2: float | list[float] | None = bounded(None, lo=0.01, hi=1e7, unit="m2")
    replacement_cost_usd: float | None = bounded(None, lo=1.0, hi=1e13, unit="USD")
    replacement_time_worker_days: float | None = bounded(None, lo=0.01, hi=1e9)
    irreparable_median: float = bounded(0.01, lo=1e-4, hi=1.0, hi_open=True)
    irreparable_beta: float = bounded(0.3, lo=0.01, hi=5.0)
    realizations: int = bounded(1000, lo=10, hi=100_000)
    seed: int = with_bounds(SEED, 0)
    levels: list[float] | None = bounded(None, lo=1e-6, hi=100.0, unit="g")

    def __post_init__(self):
        from .inventory import get_inventory

        check_bounds(self, prefix="loss.")
        get_inventory(self.system)
        if isinstance(self.floor_area_m2, list) and not self.floor_area_m2:
            raise InputError("loss.floor_area_m2 is empty; give one area [m2] or one per story")
        for name in ("realizations", "seed"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int):
                raise InputError(f"loss.{name} = {v!r}; expected a whole number")
        if self.levels:
            from ..ida.config import check_levels

            check_levels(self.levels)

    def replace(self, **changes) -> LossConfig:
        """A copy with the given fields changed (None values are ignored)."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def floor_areas(self, n_stories: int, masses=None) -> tuple[list[float], str]:
        """Floor area [m2] per story and where it came from: ``floor_area_m2``, else the floor
        ``masses`` [t] (None: unknown, e.g. a mass-normalised clone) / the system's areal mass."""
        from .inventory import get_inventory

        n = n_stories
        if self.floor_area_m2 is not None:
            a = self.floor_area_m2 if isinstance(self.floor_area_m2, list) else [self.floor_area_m2] * n
            if len(a) != n:
                raise InputError(f"loss.floor_area_m2 has {len(a)} values; the building has {n} stories")
            return [float(v) for v in a], "given"
        if masses is None:
            raise InputError("the floor masses are unknown (a mass-normalised clone or a demand file): give the "
                             "floor area (loss.floor_area_m2, hlaid loss --floor-area M2)")
        rho = get_inventory(self.system).areal_mass_t_m2
        return [float(m) / rho for m in masses], (f"floor mass / {rho:g} t/m2 (a typical {self.system} office "
                                                  "floor; give floor_area_m2 to replace it)")


__all__ = ["LossConfig"]
