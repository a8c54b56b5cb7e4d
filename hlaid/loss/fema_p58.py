"""The FEMA P-58 assessment through pelicun (the optional extra ``hlaid[loss]``).

:func:`write_inputs` writes what pelicun's own command line reads, into one folder:
``demands.csv`` (hlaid's demands, :class:`~hlaid.loss.demands.Demands`), ``inventory.csv`` (the
component assignment) and ``config.json`` (pelicun's ``DL`` configuration). :func:`run_pelicun`
runs the assessment on those files in this process, through pelicun's ``DLCalculationAssessment``
with the same calls in the same order as its command line
(``python -m pelicun.tools.DL_calculation -c config.json -d demands.csv``), so both give the same
realizations for the same seed. The configuration:

* demands: the realizations as written (``empirical``: resampled to ``realizations`` rows); the
  collapsed realizations removed by ``CollapseLimits`` (PID above the drift limit); the drift
  demands copied to direction 2 (``DemandCloning``: the clone is planar, the orthogonal direction
  is assumed to drift alike), floor accelerations and residual drifts in direction 1 only;
* collapse: hlaid's lognormal collapse fragility in the intensity (``SA_T1`` or ``PGA``), sampled per
  realization against the realization's intensity; a collapse costs the replacement;
* irreparable damage: FEMA P-58's residual drift fragility (``IrreparableDamage``, median 1 %,
  dispersion 0.3 by default), evaluated by pelicun per story; an irreparable building costs the
  replacement;
* ``DamageProcess: FEMA P-58``, FEMA P-58 component fragilities and repair consequences (DLML),
  pelicun's defaults otherwise (economies of scale, non-directional multiplier 1.2).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._fileio import atomic_write
from ..errors import InputError, one_line
from ..units import G_M_S2

UNITS = ("ea", "EA", "m", "mm", "cm", "ft", "in", "inch", "m2", "mm2", "cm2", "ft2", "in2", "inch2", "SF", "LF")
"""Quantity units an inventory may use (pelicun's)."""

DATABASE = "FEMA P-58"
COST_UNIT = "USD_2011"
TIME_UNIT = "worker_day"


def require_pelicun():
    """The ``pelicun`` module; an InputError saying how to install it when it is missing or unusable."""
    try:
        import pelicun.assessment  # noqa: F401
        import pelicun.file_io  # noqa: F401
    except ImportError as err:
        raise InputError("the loss assessment needs pelicun and its damage and loss library: pip install "
                         f"'hlaid[loss]' ({type(err).__name__}: {one_line(err)})") from None
    import pelicun
    return pelicun


def library_file(name: str) -> Path:
    """A file of the FEMA P-58 dataset shipped with pelicun (``fragility.csv``, ``consequence_repair.csv``)."""
    require_pelicun()
    from pelicun.file_io import resolve_default_dataset_path

    return Path(resolve_default_dataset_path(DATABASE)) / name


@dataclass(frozen=True, kw_only=True)
class PelicunInputs:
    """Everything one pelicun assessment needs.

    demands_csv, inventory_csv : the file texts (pelicun's demand and component assignment formats)
    n_stories : stories of the building
    im_type : pelicun's demand type of the intensity column (``SA_0.413`` or ``PGA``)
    collapse_median_g, collapse_beta : the lognormal collapse fragility in that intensity (None: no
        collapse fragility; collapsed realizations are still removed from the demands)
    drift_limit : PID above which a realization is a collapse (``CollapseLimits``)
    replacement_cost, replacement_time : [USD_2011], [worker-days]
    irreparable_median, irreparable_beta : the residual drift fragility
    realizations, seed : pelicun's sample size and seed
    directions : drift demand directions (2: direction 1 copied to 2)
    """

    demands_csv: str
    inventory_csv: str
    n_stories: int
    im_type: str
    collapse_median_g: float | None
    collapse_beta: float | None
    drift_limit: float
    replacement_cost: float
    replacement_time: float
    irreparable_median: float = 0.01
    irreparable_beta: float = 0.3
    realizations: int = 1000
    seed: int = 0

    def config(self) -> dict:
        """pelicun's configuration (the content of ``config.json``)."""
        n = self.n_stories
        dl: dict = {
            "Asset": {"ComponentAssignmentFile": "inventory.csv", "ComponentDatabase": DATABASE,
                      "NumberOfStories": n, "OccupancyType": "COM1"},
            "Demands": {"DemandFilePath": "demands.csv", "CollapseLimits": {"PID": self.drift_limit},
                        "DemandCloning": {f"PID-{k}-1": [f"PID-{k}-1", f"PID-{k}-2"] for k in range(1, n + 1)}},
            "Damage": {"DamageProcess": "FEMA P-58",
                       "IrreparableDamage": {"DriftCapacityMedian": self.irreparable_median,
                                             "DriftCapacityLogStd": self.irreparable_beta}},
            "Losses": {"Repair": {"ConsequenceDatabase": DATABASE, "MapApproach": "Automatic",
                                  "DecisionVariables": {"Cost": True, "Time": True, "Carbon": False, "Energy": False},
                                  "ReplacementCost": {"Unit": COST_UNIT, "Median": self.replacement_cost},
                                  "ReplacementTime": {"Unit": TIME_UNIT, "Median": self.replacement_time}}},
            "Options": {"Seed": self.seed, "Sampling": {"SampleSize": self.realizations},
                        "ListAllDamageStates": True, "Verbose": False, "PrintLog": False,
                        "LogFile": "pelicun_log.txt"},
            "Outputs": {"Demand": {}, "Asset": {}, "Damage": {},
                        "Loss": {"Repair": {"Sample": False, "Statistics": False, "GroupedSample": False,
                                            "GroupedStatistics": False, "AggregateSample": True,
                                            "AggregateStatistics": True}},
                        "Format": {"CSV": True, "JSON": False}},
        }
        if self.collapse_median_g is not None:
            # pelicun takes the capacity in the length unit's acceleration (m/s^2 here)
            dl["Damage"]["CollapseFragility"] = {"DemandType": self.im_type, "CapacityDistribution": "lognormal",
                                                 "CapacityMedian": self.collapse_median_g * G_M_S2,
                                                 "Theta_1": self.collapse_beta}
        return {"GeneralInformation": {"units": {"length": "m"}, "NumberOfStories": n}, "DL": dl}


def write_inputs(folder: str | os.PathLike, inputs: PelicunInputs) -> dict:
    """Write ``demands.csv``, ``inventory.csv`` and ``config.json`` into ``folder``; returns the config."""
    folder = Path(folder)
    cfg = inputs.config()
    atomic_write(folder / "demands.csv", lambda p: p.write_text(inputs.demands_csv))
    atomic_write(folder / "inventory.csv", lambda p: p.write_text(inputs.inventory_csv))
    atomic_write(folder / "config.json", lambda p: p.write_text(json.dumps(cfg, indent=2) + "\n"))
    return cfg


SAMPLE_COLUMNS = {"repair_cost": "repair_cost-", "repair_time_parallel": "repair_time-parallel",
                  "repair_time_sequential": "repair_time-sequential", "collapse": "collapse",
                  "irreparable": "irreparable"}
"""hlaid's names of pelicun's per-realization results (``DL_summary.csv`` columns)."""


def run_pelicun(folder: str | os.PathLike) -> dict[str, np.ndarray]:
    """Run the FEMA P-58 assessment on the inputs in ``folder`` (:func:`write_inputs`): the calls of
    pelicun's ``DL_calculation`` with the same arguments. Returns the per-realization results
    (``repair_cost`` [USD_2011], ``repair_time_parallel``/``_sequential`` [worker-days], ``collapse``
    and ``irreparable`` as 0/1), as pelicun's ``DL_summary.csv`` holds them; pelicun's log goes to
    ``folder/pelicun_log.txt``."""
    require_pelicun()
    with warnings.catch_warnings():  # pandas' deprecation notes from inside pelicun: not the user's concern
        warnings.simplefilter("ignore")
        return _run(Path(folder).resolve())


def _run(folder: Path) -> dict[str, np.ndarray]:
    import pandas as pd
    from pelicun.assessment import DLCalculationAssessment
    from pelicun.base import convert_to_SimpleIndex
    from pelicun.base import get as cget

    config = json.loads((folder / "config.json").read_text())
    dl = config["DL"]
    options = dict(dl["Options"], LogFile=str(folder / "pelicun_log.txt"))
    length = cget(config, "GeneralInformation/units/length")
    a = DLCalculationAssessment(config_options=options)
    a.calculate_demand(demand_path=folder / dl["Demands"]["DemandFilePath"],
                       collapse_limits=cget(dl, "Demands/CollapseLimits"), length_unit=length,
                       demand_calibration=None, sample_size=int(options["Sampling"]["SampleSize"]),
                       demand_cloning=cget(dl, "Demands/DemandCloning"), residual_drift_inference=None,
                       coupled_demands=False)
    a.calculate_asset(num_stories=int(dl["Asset"]["NumberOfStories"]),
                      component_assignment_file=str(folder / dl["Asset"]["ComponentAssignmentFile"]),
                      collapse_fragility_demand_type=cget(dl, "Damage/CollapseFragility/DemandType"),
                      component_sample_file=None,
                      add_irreparable_damage_columns=cget(dl, "Damage/IrreparableDamage", default=False))
    a.calculate_damage(length_unit=length, component_database=dl["Asset"]["ComponentDatabase"],
                       collapse_fragility=cget(dl, "Damage/CollapseFragility"),
                       irreparable_damage=cget(dl, "Damage/IrreparableDamage"),
                       damage_process_approach=cget(dl, "Damage/DamageProcess"), custom_model_dir=None,
                       scaling_specification=None)
    rep = dl["Losses"]["Repair"]
    dvs = tuple(k for k, v in rep["DecisionVariables"].items() if v)
    agg, _ = a.calculate_loss(loss_map_approach=rep["MapApproach"], occupancy_type=dl["Asset"]["OccupancyType"],
                              consequence_database=rep["ConsequenceDatabase"], custom_model_dir=None,
                              damage_process_approach=cget(dl, "Damage/DamageProcess"),
                              replacement_cost_parameters=rep["ReplacementCost"],
                              replacement_time_parameters=rep["ReplacementTime"],
                              decision_variables=dvs)
    dmg = a.damage.save_sample()
    assert isinstance(dmg, pd.DataFrame)
    dmg = convert_to_SimpleIndex(dmg.T.groupby(level=["cmp", "ds"]).sum().T, axis=1)
    agg = convert_to_SimpleIndex(agg, axis=1)
    out = {}
    for name, col in SAMPLE_COLUMNS.items():
        if name in ("collapse", "irreparable"):
            out[name] = dmg[f"{col}-1"].to_numpy(float) if f"{col}-1" in dmg.columns else np.zeros(len(dmg))
        else:
            out[name] = agg[col].to_numpy(float)
    return out


def summarise(sample: dict[str, np.ndarray], replacement_cost: float, replacement_time: float,
              ci: float = 0.90) -> dict:
    """Repair cost (median, ``ci`` band, their ratios to the replacement cost), repair time (median
    and band, parallel and sequential repairs), P(collapse), P(irreparable) and P(replacement)
    (either) over pelicun's realizations."""
    q = (0.5 - ci / 2, 0.5, 0.5 + ci / 2)
    cost = sample["repair_cost"]
    lo, med, hi = (float(v) for v in np.quantile(cost, q))
    out = {"n_realizations": int(cost.size), "ci": ci, "cost_unit": COST_UNIT, "time_unit": TIME_UNIT,
           "replacement_cost": replacement_cost, "replacement_time": replacement_time,
           "repair_cost_median": med, "repair_cost_band": [lo, hi], "repair_cost_mean": float(cost.mean()),
           "repair_cost_ratio_median": med / replacement_cost,
           "repair_cost_ratio_band": [lo / replacement_cost, hi / replacement_cost],
           "repair_cost_ratio_mean": float(cost.mean()) / replacement_cost}
    for k in ("parallel", "sequential"):
        t = sample[f"repair_time_{k}"]
        tl, tm, th = (float(v) for v in np.quantile(t, q))
        out[f"repair_time_{k}_median"], out[f"repair_time_{k}_band"] = tm, [tl, th]
    col, irr = sample["collapse"] > 0.5, sample["irreparable"] > 0.5
    out["p_collapse"] = float(col.mean())
    out["p_collapse_fragility_at_im"] = out["p_collapse"]  # the fragility at the demands' intensity, sampled
    out["p_irreparable"] = float((irr & ~col).mean())
    out["p_replacement"] = float((col | irr).mean())
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in out.items()}


__all__ = ["PelicunInputs", "write_inputs", "run_pelicun", "summarise", "require_pelicun", "library_file",
           "SAMPLE_COLUMNS", "UNITS", "DATABASE", "COST_UNIT", "TIME_UNIT"]
