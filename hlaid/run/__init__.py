"""A run folder: ``hlaid run`` / ``hlaid demo`` write it, ``hlaid report`` and ``hlaid loss`` read it.

:mod:`.runner` runs the pipeline (measurement -> HLA -> clone -> replay -> IDA -> assessment ->
losses) into one folder; :mod:`.config` is the run config's schema; :mod:`.summary` the run's
typed, versioned summary (``summary.json``, :class:`RunSummary`); :mod:`.report` renders
``report.html`` from it, one module per section under :mod:`.sections`; :mod:`.loss` adds the
losses to an existing run folder (``hlaid loss RUN_DIR``).

The public names load on first use (a module-level ``__getattr__``, PEP 562), so reading a run
config imports no heavy library. No name here is also the name of a submodule.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .config import MeasurementSource, RunConfig, input_paths, load_run_config
    from .loss import loss_of_run, run_collapse
    from .report import build_report, embedded_figures, screenshot
    from .runner import load_measurement, parameter_table, run_from_file, run_pipeline
    from .summary import RunSummary, read_summary

__all__ = ["RunConfig", "MeasurementSource", "load_run_config", "input_paths", "run_pipeline", "run_from_file",
           "load_measurement", "parameter_table", "build_report", "embedded_figures", "screenshot", "loss_of_run",
           "run_collapse", "RunSummary", "read_summary"]

_WHERE = {
    **dict.fromkeys(("RunConfig", "MeasurementSource", "load_run_config", "input_paths"), ".config"),
    **dict.fromkeys(("run_pipeline", "run_from_file", "load_measurement", "parameter_table"), ".runner"),
    **dict.fromkeys(("build_report", "embedded_figures", "screenshot"), ".report"),
    **dict.fromkeys(("loss_of_run", "run_collapse"), ".loss"),
    **dict.fromkeys(("RunSummary", "read_summary"), ".summary"),
}
"""Public name -> the submodule that defines it (the names of ``__all__``)."""

__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
