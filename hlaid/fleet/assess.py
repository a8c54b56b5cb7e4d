"""The one seam between the fleet and the risk assessment of a clone.

:func:`assess_clone` calls ``hlaid.ida.assess`` (an ensemble of clones, IDA over the
ensemble, the collapse fragility with its band, the probabilities at the building's own
intensity and the re-occupancy indicator). With ``n_ensemble: 0`` the fleet uses
:func:`point_assess` instead: an IDA of the identified (point) clone alone, labelled
``ensemble: 0`` in every result, whose band is the bootstrap interval over records (record-to-
record variability only, no identification uncertainty).

The contract of an assess function (``hlaid.ida.assess`` and the fakes of the tests)::

    assess(clone, records, *, n_ensemble=20, ida_config=None, own_motion=None, seed=0) -> Assessment

where ``Assessment.to_dict()`` (or a plain dict) is JSON-able. Its scalar entries become
columns of the fleet table (nested mappings flattened to ``a.b``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..clone import Clone
from ..ida import IDAConfig, intensity, run_ida
from ..motions import GroundMotion
from ..uncertainty.config import PLACARDS

POINT = "point clone (n_ensemble: 0)"
"""The ``engine`` entry of a result computed by :func:`point_assess` on request (``n_ensemble: 0``)."""

ENGINE = "hlaid.ida"


def default_assess() -> tuple[Callable, str]:
    """``(assess function, engine name)``: ``hlaid.ida.assess`` (imported when needed)."""
    from ..ida import assess
    return assess, ENGINE


def assess_clone(clone: Clone, records: Sequence[GroundMotion], *, n_ensemble: int, ida_config: IDAConfig,
                 own_motion: GroundMotion | None, seed: int, assess: Callable | None = None,
                 engine: str | None = None) -> dict:
    """Assess one clone; returns the assessment as a JSON-able dict with ``engine`` and ``ensemble``.

    Parameters
    ----------
    clone : the identified clone
    records : IDA records
    n_ensemble : clones in the ensemble (the point-clone fallback has 0)
    ida_config : IDA settings (its ``records`` are ignored: ``records`` is used)
    own_motion : the ground motion the building recorded (its Sa(T1) is the own intensity)
    seed : seed of the ensemble and the bootstraps
    assess : an assess function with the contract above; None: :func:`default_assess`
    engine : the label of ``assess`` in the results (default: its name)
    """
    if assess is None:
        assess, label = default_assess()
    else:
        label = engine_label(assess)
    res = assess(clone, list(records), n_ensemble=n_ensemble, ida_config=ida_config, own_motion=own_motion,
                 seed=seed)
    d = dict(res.to_dict() if hasattr(res, "to_dict") else res)
    d["engine"] = engine or label
    d["ensemble"] = 0 if assess is point_assess else int(d.get("n_ensemble", n_ensemble))
    d["basis"] = basis_of(clone, d, ida_config)
    d["basis_flags"] = " | ".join(d["basis"]["flags"])
    return d


def basis_of(clone: Clone, d: dict, ida_config: IDAConfig) -> dict:
    """What a unit's assessment ``d`` rests on (:func:`hlaid.ida.basis.decision_basis`): P(collapse)
    at the clone's events (the assessment's ``events``), the members' median peak drift ratio
    under the own record against the drift survived, the heights and the clone's replay error."""
    from ..ida.basis import decision_basis

    own = d.get("own_peak_drift")
    ratio = None
    if isinstance(own, (list, tuple, np.ndarray)) and len(own):
        ratio = float(np.median(np.asarray(own, dtype=float)))
    events = [e for e in d.get("events") or () if isinstance(e, dict) and "name" in e]
    return decision_basis(clone, events=events, heights=ida_config.heights_mm,
                          heights_assumed=ida_config.heights_mm is not None, demand_ratio=ratio,
                          drift_limit=ida_config.drift_limit,
                          events_note="the assessment reports none (the clone's events' ground motions not at "
                                      "hand)").to_dict()


def engine_label(assess: Callable) -> str:
    """How the results name an assess function: its ``engine`` attribute, :data:`POINT` for
    :func:`point_assess`, else its qualified name."""
    if assess is point_assess:
        return POINT
    return getattr(assess, "engine", None) or f"{assess.__module__}.{assess.__qualname__}"


# ---------------------------------------------------------------------------- point clone
FALLBACK_RULE = ("point clone (record-to-record variability only): red if P(collapse) >= 0.10 at the own "
                 "intensity, yellow if >= 0.02, else green")


