"""Incremental dynamic analysis (IDA) and collapse fragility of a clone.

``run_ida(clone, records)`` scales every record to increasing intensities, runs them in batches
of the simulator, finds each record's collapse intensity (drift limit, IDA slope, or
divergence; hunt-and-fill refinement) and returns an :class:`IDAResult` with fractile
curves, lognormal collapse fragility (maximum likelihood, Baker 2015) and drift-limit
exceedance. :func:`assess` runs it over an ensemble of clones drawn from the identification
uncertainty: the fragility band, the probabilities at the building's own record and a
re-occupancy indicator (``docs/uncertainty.md``). Method and verification: ``docs/ida.md``. Names
are imported on first use:
:mod:`hlaid.ida.config` (the schema) loads without scipy or torch.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .analysis import ida_from_config, run_ida, scan_collapse
    from .assessment import Assessment, ReoccupancyThresholds, assess
    from .config import IDAConfig, load_ida_config
    from .fragility import (
        LognormalFragility,
        fit_capacities,
        fit_counts,
        fragility_from_capacities,
        fragility_from_exceedance,
    )
    from .measures import INTENSITY_MEASURES, IntensityMeasure, get_intensity_measure, intensity, response_spectrum
    from .prepare import prepare_building
    from .results import IDAResult

_WHERE = {
    ".analysis": ("run_ida", "ida_from_config", "scan_collapse"),
    ".assessment": ("Assessment", "ReoccupancyThresholds", "assess"),
    ".config": ("IDAConfig", "load_ida_config"),
    ".fragility": ("LognormalFragility", "fit_capacities", "fit_counts", "fragility_from_capacities",
                   "fragility_from_exceedance"),
    ".measures": ("INTENSITY_MEASURES", "IntensityMeasure", "get_intensity_measure", "intensity", "response_spectrum"),
    ".prepare": ("prepare_building",),
    ".results": ("IDAResult",),
}

__all__ = ["Assessment", "ReoccupancyThresholds", "assess",
           "INTENSITY_MEASURES", "IDAConfig", "IDAResult", "IntensityMeasure", "LognormalFragility", "fit_capacities",
           "fit_counts", "fragility_from_capacities", "fragility_from_exceedance", "get_intensity_measure", "run_ida",
           "ida_from_config", "intensity", "load_ida_config", "prepare_building", "response_spectrum", "scan_collapse"]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
