"""Two questions about a recorded event, two names.

* **Did the clone survive this recorded event?** (:func:`hlaid.loss.ownmotion.own_motion_check`,
  :class:`OwnMotionCheck`):
  the event's OWN ground motion replayed by the clone and its posterior ensemble, with the
  collapse law in force; ``P(collapse | this motion)`` is the fraction of the ensemble's members
  (the nominal clone alone where there is no ensemble) that reach the drift limit or diverge,
  and the replay's peak and residual drift ratios stand beside the measured ones.
* **How likely is collapse in another record of this intensity?** (:func:`fragility_at_im`): the
  collapse fragility (the IDA over a record suite) at the event's Sa(T1). It is a statement about
  other records, not about this one.

Every command that reports either names it with :data:`OWN_MOTION` or :data:`AT_INTENSITY`, and
writes them under the JSON keys ``p_collapse_own_motion`` and ``p_collapse_fragility_at_im``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

OWN_MOTION = "P(collapse | the event's own motion), clone and ensemble replaying it"
AT_INTENSITY = "P(collapse | another record of the event's intensity), the IDA fragility at its Sa(T1)"

RESIDUAL_TOLERANCE = 0.003
"""The replay's residual drift ratio within this of the measured one (absolute) counts as met."""


def p_collapse(im: float, median: float | None, beta: float | None) -> float | None:
    """P(collapse | IM = ``im``) of the lognormal fragility (``median`` [g], ``beta``); None where
    the fragility or the intensity is unknown."""
    if median is None or beta is None or im is None or not (median > 0 and beta > 0 and math.isfinite(im)):
        return None
    if im <= 0:
        return 0.0
    return 0.5 * math.erfc(-math.log(im / median) / (beta * math.sqrt(2.0)))


def fragility_at_im(im: float | None, median: float | None, beta: float | None) -> float | None:
    """P(collapse) of the lognormal collapse fragility at intensity ``im`` [g]: the one
    computation of the "another record of this intensity" figure (None: not assessed)."""
    return None if im is None else p_collapse(im, median, beta)


@dataclass(frozen=True)
class OwnMotionCheck:
    """The clone replaying one recorded event's own ground motion.

    Attributes
    ----------
    name : the event
    in_clone : the clone was identified from it (else: a later event it has not seen)
    p_collapse : P(collapse | this motion) over the runs (None: not assessed)
    n_runs : the buildings replayed (the nominal clone, or the ensemble's members)
    peak, residual : ``(story,)`` the nominal clone's peak and residual drift ratios
    residual_median : ``(story,)`` the ensemble's median residual drift ratio (None: no ensemble)
    measured_peak, measured_residual : ``(story,)`` the record's (None: no floor displacements)
    heights_assumed : the drift ratios rest on story heights given, not measured
    why : why it is not assessed (empty when it is)
    """

    name: str
    in_clone: bool
    p_collapse: float | None
    n_runs: int = 0
    peak: tuple[float, ...] | None = None
    residual: tuple[float, ...] | None = None
    residual_median: tuple[float, ...] | None = None
    measured_peak: tuple[float, ...] | None = None
    measured_residual: tuple[float, ...] | None = None
    heights_assumed: bool = False
    why: str = ""

    @property
    def residual_error(self) -> tuple[float, ...] | None:
        """``(story,)`` the nominal replay's residual drift ratio less the measured (None: not known)."""
        if self.residual is None or self.measured_residual is None:
            return None
        return tuple(float(a - b) for a, b in zip(self.residual, self.measured_residual))

    @property
    def residual_met(self) -> bool | None:
        """Whether every story's residual lies within :data:`RESIDUAL_TOLERANCE` of the measured."""
        e = self.residual_error
        return None if e is None else bool(max(abs(v) for v in e) <= RESIDUAL_TOLERANCE)

    def text(self) -> str:
        """One line: the figure with its name, the drifts beside the measured."""
        if self.p_collapse is None:
            return f"{self.name}: {OWN_MOTION}: not assessed ({self.why})"
        who = "clone" if self.n_runs <= 1 else f"{self.n_runs} clones"
        out = f"{self.name}: {OWN_MOTION}: {self.p_collapse:.1%} ({who}"
        out += ", identified from it)" if self.in_clone else ", not identified from it)"
        pct = _pct
        if self.peak is not None:
            out += f"; peak drift {pct(self.peak)} %"
            out += f" (measured {pct(self.measured_peak)} %)" if self.measured_peak is not None else ""
        if self.residual is not None:
            out += f", residual {pct(self.residual)} %"
            out += f" (measured {pct(self.measured_residual)} %)" if self.measured_residual is not None else ""
        if self.heights_assumed:
            out += " [drift ratios over assumed story heights]"
        return out

    def to_dict(self) -> dict:
        return {"name": self.name, "in_clone": self.in_clone, "question": OWN_MOTION,
                "p_collapse_own_motion": self.p_collapse, "n_runs": self.n_runs,
                "peak_drift_ratio": _list(self.peak), "residual_drift_ratio": _list(self.residual),
                "residual_drift_ratio_median": _list(self.residual_median),
                "measured_peak_drift_ratio": _list(self.measured_peak),
                "measured_residual_drift_ratio": _list(self.measured_residual),
                "residual_drift_error": _list(self.residual_error), "residual_within_0.3%": self.residual_met,
                "heights_assumed": self.heights_assumed, "why_not_assessed": self.why or None}


