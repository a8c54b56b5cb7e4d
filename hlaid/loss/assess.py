"""From a clone to losses: demands at the recorded event and at IDA stripes, each through pelicun.

:func:`assess_losses` is the one library entry: the clone (and its ensemble) under the building's
own record and under the IDA records scaled to each stripe level, pelicun's FEMA P-58 assessment of
every demand set (:mod:`hlaid.loss.fema_p58`), the loss curve against intensity and the repair
cost distribution at the recorded event (:func:`hlaid.run.loss_of_run` does it for a run folder);
:func:`loss_of_demand_file` assesses a demand file.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import _progress
from .._fileio import write_json
from ..errors import InputError
from .config import LossConfig
from .demands import Demands, clone_demands
from .fema_p58 import PelicunInputs, run_pelicun, summarise, write_inputs
from .inventory import default_inventory, get_inventory, read_inventory


@dataclass(frozen=True, eq=False)
class LossResult:
    """The FEMA P-58 assessment of one demand set.

    name : ``recorded`` or ``stripe-K`` (the folder its pelicun files are in)
    demands : the hlaid demands
    sample : pelicun's per-realization results (:func:`hlaid.loss.fema_p58.run_pelicun`)
    summary : :func:`hlaid.loss.fema_p58.summarise` of them, with the intensity and the demand counts
    """

    name: str
    demands: Demands
    sample: dict
    summary: dict


@dataclass(frozen=True, kw_only=True)
class Asset:
    """What the pelicun inputs need to know of the building: its inventory text, replacement values,
    floor areas (and where they came from) and the collapse fragility in its intensity."""

    inventory_csv: str
    inventory_source: str
    floor_area_m2: list
    area_source: str
    replacement_cost: float
    replacement_time: float
    collapse_median_g: float | None
    collapse_beta: float | None
    collapse_source: str


def describe_building(n: int, masses, cfg: LossConfig, collapse: tuple[float, float] | None, *,
                      collapse_source: str = "", base_dir: str | os.PathLike | None = None) -> Asset:
    """Inventory, floor areas, replacement values and collapse fragility of a building of ``n``
    stories with floor ``masses`` [t] (None: unknown) under ``cfg``."""
    area, area_src = cfg.floor_areas(n, masses)
    system = get_inventory(cfg.system)
    if cfg.inventory is not None:
        p = Path(cfg.inventory)
        if base_dir is not None and not p.is_absolute():
            p = Path(base_dir) / p
        inv, inv_src = read_inventory(p, n, area), str(p)
    else:
        inv, inv_src = default_inventory(system, area), f"default {system.name}: {system.description}"
    total = float(sum(area))
    cost = cfg.replacement_cost_usd or system.replacement_cost_usd_m2 * total
    time = cfg.replacement_time_worker_days or system.replacement_time_wd_m2 * total
    med, beta = collapse if collapse is not None else (None, None)
    asset = Asset(inventory_csv=inv, inventory_source=inv_src, floor_area_m2=area, area_source=area_src,
                  replacement_cost=float(cost), replacement_time=float(time), collapse_median_g=med,
                  collapse_beta=beta, collapse_source=collapse_source if collapse else "none")
    for line in assumption_lines(asset, cfg, given_inventory=cfg.inventory is not None):
        _progress.info(line)
    return asset


def assumption_lines(asset: Asset, cfg: LossConfig, *, given_inventory: bool) -> list[str]:
    """What the losses assume of the building that the user did not give (also in ``loss.json``):
    the floor areas, the component quantities, the replacement values."""
    area = asset.floor_area_m2
    same = len(set(round(a, 6) for a in area)) == 1
    shown = f"{area[0]:.4g} m2 per story" if same else "[" + ", ".join(f"{a:.4g}" for a in area) + "] m2"
    lines = [f"loss assumption: floor area {shown}, {asset.area_source}"]
    if not given_inventory:
        rows = list(csv.reader(io.StringIO(asset.inventory_csv)))[1:]
        qty = [float(r[4]) for r in rows if len(r) > 4 and r[1] == "ea"]
        frac = sum(1 for q in qty if abs(q - round(q)) > 1e-9)
        lines.append(f"loss assumption: components of the {asset.inventory_source.split(':')[0]} inventory, "
                     "quantities = typical density per m2 x floor area"
                     + (f" ({frac} of {len(qty)} counted quantities fractional, e.g. {min(q for q in qty if q):.3g} "
                        "of a unit: expected values, not whole pieces); yours instead: LossConfig(inventory=CSV), "
                        "loss.inventory, hlaid loss --inventory CSV" if frac else ""))
    lines.append(f"loss assumption: replacement cost {asset.replacement_cost:,.0f} USD_2011 and time "
                 f"{asset.replacement_time:,.0f} worker-days"
                 + ("" if cfg.replacement_cost_usd and cfg.replacement_time_worker_days else
                    " (the system's typical values per m2 x total floor area)"))
    return lines


def assess_demands(demands: Demands, asset: Asset, cfg: LossConfig, folder: str | os.PathLike,
                   name: str) -> LossResult:
    """Write the pelicun inputs of ``demands`` into ``folder`` and run the assessment there."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    inputs = PelicunInputs(demands_csv=demands.csv_text(), inventory_csv=asset.inventory_csv,
                           n_stories=demands.n_stories, im_type=demands.sa_name(),
                           collapse_median_g=asset.collapse_median_g, collapse_beta=asset.collapse_beta,
                           drift_limit=demands.drift_limit, replacement_cost=asset.replacement_cost,
                           replacement_time=asset.replacement_time, irreparable_median=cfg.irreparable_median,
                           irreparable_beta=cfg.irreparable_beta, realizations=cfg.realizations, seed=cfg.seed)
    write_inputs(folder, inputs)
    notes = []
    if demands.collapsed.all():  # pelicun needs at least one non-collapse realization
        r = cfg.realizations
        sample = {"repair_cost": np.full(r, asset.replacement_cost),
                  "repair_time_parallel": np.full(r, asset.replacement_time),
                  "repair_time_sequential": np.full(r, asset.replacement_time),
                  "collapse": np.ones(r), "irreparable": np.zeros(r)}
        notes.append("every realization collapsed in the replay: pelicun not run, the loss is the replacement")
    else:
        sample = run_pelicun(folder)
    s = summarise(sample, asset.replacement_cost, asset.replacement_time)
    if asset.collapse_median_g is None:  # no fragility given: collapse not assessed (pelicun counted none)
        s.update(p_collapse=None, p_collapse_fragility_at_im=None, p_replacement=None)
        notes.append("collapse not assessed: no collapse fragility; the losses are those of the realisations that did "
                     "not collapse")
    s.update(name=name, level_g=demands.level, im=float(np.median(demands.im)), im_label=demands.im_label,
             n_demand_realizations=demands.n_realizations, n_collapsed_in_replay=int(demands.collapsed.sum()),
             notes=notes)
    return LossResult(name=name, demands=demands, sample=sample, summary=s)


