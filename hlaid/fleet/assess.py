"""The one seam between the fleet and the risk assessment of a clone.

:func:`assess_clone` calls ``hlaid.uncertainty.assess`` (an ensemble of clones, IDA over the
ensemble, the collapse fragility with its band, the probabilities at the building's own
intensity and the re-occupancy indicator). Only when that module is not installed does it
fall back to :func:`point_assess`: an IDA of the identified (point) clone alone, labelled
``ensemble: 0`` in every result, whose band is the bootstrap interval over records (record-to-
record variability only, no identification uncertainty).

The contract of an assess function (``hlaid.uncertainty.assess`` and the fakes of the tests)::

    assess(clone, records, *, n_ensemble=20, ida_config=None, own_motion=None, seed=0) -> Assessment

where ``Assessment.to_dict()`` (or a plain dict) is JSON-able. Its scalar entries become
columns of the fleet table (nested mappings flattened to ``a.b``).
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..clone import Clone
from ..ida import IDAConfig, ida, intensity
from ..motions import GroundMotion

FALLBACK = "point clone (hlaid.uncertainty missing)"
"""The ``engine`` entry of a result computed by :func:`point_assess`."""

ENGINE = "hlaid.uncertainty"


def default_assess() -> tuple[Callable, str]:
    """``(assess function, engine name)``: ``hlaid.uncertainty.assess`` when the module exists,
    else :func:`point_assess`. An error inside an existing module is not hidden."""
    if importlib.util.find_spec("hlaid.uncertainty") is None:
        return point_assess, FALLBACK
    from ..uncertainty import assess  # type: ignore[import-not-found]
    return assess, ENGINE


def assess_clone(clone: Clone, records: Sequence[GroundMotion], *, n_ensemble: int, ida_config: IDAConfig,
                 own_motion: GroundMotion | None, seed: int, assess: Callable | None = None) -> dict:
    """Assess one clone; returns the assessment as a JSON-able dict with ``engine`` and ``ensemble``.

    Parameters
    ----------
    clone : the identified clone
    records : IDA records
    n_ensemble : clones in the ensemble (the fallback always has 0)
    ida_config : IDA settings (its ``records`` are ignored: ``records`` is used)
    own_motion : the ground motion the building recorded (its Sa(T1) is the own intensity)
    assess : an assess function with the contract above; None: :func:`default_assess`
    """
    if assess is None:
        assess, engine = default_assess()
    else:
        engine = getattr(assess, "engine", None) or f"{assess.__module__}.{assess.__qualname__}"
    res = assess(clone, list(records), n_ensemble=n_ensemble, ida_config=ida_config, own_motion=own_motion,
                 seed=seed)
    d = dict(res.to_dict() if hasattr(res, "to_dict") else res)
    if assess is point_assess:
        engine = FALLBACK
    d.setdefault("engine", engine)
    d.setdefault("ensemble", 0 if engine == FALLBACK else n_ensemble)
    return d


# ---------------------------------------------------------------------------- fallback
@dataclass(frozen=True, kw_only=True)
class PointAssessment:
    """Risk of a point clone (no ensemble): see :func:`point_assess`.

    Attributes
    ----------
    median_collapse_g : median collapse intensity [g] (lognormal MLE over the records)
    collapse_band_g : bootstrap interval (level ``ci``) of that median over records
    beta : lognormal dispersion (record-to-record)
    own_im_g : the building's own record's intensity [g] (None without the record)
    p_collapse : P(collapse | own intensity)
    p_drift : P(peak drift ratio > limit | own intensity), by limit (``"0.01"``: 1 %)
    reoccupancy : ``"re-occupy"``, ``"restricted"`` or ``"unsafe"`` (rule: :data:`FALLBACK_RULE`)
    """

    median_collapse_g: float | None
    collapse_band_g: tuple[float, float] | None
    beta: float | None
    im: str
    period_s: float | None
    own_im_g: float | None
    p_collapse: float | None
    p_drift: dict = field(default_factory=dict)
    reoccupancy: str = "unknown"
    n_records: int = 0
    notes: tuple = ()

    def to_dict(self) -> dict:
        return {"ensemble": 0, "engine": FALLBACK, "median_collapse_g": self.median_collapse_g,
                "collapse_band_g": list(self.collapse_band_g) if self.collapse_band_g else None,
                "beta": self.beta, "im": self.im, "period_s": self.period_s, "own_im_g": self.own_im_g,
                "p_collapse": self.p_collapse, "p_drift": dict(self.p_drift), "reoccupancy": self.reoccupancy,
                "decision_rule": FALLBACK_RULE, "n_records": self.n_records, "notes": list(self.notes)}


FALLBACK_RULE = ("unsafe if P(collapse) >= 0.10 at the own intensity; restricted if P(drift > 2 %) >= 0.50; "
                 "else re-occupy (point clone, record-to-record variability only)")


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def point_assess(clone, records, *, n_ensemble: int = 0, ida_config: IDAConfig | None = None,
                 own_motion: GroundMotion | None = None, seed: int = 0) -> PointAssessment:
    """IDA of the point clone alone (``n_ensemble`` is ignored): the fallback of :func:`assess_clone`."""
    cfg = ida_config or IDAConfig()
    res = ida(clone, records, **cfg.ida_kwargs())
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
    p_drift = {}
    if own is not None:
        for d in res.exceedance_limits:
            try:
                p = res.limit_fragility(d, n_boot=0, seed=seed).probability(own)
            except ValueError:  # too few exceedances to fit: the fraction of records
                p = res.exceedance([d], [own])[0, 0]
            p_drift[f"{d:g}"] = _num(p)
    decision = "unknown"
    if p_col is not None:
        p2 = p_drift.get("0.02")
        decision = ("unsafe" if p_col >= 0.10 else "restricted" if p2 is not None and p2 >= 0.5 else "re-occupy")
    return PointAssessment(
        median_collapse_g=None if frag is None else _num(frag.median),
        collapse_band_g=None if frag is None or frag.median_ci is None else tuple(float(v) for v in frag.median_ci),
        beta=None if frag is None else _num(frag.beta), im=res.im, period_s=_num(res.period), own_im_g=own,
        p_collapse=p_col, p_drift=p_drift, reoccupancy=decision, n_records=res.n_records, notes=tuple(notes))


def flatten(d: dict, prefix: str = "") -> dict:
    """Scalar entries of a nested mapping as ``{"a.b": value}``; a pair of numbers ``[lo, hi]``
    becomes ``a_lo``/``a_hi``; other lists are left out (they stay in the result JSON)."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        elif isinstance(v, (list, tuple)):
            if len(v) == 2 and all(isinstance(x, (int, float)) or x is None for x in v):
                out[f"{key}_lo"], out[f"{key}_hi"] = v
        elif isinstance(v, (np.floating, np.integer, np.bool_)):
            out[key] = v.item()
        elif v is None or isinstance(v, (str, int, float, bool)):
            out[key] = v
    return out


__all__ = ["assess_clone", "default_assess", "point_assess", "PointAssessment", "flatten", "FALLBACK", "ENGINE"]