def _list(v):
    return None if v is None else [float(x) for x in v]


def _pct(v) -> str:
    return " / ".join(f"{100 * x:.2f}" for x in v)


def check_of_demands(name: str, nominal, ensemble=None, *, measured=None, in_clone: bool = False,
                     heights_assumed: bool = False) -> OwnMotionCheck:
    """The :class:`OwnMotionCheck` of demands (:class:`~hlaid.loss.Demands`) of one recorded
    motion: ``nominal`` the identified clone's (or None), ``ensemble`` its members' (or None).
    P(collapse | this motion) is the fraction of the members that collapse (the nominal clone's
    0 or 1 without an ensemble); the peak and residual drift ratios are the nominal clone's (the
    members' median where there is no nominal run)."""
    def row(d, k):
        return None if d is None or bool(d.collapsed[k]) else (tuple(float(v) for v in d.pid[k]),
                                                                tuple(float(v) for v in d.rid[k]))
    peak = res = rmed = None
    if nominal is not None and row(nominal, 0) is not None:
        peak, res = row(nominal, 0)  # type: ignore[misc]
    p, n = (float(nominal.collapsed[0]), 1) if nominal is not None else (None, 0)
    if ensemble is not None and ensemble.n_realizations:
        p, n = float(np.mean(ensemble.collapsed)), int(ensemble.n_realizations)
        ok = ~ensemble.collapsed
        if ok.any():
            rmed = tuple(float(v) for v in np.median(ensemble.rid[ok], axis=0))
            if peak is None:
                peak = tuple(float(v) for v in np.median(ensemble.pid[ok], axis=0))
                res = rmed
    mp, mr = (None, None) if measured is None else (tuple(map(float, measured[0])), tuple(map(float, measured[1])))
    return OwnMotionCheck(name=name, in_clone=in_clone, p_collapse=p, n_runs=n, peak=peak, residual=res,
                          residual_median=rmed, measured_peak=mp, measured_residual=mr,
                          heights_assumed=heights_assumed, why="" if p is not None else "no replay")


RESIDUAL_WINDOW_S = 1.0
"""A measured residual drift: the mean drift over the record's last second less its first's."""


def measured_drift_ratios(meas, heights) -> tuple[np.ndarray, np.ndarray] | None:
    """``(peak, residual)`` ``(story,)`` drift ratios the measurement's floor displacements held
    (the largest |story drift| and the drift left at its end, the mean over its last second less
    its first's, each over the story's height); None without floor displacements, heights or two
    seconds of record."""
    if meas is None or meas.floor_disp is None or heights is None:
        return None
    h = np.asarray(heights, dtype=float)
    u = np.asarray(meas.floor_disp, dtype=float)
    n = max(int(round(RESIDUAL_WINDOW_S / meas.dt)), 1)
    if h.shape != (u.shape[1],) or 2 * n > u.shape[0]:
        return None
    drift = np.diff(u, axis=1, prepend=0.0)
    return np.nanmax(np.abs(drift), axis=0) / h, np.abs(drift[-n:].mean(axis=0) - drift[:n].mean(axis=0)) / h


__all__ = ["AT_INTENSITY", "OWN_MOTION", "OwnMotionCheck", "RESIDUAL_TOLERANCE", "RESIDUAL_WINDOW_S",
           "check_of_demands", "fragility_at_im", "measured_drift_ratios"]
