"""Incremental dynamic analysis (IDA) and collapse fragility of a clone.

``run_ida(clone, records)`` scales every record to increasing intensities, runs them in batches
of the simulator, finds each record's collapse intensity (drift limit, IDA slope, or
divergence; hunt-and-fill refinement) and returns an :class:`IDAResult` with fractile
curves, lognormal collapse fragility (maximum likelihood, Baker 2015) and drift-limit
exceedance. Method and verification: ``docs/ida.md``.
"""

from .analysis import ida_from_config, run_ida, scan_collapse
from .config import IDAConfig, load_ida_config
from .fragility import (
           LognormalFragility,
           fit_capacities,
           fit_counts,
           fragility_from_capacities,
           fragility_from_exceedance,
)
from .intensity import (
           INTENSITY_MEASURES,
           IntensityMeasure,
           get_intensity_measure,
           intensity,
           response_spectrum,
)
from .prepare import prepare_building
from .results import IDAResult

__all__ = [
           "INTENSITY_MEASURES",
           "IDAConfig",
           "IDAResult",
           "IntensityMeasure",
           "LognormalFragility",
           "fit_capacities",
           "fit_counts",
           "fragility_from_capacities",
           "fragility_from_exceedance",
           "get_intensity_measure",
           "run_ida",
           "ida_from_config",
           "intensity",
           "load_ida_config",
           "prepare_building",
           "response_spectrum",
           "scan_collapse",
]