@dataclass(frozen=True, kw_only=True)
class PointAssessment:
    """Risk of a point clone (no ensemble), the fallback of :func:`assess_clone`. Field names
    are those of ``hlaid.ida.assessment.Assessment`` so the fleet table has one layout.

    Attributes
    ----------
    collapse_median : median collapse intensity [g] (lognormal MLE over the records)
    collapse_median_band : bootstrap interval (level ``ci``) of that median over records [g]
    beta : lognormal dispersion (record-to-record)
    own_im : the building's own record's intensity [g] (None without the record)
    p_collapse : P(collapse | own intensity) from the fitted fragility
    drift_limits, p_exceed : P(peak drift ratio > limit | own intensity), per limit
    indicator : ``"green"``, ``"yellow"``, ``"red"`` (rule: :data:`FALLBACK_RULE`)
    """

    n_records: int
    ci: float
    im: str
    period: float | None
    collapse_median: float | None
    collapse_median_band: tuple[float, float] | None
    beta: float | None
    own_im: float | None = None
    p_collapse: float | None = None
    drift_limits: tuple = ()
    p_exceed: tuple = ()
    indicator: str | None = None
    notes: tuple = ()
    events: tuple = ()
    """P(collapse) at each of the clone's events (:meth:`hlaid.ida.basis.AtEvent.to_dict`)."""

    def to_dict(self) -> dict:
        return {"n_ensemble": 0, "n_records": self.n_records, "ci": self.ci, "im": self.im,
                "period": self.period, "collapse_median": self.collapse_median,
                "collapse_median_band": list(self.collapse_median_band) if self.collapse_median_band else None,
                "beta": self.beta, "own_im": self.own_im, "p_collapse": self.p_collapse,
                "drift_limits": list(self.drift_limits), "p_exceed": list(self.p_exceed),
                "indicator": self.indicator,
                "placard": None if self.indicator is None else PLACARDS.get(self.indicator), "rule": FALLBACK_RULE,
                "notes": list(self.notes), "events": list(self.events)}


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def point_assess(clone, records, *, n_ensemble: int = 0, ida_config: IDAConfig | None = None,
                 own_motion: GroundMotion | None = None, seed: int = 0) -> PointAssessment:
    """IDA of the point clone alone (``n_ensemble`` is ignored): the fallback of :func:`assess_clone`."""
    cfg = ida_config or IDAConfig()
    res = run_ida(clone, records, cfg)
    notes = list(res.notes)
    try:
        frag = res.collapse_fragility("capacities", n_boot=cfg.bootstrap, ci=cfg.ci, seed=seed)
    except ValueError as err:
        frag = None
        notes.append(f"collapse fragility not fitted: {err}")
    own = None
    if own_motion is not None:
        own = float(intensity(own_motion, res.im, building=res.building, period=cfg.period)[0])
    p_col = None if frag is None or own is None else _num(frag.probability(own))
    p_exc = []
    if own is not None:
        for d in res.exceedance_limits:
            try:
                p = res.limit_fragility(d, n_boot=0, seed=seed).probability(own)
            except ValueError:  # too few exceedances to fit: the fraction of records
                p = res.exceedance([d], [own])[0, 0]
            p_exc.append(_num(p))
        # exceeding a larger drift implies exceeding a smaller one; fragilities fitted one limit at a
        # time can cross in their tails (a coarse grid), so each is at least those of larger drifts
        for j in range(len(p_exc) - 2, -1, -1):
            here, above = p_exc[j], p_exc[j + 1]
            if here is not None and above is not None:
                p_exc[j] = max(here, above)
    indicator = None if p_col is None else "red" if p_col >= 0.10 else "yellow" if p_col >= 0.02 else "green"
    from ..ida.basis import ida_events

    events = () if not isinstance(clone, Clone) or not clone.events else tuple(
        e.to_dict() for e in ida_events(clone, res, None if own_motion is None else _with_own(clone, own_motion)))
    return PointAssessment(
        n_records=res.n_records, ci=cfg.ci, im=res.im, period=_num(res.period),
        collapse_median=None if frag is None else _num(frag.median),
        collapse_median_band=(None if frag is None or frag.median_ci is None
                              else cast("tuple[float, float]", tuple(float(v) for v in frag.median_ci))),
        beta=None if frag is None else _num(frag.beta), own_im=own, p_collapse=p_col,
        drift_limits=tuple(res.exceedance_limits) if own is not None else (), p_exceed=tuple(p_exc),
        indicator=indicator, notes=tuple(notes), events=events)


def _with_own(clone: Clone, own_motion: GroundMotion) -> list:
    """``(name, motion)`` of the clone's events, ``own_motion`` where it is one of them."""
    from ..events.evidence import event_motions

    em = event_motions(clone, [own_motion])
    return list(zip(em.names, em.motions))


def flatten(d: dict, prefix: str = "") -> dict:
    """Scalar entries of a nested mapping as ``{"a.b": value}``: a band ``[lo, hi]`` (a key
    ending in ``band``) becomes ``KEY_lo``/``KEY_hi``; ``p_exceed`` (and ``p_exceed_band``) per
    ``drift_limits`` becomes ``p_exceed_0.01`` (``p_exceed_0.01_band_lo`` ...); other lists are left out (they stay in
    the result JSON)."""
    out = {}
    limits = d.get("drift_limits")
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        elif isinstance(v, (list, tuple)):
            if k in ("p_exceed", "p_exceed_band") and isinstance(limits, (list, tuple)) and len(limits) == len(v):
                for lim, x in zip(limits, v):
                    out.update(flatten({f"p_exceed_{lim:g}" + k.removeprefix("p_exceed"): x}, prefix))
            elif k.endswith("band") and len(v) == 2 and all(isinstance(x, (int, float)) or x is None for x in v):
                out[f"{key}_lo"], out[f"{key}_hi"] = v
        elif isinstance(v, (np.floating, np.integer, np.bool_)):
            out[key] = v.item()
        elif v is None or isinstance(v, (str, int, float, bool)):
            out[key] = v
    return out


__all__ = ["assess_clone", "default_assess", "engine_label", "POINT", "point_assess", "PointAssessment", "flatten",
           "ENGINE",
           "FALLBACK_RULE"]
