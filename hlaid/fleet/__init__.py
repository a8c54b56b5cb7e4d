"""A building portfolio on dask.distributed: ``hlaid fleet FLEET.yaml -o DIR``.

For every building and event: measurement (a file, or station data through ObsPy) ->
identification (:func:`hlaid.identify_clone`) -> ensemble, IDA and decision (``hlaid.uncertainty``,
through the one seam :func:`assess_clone`) -> one row of the fleet table and the portfolio
report. One dask task per (building, event); finished units are kept, so a rerun resumes;
a failing unit does not stop the others. Reference: ``docs/fleet.md``. Names are imported
on first use: the config schema and the scheduler address check load without dask or torch.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .assess import POINT, PointAssessment, assess_clone, default_assess, point_assess
    from .config import BuildingEntry, ClusterConfig, EventSpec, FleetConfig, FleetMeasurement, load_fleet_config
    from .engine import FleetSummary, open_client, run_fleet, run_fleet_from_file
    from .task import UnitJob, make_jobs, run_unit

__all__ = ["FleetConfig", "BuildingEntry", "FleetMeasurement", "EventSpec", "ClusterConfig", "load_fleet_config",
           "run_fleet", "run_fleet_from_file", "FleetSummary", "open_client", "assess_clone", "default_assess",
           "point_assess", "PointAssessment", "POINT", "UnitJob", "make_jobs", "run_unit"]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in {
    ".assess": ("POINT", "PointAssessment", "assess_clone", "default_assess", "point_assess"),
    ".config": ("BuildingEntry", "ClusterConfig", "EventSpec", "FleetConfig", "FleetMeasurement", "load_fleet_config"),
    ".engine": ("FleetSummary", "open_client", "run_fleet", "run_fleet_from_file"),
    ".task": ("UnitJob", "make_jobs", "run_unit"),
}.items() for name in names})