def assess_losses(clone, own_motion, *, records=None, levels=(), collapse: tuple[float, float] | None,
                  cfg: LossConfig | None = None, ida_config=None, n_ensemble: int = 0, seed: int = 0,
                  folder: str | os.PathLike, collapse_source: str = "",
                  base_dir: str | os.PathLike | None = None, plots: bool = True, events=None,
                  heights_assumed: bool | None = None) -> dict:
    """Losses at the recorded event and at the IDA stripes; writes everything under ``folder``.

    Parameters
    ----------
    clone : the :class:`~hlaid.clone.Clone`
    own_motion : the ground motion the building recorded (GroundMotion), or None
    records, levels : IDA records and the stripe levels [g] of the loss curve (none: no curve)
    collapse : ``(median [g], beta)`` of the clone's collapse fragility in the IDA's intensity
    cfg : :class:`LossConfig` (None: defaults)
    ida_config : the IDA settings the demands are run with (:func:`hlaid.loss.clone_demands`)
    n_ensemble, seed : the ensemble of clones (0: the identified clone alone)
    folder : output folder (``recorded/``, ``stripe-K/`` with pelicun's inputs, ``loss.json``,
        ``loss_curve.csv``, ``loss_curve.png``, ``repair_cost.png``; ``plots`` False: no PNG)
    events : P(collapse) at the clone's events as its run reported them (mappings of
        :class:`hlaid.ida.basis.AtEvent`'s fields), so the losses show the same figures; None: the
        lognormal ``collapse`` at each event's intensity
    heights_assumed : the story heights were given, not measured (None: where ``ida_config``
        gives them)

    Returns
    -------
    dict : the ``loss`` block of a run summary (also ``loss.json``), with ``basis``: what the losses
    rest on (:class:`hlaid.ida.basis.DecisionBasis`)
    """
    cfg = cfg or LossConfig()
    folder = Path(folder)
    masses = None if clone.mass_normalised else list(clone.building.mass)
    b = describe_building(clone.building.n_stories, masses, cfg, collapse, collapse_source=collapse_source,
                          base_dir=base_dir)
    results = []
    if own_motion is not None:
        _progress.info("loss at the recorded event: demands of the clone(s) under the record, then pelicun")
        d = clone_demands(clone, own_motion, n_ensemble=n_ensemble, seed=seed, ida_config=ida_config)
        results.append(assess_demands(d, b, cfg, folder / "recorded", "recorded"))
    levels = list(levels or ())
    if levels and records is None:
        raise InputError("the loss curve needs the IDA records (records=[...], or the run's ida.records)")
    for k, lv in enumerate(_progress.progress(levels, desc="loss stripes", unit="levels")):
        d = clone_demands(clone, records, level=lv, n_ensemble=n_ensemble, seed=seed, ida_config=ida_config,
                          event_motions=[own_motion] if own_motion is not None else ())
        results.append(assess_demands(d, b, cfg, folder / f"stripe-{k + 1}", f"stripe-{k + 1}"))
    if not results:
        raise InputError("nothing to assess: give the recorded ground motion or stripe levels")
    own = next((r for r in results if r.name == "recorded"), None)
    stripes = [r for r in results if r.name != "recorded"]
    out = {"format": "hlaid-loss", "version": 1, "engine": _engine(), "system": cfg.system,
           "inventory": b.inventory_source, "floor_area_m2": b.floor_area_m2, "floor_area_source": b.area_source,
           "replacement_cost": b.replacement_cost, "replacement_time": b.replacement_time,
           "collapse_fragility": {"median_g": b.collapse_median_g, "beta": b.collapse_beta,
                                  "source": b.collapse_source},
           "irreparable": {"median": cfg.irreparable_median, "beta": cfg.irreparable_beta},
           "n_ensemble": n_ensemble, "realizations": cfg.realizations, "seed": cfg.seed,
           "recorded": None if own is None else own.summary, "stripes": [r.summary for r in stripes],
           "demands": {r.name: r.demands.summary() for r in results}, "assumptions": ASSUMPTIONS}
    out["basis"] = loss_basis(clone, own, collapse, ida_config, events, heights_assumed, own_motion,
                              collapse_source).to_dict()
    write_json(folder / "loss.json", out)
    if stripes:
        from .._fileio import atomic_write

        text = _curve_csv(stripes)
        atomic_write(folder / "loss_curve.csv", lambda p: p.write_text(text))
    if not plots:
        return out
    from ..plots import save_figure
    from .plots import plot_loss_curve, plot_repair_cost

    if stripes:
        save_figure(plot_loss_curve(stripes, own), folder / "loss_curve.png")
    if own is not None:
        save_figure(plot_repair_cost(own, b.replacement_cost), folder / "repair_cost.png")
    return out


