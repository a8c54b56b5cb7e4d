"""The result of an IDA: every run, each record's collapse intensity, and their summaries.

Summaries follow Vamvatsikos & Cornell (2002): each record's IDA curve is the piecewise-
linear curve through its points (from the origin) up to its collapse intensity, beyond
which its EDP is infinite; fractiles of the EDP and probabilities of exceedance are taken
across records at common IM values ("stripes"). Written atomically as a folder:
``points.csv`` (every run), ``summary.json``, ``ida.npz`` and PNG figures.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._fileio import atomic_directory, write_json, write_npz
from ..model import Building
from ..units import UNITS_JSON
from .fragility import (
    FRACTILES,
    LognormalFragility,
    fragility_from_capacities,
    fragility_from_exceedance,
)

FORMAT, VERSION = "hlaid-ida", 1


@dataclass(frozen=True, eq=False)
class IDAResult:
    """Incremental dynamic analysis of one building over a record set.

    IM values are in g; drifts in mm, drift ratios dimensionless. ``R`` records, ``N`` runs
    (points), ``n`` stories.

    Attributes
    ----------
    building : the building analysed (P-Delta resolved)
    im, im_label : intensity measure name and label; period : its period [s] (nan for PGA)
    record_names, record_sources : (R,) ; record_im : (R,) IM of the unscaled records [g];
    record_dt : (R,) [s]
    levels : (level,) the grid of IM levels [g]
    drift_limit, slope_ratio : collapse criteria; exceedance_limits : drift ratios summarised
    elastic_slope : (R,) IM per unit drift ratio of the linear response
    point_record, point_im, point_scale, point_stage, point_status, point_substeps : (N,) the
        record, IM, scale factor, stage (probe/grid/hunt/fill), simulator status (0 ok,
        1 drift limit, 2 diverged) and RK4 sub-steps of every run
    peak_drift, residual_drift : (N, n) [mm]
    collapse_im : (R,) collapse intensity [g] (midpoint of the bracket), NaN if censored
    collapse_lo, collapse_hi : (R,) bracket [last survived, first collapsed] [g]
    collapse_mode : (R,) "drift limit", "slope", "diverged" or "none"
    censored_im : (R,) highest IM run for records that never collapsed [g], else NaN
    settings, notes, timing : what was run and decided, and how long it took
    """

    building: Building
    im: str
    im_label: str
    period: float
    record_names: tuple
    record_sources: tuple
    record_im: np.ndarray
    record_dt: np.ndarray
    levels: np.ndarray
    drift_limit: float
    slope_ratio: float
    exceedance_limits: tuple
    elastic_slope: np.ndarray
    point_record: np.ndarray
    point_im: np.ndarray
    point_scale: np.ndarray
    point_stage: np.ndarray
    point_status: np.ndarray
    point_substeps: np.ndarray
    peak_drift: np.ndarray
    residual_drift: np.ndarray
    collapse_im: np.ndarray
    collapse_lo: np.ndarray
    collapse_hi: np.ndarray
    collapse_mode: tuple
    censored_im: np.ndarray
    settings: dict = field(default_factory=dict)
    notes: tuple = ()
    timing: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ per point
    @property
    def n_records(self) -> int:
        return len(self.record_names)

    @property
    def drift_ratio(self) -> np.ndarray:
        """(N, n) peak drift ratio of every run and story."""
        return self.peak_drift / np.asarray(self.building.height)

    @property
    def edp(self) -> np.ndarray:
        """(N,) peak inter-story drift ratio (largest story) of every run."""
        return self.drift_ratio.max(axis=1)

    @property
    def residual_ratio(self) -> np.ndarray:
        """(N, n) residual drift ratio (NaN for runs stopped at the drift limit or diverged)."""
        r = self.residual_drift / np.asarray(self.building.height)
        return np.where((self.point_status == 0)[:, None], r, np.nan)

    @property
    def collapsed(self) -> np.ndarray:
        """(N,) True for runs at or above their record's collapse intensity."""
        lim = np.where(np.isfinite(self.collapse_hi), self.collapse_hi, np.inf)
        return self.point_im >= lim[self.point_record]

    # ------------------------------------------------------------------ curves
    def curve(self, r: int) -> tuple[np.ndarray, np.ndarray]:
        """Record ``r``'s IDA curve below collapse: ``(im, edp)`` sorted by IM, from the origin."""
        sel = (self.point_record == r) & ~self.collapsed
        im, edp = self.point_im[sel], self.edp[sel]
        o = np.argsort(im, kind="stable")
        return np.concatenate([[0.0], im[o]]), np.concatenate([[0.0], edp[o]])

    def edp_at(self, im_values) -> np.ndarray:
        """(R, M) EDP of every record at IM values: interpolated on its curve, inf at or above
        its collapse intensity, NaN above the highest IM run for a record that never collapsed."""
        x = np.atleast_1d(np.asarray(im_values, dtype=np.float64))
        out = np.empty((self.n_records, x.size))
        for r in range(self.n_records):
            ci, ce = self.curve(r)
            out[r] = np.interp(x, ci, ce)
            if np.isfinite(self.collapse_im[r]):
                out[r, x >= self.collapse_im[r]] = np.inf
            else:
                out[r, x > ci[-1]] = np.nan
        return out

    def fractiles(self, im_values=None, q=FRACTILES) -> np.ndarray:
        """(len(q), M) EDP fractiles (percent ``q``) across records at IM values (default:
        the grid levels); inf where more than ``100 - q`` % of the records collapsed."""
        x = self.levels if im_values is None else np.asarray(im_values, dtype=np.float64)
        e = self.edp_at(x)
        out = np.full((len(q), x.size), np.nan)
        for j in range(x.size):
            v = np.sort(e[~np.isnan(e[:, j]), j])
            if v.size:
                out[:, j] = [_percentile_inf(v, qq) for qq in q]
        return out

    def exceedance(self, limits=None, im_values=None) -> np.ndarray:
        """(limit, M) fraction of records whose drift ratio exceeds each limit at each IM (a
        collapse exceeds every limit); records with unknown EDP there are left out."""
        d = np.asarray(self.exceedance_limits if limits is None else limits, dtype=np.float64)
        x = self.levels if im_values is None else np.asarray(im_values, dtype=np.float64)
        e = self.edp_at(x)
        known = ~np.isnan(e)
        with np.errstate(invalid="ignore"):
            return np.array([((e > lim) & known).sum(0) / np.maximum(known.sum(0), 1) for lim in d])

    def limit_capacities(self, limit: float) -> tuple[np.ndarray, np.ndarray]:
        """Per record, the IM [g] at which the curve first exceeds drift ratio ``limit``
        (linear interpolation; the collapse IM if it collapses first), and for records that
        never exceed it the highest IM survived (censored); ``(capacity, censored)``, NaN-padded."""
        cap = np.full(self.n_records, np.nan)
        cen = np.full(self.n_records, np.nan)
        for r in range(self.n_records):
            ci, ce = self.curve(r)
            above = np.flatnonzero(ce > limit)
            if above.size:
                k = above[0]
                cap[r] = ci[k - 1] + (ci[k] - ci[k - 1]) * (limit - ce[k - 1]) / (ce[k] - ce[k - 1])
            elif np.isfinite(self.collapse_im[r]):
                cap[r] = self.collapse_im[r]
            else:
                cen[r] = ci[-1]
        return cap, cen

    # ------------------------------------------------------------------ fragility
    def collapse_fragility(self, method: str = "capacities", *, n_boot: int = 1000, ci: float = 0.90,
                           seed: int | None = 0) -> LognormalFragility:
        """Collapse fragility: ``"capacities"`` (MLE of the records' collapse IMs, censored
        records included) or ``"counts"`` (Baker's binomial MLE on the grid levels)."""
        if method == "capacities":
            return fragility_from_capacities(self.collapse_im, self.censored_im, n_boot=n_boot, ci=ci, seed=seed)
        if method == "counts":
            return fragility_from_exceedance(self.levels, self.collapse_table(), n_boot=n_boot, ci=ci, seed=seed)
        raise ValueError(f"unknown method {method!r}; expected 'capacities' or 'counts'")

    def collapse_table(self) -> np.ndarray:
        """(R, level) True where the record has collapsed at or below the grid level."""
        c = np.where(np.isfinite(self.collapse_im), self.collapse_im, np.inf)
        return self.levels[None, :] >= c[:, None]

    def limit_fragility(self, limit: float, *, n_boot: int = 1000, ci: float = 0.90,
                        seed: int | None = 0) -> LognormalFragility:
        """Fragility of exceeding drift ratio ``limit`` (MLE of the records' IM capacities)."""
        cap, cen = self.limit_capacities(limit)
        return fragility_from_capacities(cap, cen, n_boot=n_boot, ci=ci, seed=seed)

    # ------------------------------------------------------------------ output
    def points_table(self) -> str:
        """CSV text: one row per run."""
        n = self.building.n_stories
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["record_index", "record", "stage", "im_g", "scale", "status", "collapsed", "substeps",
                    "max_drift_ratio", *[f"drift_ratio_{i + 1}" for i in range(n)],
                    *[f"residual_ratio_{i + 1}" for i in range(n)], *[f"peak_drift_mm_{i + 1}" for i in range(n)]])
        dr, rr, col, edp = self.drift_ratio, self.residual_ratio, self.collapsed, self.edp
        order = np.lexsort((self.point_im, self.point_record))
        for k in order:
            w.writerow([int(self.point_record[k]), self.record_names[self.point_record[k]], self.point_stage[k],
                        f"{self.point_im[k]:.6g}", f"{self.point_scale[k]:.6g}", int(self.point_status[k]),
                        int(col[k]), int(self.point_substeps[k]), f"{edp[k]:.6g}",
                        *[f"{v:.6g}" for v in dr[k]], *[f"{v:.6g}" for v in rr[k]],
                        *[f"{v:.6g}" for v in self.peak_drift[k]]])
        return buf.getvalue()

    def summary(self, *, n_boot: int = 1000, ci: float = 0.90, seed: int | None = 0) -> dict:
        """A JSON-able summary: records, collapse fragility (both estimators), drift-limit
        fragilities and exceedance table, fractiles, settings and notes."""
        from .._version import __version__
        frag = {}
        for method in ("capacities", "counts"):
            try:
                frag[method] = self.collapse_fragility(method, n_boot=n_boot, ci=ci, seed=seed).to_dict()
            except ValueError as err:
                frag[method] = {"not_fitted": str(err)}
        limits = {}
        exc = self.exceedance()
        for j, d in enumerate(self.exceedance_limits):
            try:
                f = self.limit_fragility(d, n_boot=n_boot, ci=ci, seed=seed).to_dict()
            except ValueError as err:
                f = {"not_fitted": str(err)}
            limits[f"{d:g}"] = {"fragility": f, "fraction_exceeding": exc[j].tolist()}
        fr = self.fractiles()
        return {
            "format": FORMAT, "version": VERSION, "hlaid_version": __version__, "units": UNITS_JSON,
            "building": self.building.to_dict(),
            "intensity_measure": {"name": self.im, "label": self.im_label, "units": "g",
                                  "period_s": None if not np.isfinite(self.period) else self.period},
            "edp": "peak inter-story drift ratio (largest story)",
            "collapse_criteria": {"drift_limit": self.drift_limit, "slope_ratio": self.slope_ratio,
                                  "divergence": True},
            "levels_g": self.levels.tolist(),
            "records": [{"name": self.record_names[r], "source": self.record_sources[r],
                         "im_unscaled_g": float(self.record_im[r]), "dt_s": float(self.record_dt[r]),
                         "collapse_im_g": _num(self.collapse_im[r]), "bracket_g": [_num(self.collapse_lo[r]),
                                                                                    _num(self.collapse_hi[r])],
                         "collapse_mode": self.collapse_mode[r], "censored_at_g": _num(self.censored_im[r])}
                        for r in range(self.n_records)],
            "collapse_fragility": frag,
            "drift_limits": limits,
            "fractiles": {f"p{q}": [_num(v) for v in fr[i]] for i, q in enumerate(FRACTILES)},
            "n_runs": int(self.point_im.size), "settings": self.settings, "notes": list(self.notes),
            "timing": self.timing,
        }

    def arrays(self) -> dict[str, np.ndarray]:
        """Every array of the result (for NPZ)."""
        return {"record_names": np.array(self.record_names), "record_im": self.record_im,
                "record_dt": self.record_dt, "levels": self.levels, "elastic_slope": self.elastic_slope,
                "point_record": self.point_record, "point_im": self.point_im, "point_scale": self.point_scale,
                "point_stage": self.point_stage.astype(str), "point_status": self.point_status,
                "point_substeps": self.point_substeps, "peak_drift": self.peak_drift,
                "residual_drift": self.residual_drift, "height": np.asarray(self.building.height),
                "collapse_im": self.collapse_im, "collapse_lo": self.collapse_lo, "collapse_hi": self.collapse_hi,
                "collapse_mode": np.array(self.collapse_mode), "censored_im": self.censored_im}

    def save(self, out: str | os.PathLike, *, force: bool = False, plots: bool = True, n_boot: int = 1000,
             ci: float = 0.90, seed: int | None = 0, inputs: Sequence[str | os.PathLike | None] = (),
             basis: dict | None = None) -> Path:
        """Write the folder ``out`` atomically: points.csv, summary.json (with ``basis``, what the
        decision rests on, :meth:`hlaid.ida.basis.DecisionBasis.to_dict`, where given), ida.npz and, with
        ``plots``, ida_curves.png, fragility.png, exceedance.png. An existing non-empty folder
        is replaced only with ``force``, and only when hlaid wrote it and it holds none of
        ``inputs`` (:func:`hlaid._fileio.check_output_folder`)."""
        summary = self.summary(n_boot=n_boot, ci=ci, seed=seed)
        if basis is not None:
            summary["basis"] = basis
        with atomic_directory(out, force=force, inputs=inputs) as tmp:
            (tmp / "points.csv").write_text(self.points_table())
            write_json(tmp / "summary.json", summary)
            write_npz(tmp / "ida.npz", self.arrays())
            if plots:
                from ..plots import save_figure
                from .plots import plot_exceedance, plot_fragility, plot_ida_curves
                save_figure(plot_ida_curves(self), tmp / "ida_curves.png")
                save_figure(plot_fragility(self, n_boot=n_boot, ci=ci, seed=seed), tmp / "fragility.png")
                save_figure(plot_exceedance(self, n_boot=0), tmp / "exceedance.png")
        return Path(out)


def _percentile_inf(v: np.ndarray, q: float) -> float:
    """Percentile ``q`` of sorted ``v`` that may hold inf (no NaN from inf - inf)."""
    pos = (v.size - 1) * q / 100.0
    lo, hi = int(np.floor(pos)), int(np.ceil(pos))
    if np.isinf(v[hi]):
        return float("inf")
    return float(v[lo] + (v[hi] - v[lo]) * (pos - lo))


def _num(v) -> float | None:
    v = float(v)
    return v if np.isfinite(v) else None