def loss_basis(clone, own: LossResult | None, collapse, ida_config, events, heights_assumed, own_motion,
               source: str = ""):
    """What the losses rest on (:func:`hlaid.ida.basis.decision_basis`): P(collapse) at the clone's
    events (``events`` as its run reported them, else the lognormal ``collapse`` at each event's
    intensity), the recorded event's median peak drift ratio against the drift survived, the
    heights and the clone's replay error."""
    from ..events.evidence import event_motions
    from ..ida.basis import decision_basis, events_at
    from ..ida.config import IDAConfig
    from ..ida.measures import intensity
    from .demands import median_peak_ratio

    cfg = ida_config or IDAConfig()
    if events is None:
        median, beta = collapse if collapse is not None else (None, None)
        em = event_motions(clone, [own_motion] if own_motion is not None else [])
        period = own.demands.period if own is not None else cfg.period
        events = events_at(list(zip(em.names, em.motions)),
                           lambda m: intensity(m, cfg.im, building=clone.building, period=period)[0], median, beta,
                           f"the losses' collapse fragility ({source})" if source else "the losses' collapse fragility")
    d = own.demands if own is not None else None
    ratio = None if d is None else median_peak_ratio(d.pid[~d.collapsed])
    assumed = cfg.heights_mm is not None if heights_assumed is None else heights_assumed
    return decision_basis(clone, events=events, heights=cfg.heights_mm, heights_assumed=assumed,
                          demand_ratio=ratio, drift_limit=cfg.drift_limit)


ASSUMPTIONS = (
    "demands from the clone's own replay (residual drift from a free-vibration tail), one realization per ensemble "
    "member and record, resampled by pelicun (empirical)",
    "the clone is planar: peak drifts are taken for both horizontal directions (pelicun DemandCloning), floor "
    "accelerations and residual drifts in the identified direction",
    "collapse from hlaid's lognormal collapse fragility at each realization's intensity; realizations that reached "
    "the drift limit in the replay are removed from the non-collapse demands (pelicun CollapseLimits)",
    "irreparable damage from FEMA P-58's residual drift fragility, evaluated by pelicun per story; collapse and "
    "irreparable damage cost the replacement",
    "FEMA P-58 2nd edition fragilities and repair consequences (USD 2011, worker-days) as shipped with pelicun")


def _engine() -> str:
    from importlib.metadata import PackageNotFoundError, version

    def v(name):
        try:
            return version(name)
        except PackageNotFoundError:
            return "?"
    return f"pelicun {v('pelicun')}, simcenter-dlml {v('simcenter-dlml')}"


def _curve_csv(stripes: list[LossResult]) -> str:
    head = ["level_g", "repair_cost_ratio_mean", "repair_cost_ratio_median", "repair_cost_ratio_lo",
            "repair_cost_ratio_hi", "repair_time_parallel_median", "p_collapse", "p_irreparable",
            "n_collapsed_in_replay", "n_demand_realizations"]
    rows = [",".join(head)]
    for r in stripes:
        s = r.summary
        vals = [s["level_g"], s["repair_cost_ratio_mean"], s["repair_cost_ratio_median"], *s["repair_cost_ratio_band"],
                s["repair_time_parallel_median"], s["p_collapse"], s["p_irreparable"], s["n_collapsed_in_replay"],
                s["n_demand_realizations"]]
        rows.append(",".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in vals))
    return "\n".join(rows) + "\n"


def loss_of_demand_file(path: str | os.PathLike, cfg: LossConfig, out: str | os.PathLike, *,
                        collapse: tuple[float, float] | None = None, drift_limit: float = 0.10,
                        force: bool = False, base_dir: str | os.PathLike | None = None) -> dict:
    """``hlaid loss DEMANDS.csv -o OUT``: pelicun's FEMA P-58 assessment of a demand file (e.g. one
    written by ``hlaid demands``) with ``cfg``'s inventory (``floor_area_m2`` required: the file
    has no masses) and an optional collapse fragility in the file's intensity column (without one,
    P(collapse) and P(replacement) are None: not assessed). Writes pelicun's inputs and
    ``loss.json`` into ``out``; returns the summary."""
    from .._fileio import atomic_directory
    from .demands import read_demand_csv

    df = read_demand_csv(path)
    if collapse is not None and df.im_type is None:
        raise InputError("a collapse fragility needs an intensity column (1-SA_T-0-1 or PGA) in the demand file",
                         source=str(path))
    asset = describe_building(df.n_stories, None, cfg, collapse, collapse_source="given" if collapse else "",
                              base_dir=base_dir)
    with atomic_directory(out, force=force, inputs=[path, cfg.inventory]) as tmp:
        inputs = PelicunInputs(demands_csv=df.text, inventory_csv=asset.inventory_csv, n_stories=df.n_stories,
                               im_type=df.im_type or "PGA", collapse_median_g=asset.collapse_median_g,
                               collapse_beta=asset.collapse_beta, drift_limit=drift_limit,
                               replacement_cost=asset.replacement_cost, replacement_time=asset.replacement_time,
                               irreparable_median=cfg.irreparable_median, irreparable_beta=cfg.irreparable_beta,
                               realizations=cfg.realizations, seed=cfg.seed)
        write_inputs(tmp, inputs)
        s = summarise(run_pelicun(tmp), asset.replacement_cost, asset.replacement_time)
        if collapse is None:  # pelicun counted no collapse because none was asked for: not assessed, not 0
            s.update(p_collapse=None, p_collapse_fragility_at_im=None, p_replacement=None)
            s["notes"] = ["collapse not assessed: no collapse fragility given (--collapse-median, --collapse-beta); "
                          "the repair costs and times are those of the realisations that did not collapse"]
        s.update(demand_file=str(path), inventory=asset.inventory_source, n_demand_realizations=df.n_realizations,
                 collapse_fragility={"median_g": asset.collapse_median_g, "beta": asset.collapse_beta},
                 engine=_engine(), assumptions=ASSUMPTIONS)
        write_json(tmp / "loss.json", s)
    return s


__all__ = ["loss_of_demand_file", "LossResult", "Asset", "assess_demands", "assess_losses", "describe_building",
           "ASSUMPTIONS"]
