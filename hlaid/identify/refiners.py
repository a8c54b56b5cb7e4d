"""Refinements of the paper's estimate against the measured floor accelerations, by name.

``refine.method`` picks one of :data:`REFINERS` (as torchdiffeq's ``SOLVERS``). Each is a small
class whose ``__init__`` stores the settings of ``refine`` and whose :meth:`Refiner.refine` takes a
:class:`RefineProblem` (the measurement, the paper's estimate, what the fall-backs need) and
returns a :class:`Refinement`; each owns its fall-back:

- ``"eiv"``: errors in variables (:mod:`hlaid.identify.eiv`), from the regressions' building;
  where it misses the data, stops on its iteration limit or its tangent is unstable or too
  large, least squares (with its restart) and the errors-in-variables fit once more from there;
- ``"least_squares"``: least squares of the normalised residuals, again from a neutral start
  where it misses the data by more than ``restart_ratio`` times its noise;
- ``"none"``: the paper's estimate as it is.

The two replay refinements first fit k0 alone and run the regressions again with it.

This module imports no heavy library at import time (the configuration checks its names).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import _progress
from ..errors import NUMERICAL_FAILURES, InputError, NotIdentifiableError, failure_text, one_line

if TYPE_CHECKING:
    from ..measurement import Measurement
    from ..model import Building
    from .refine import RefineResult

SUBSTEPS = 4
"""RK4 sub-steps per sample of the replays (they define the optimum). Fewer, or a looser
:data:`FTOL`, was faster but moved the optimum on ill-conditioned random buildings (2 sub-steps
at 200 Hz: one run's worst parameter from 63 % to 3000 %; ftol 1e-6: another's from 36 % to
2500 %)."""
JAC_SUBSTEPS = 2
"""RK4 sub-steps of the replays that build the finite-difference Jacobian, and of the tangent's
replay: both only steer or weight the search; 2 cut the refinement of a 20-story building by a
third and left the Table 1 and random-building studies as they were (1 moved two random
buildings to worse optima)."""
FTOL = 1e-10
"""Least squares stops when a step lowers the cost by less than this fraction of it."""
EIV_FTOL = 1e-6
"""The same for the errors-in-variables fits: their cost is a negative log-likelihood whose
minimum is ``N/2`` noise variances, so this is about 0.01 units of log-likelihood for a 50 s
record at 200 Hz (a tenth of a standard error); at 1e-10 the fit found the same optimum in 19
evaluations instead of 6."""
UPPER_FACTOR = 10.0
"""k0, dy and delta_eta at most this many times their start (delta_eta's taken as at least 0.5)."""


@dataclass(frozen=True, eq=False)
class RefineProblem:
    """What a refinement of one measurement needs.

    Attributes
    ----------
    measurement : ground and floor accelerations
    start : the paper's estimate (regressions and classifiers)
    stories : 0-based identifiable stories: all their parameters are refined, the others' k0 only
    noise : the measurement's noise level, a fraction of each channel's RMS (the misfit test)
    peak_drift : ``(story,)`` peak drift along HLA's drift [mm] (the neutral restart's dy)
    regress : the regressions again with another k0: ``(story,)`` k0 -> building
    """

    measurement: Measurement
    start: Building
    stories: tuple[int, ...]
    noise: float
    peak_drift: np.ndarray
    regress: Callable[[np.ndarray], Building]

    def noise_ratio(self, rr: RefineResult) -> float:
        """The least-squares (un-whitened) cost of ``rr`` over ``0.5 N sigma^2`` (N residuals, sigma
        the noise level, at least 1 %: a noise-free record fits to the model's own discretisation)."""
        cost = rr.cost_final if rr.plain_cost is None else rr.plain_cost
        return cost / (0.5 * np.asarray(self.measurement.floor_acc).size * max(self.noise, 0.01) ** 2)

    def neutral_start(self) -> Building:
        """The restart: mid-range shape parameters, yield at a tenth of each story's peak drift,
        k0 1.5x the estimate (HLA's k0 is low when a story yields before it completes a half
        cycle that HLA sees)."""
        b = self.start
        n = b.n_stories
        return b.replace(k0=1.5 * b.k0, alpha=np.full(n, 0.2), p=np.full(n, 2.0),
                         dy=np.maximum(self.peak_drift / 10, 1e-3), delta_eta=np.full(n, 0.5))


@dataclass(frozen=True, eq=False)
class Refinement:
    """A refinement's outcome.

    Attributes
    ----------
    building : the refined building (the start itself without refinement)
    result : the final fit (its Jacobian and residuals give the clone's uncertainty); None
        without refinement
    info : the summary the clone keeps (``clone.paper.refine``); None without refinement
    """

    building: Building
    result: RefineResult | None = None
    info: dict | None = None


class Refiner:
    """A refinement: ``__init__`` stores the settings of ``refine`` (``method`` aside)."""

    def __init__(self, *, parameters=("k0", "alpha", "p", "dy", "delta_eta"), damping: bool = False,
                 band_hz=(0.1, 20.0), max_iterations: int = 40, tangent_max_mb: float = 1024.0,
                 restart_ratio: float | None = 1.0):
        self.parameters = tuple(parameters)
        self.damping = damping
        self.band_hz = tuple(band_hz)
        self.max_iterations = max_iterations
        self.tangent_max_mb = tangent_max_mb
        self.restart_ratio = restart_ratio

    def refine(self, problem: RefineProblem) -> Refinement:
        return Refinement(building=problem.start)


class NoRefinement(Refiner):
    """``"none"``: the paper's estimate as it is."""


class LeastSquares(Refiner):
    """``"least_squares"``: k0 alone, the regressions again, then least squares of every
    parameter of the identifiable stories; where that fit misses the data by more than
    ``restart_ratio`` times its noise, again from a neutral start (every story's parameters),
    kept where its cost is at least 20 % lower."""

    def refine(self, problem: RefineProblem) -> Refinement:
        info: dict[str, Any] = {}
        start = self._k0_stage(problem, info)
        rr = self._fit(start, problem, info)
        info["noise_ratio"] = problem.noise_ratio(rr)
        info.update({"cost_initial": rr.cost_initial, "cost_final": rr.cost_final, "nfev": rr.nfev,
                     "message": rr.message})
        return Refinement(building=rr.building, result=rr, info=info)

    def _replay(self, building: Building, problem: RefineProblem, **kw) -> RefineResult:
        from .refine import refine_replay

        settings: dict[str, Any] = {"band_hz": self.band_hz, "max_iterations": self.max_iterations,
                                    "upper_factor": UPPER_FACTOR, "substeps": SUBSTEPS, "jac_substeps": JAC_SUBSTEPS,
                                    "ground_noise": "ignore", "ftol": FTOL, "parameters": self.parameters,
                                    "damping": self.damping}
        return refine_replay(building, problem.measurement, **{**settings, **kw})

    def _k0_stage(self, problem: RefineProblem, info: dict) -> Building:
        """k0 alone first (HLA's k0 is its least certain output and the regressions amplify its
        error), then the regressions again with it: the start of the full fit."""
        if "k0" not in self.parameters:
            return problem.start
        s1 = self._replay(problem.start, problem, parameters=("k0",), damping=False,
                          desc="[identify] replay fit, k0 alone")
        info["stage1_k0"] = {"cost_initial": s1.cost_initial, "cost_final": s1.cost_final, "nfev": s1.nfev}
        return problem.regress(s1.building.k0.copy())

    def _ratio_limit(self) -> float:
        """The noise ratio above which a fit misses the data (``restart_ratio``; 1 when None)."""
        return 1.0 if self.restart_ratio is None else self.restart_ratio

    def _fit(self, start: Building, problem: RefineProblem, info: dict) -> RefineResult:
        """Least squares from ``start``, and the restart (``info["restart"]``)."""
        rr = self._replay(start, problem, stories=problem.stories)
        ratio = problem.noise_ratio(rr)
        if self.restart_ratio is not None and ratio > self.restart_ratio:
            _progress.info(f"[identify] the refined replay misses the data by {ratio:.1f}x its noise level "
                           "(model error: a shear-building clone does not follow everything recorded); refining "
                           "again from a neutral start. Judge the clone by its replay R and flags below; a narrower "
                           "band (refine.band_hz) or the structural system (--system) may fit better")
            alt = self._replay(problem.neutral_start(), problem, desc="[identify] replay fit from a neutral start")
            kept = alt.cost_final < 0.8 * rr.cost_final
            info["restart"] = {"noise_ratio": ratio, "cost_final": alt.cost_final, "nfev": alt.nfev, "kept": kept,
                               "stories": "all"}
            if kept:
                rr = alt
        return rr


class ErrorsInVariables(LeastSquares):
    """``"eiv"``: the errors-in-variables fit (residuals whitened by the tangent of the replay of
    the building it starts from) from the regressions' building (after the k0 stage). Where it
    misses the data by more than ``restart_ratio`` (1 when None) times its noise, stops on
    ``max_iterations`` (a start too far for its tangent), or the tangent is unstable or larger
    than ``tangent_max_mb``: least squares with its restart, then the errors-in-variables fit
    from that optimum unless it too misses the data (a tangent taken there weights nothing real)
    or its tangent fails; ``info["tangent"]`` says which."""

    def _fit(self, start: Building, problem: RefineProblem, info: dict) -> RefineResult:
        eiv, info["tangent"] = self._eiv(start, problem, "regressions")
        if eiv is not None:
            ratio = problem.noise_ratio(eiv)
            if ratio <= self._ratio_limit() and eiv.converged:
                return eiv
            why = (f"the errors-in-variables fit misses the data by {ratio:.1f}x its noise level"
                   if ratio > self._ratio_limit() else
                   f"the errors-in-variables fit did not converge in {eiv.nfev} evaluations")
        else:
            why = info["tangent"]["why"]
        _progress.info(f"[identify] {why}: least squares first")
        info["tangent"] = {"fallback": why}
        rr = super()._fit(start, problem, info)
        ratio = problem.noise_ratio(rr)
        if ratio > self._ratio_limit():
            why = f"the least-squares fit misses the data by {ratio:.1f}x its noise level"
        else:
            eiv, stage = self._eiv(rr.building, problem, "least squares")
            if eiv is not None:
                info["tangent"].update(stage)
                return eiv
            why = stage["why"]
        _progress.info(f"[identify] errors-in-variables stage skipped: {why}")
        info["tangent"].update({"skipped": why})
        return rr

    def _eiv(self, building: Building, problem: RefineProblem, start: str) -> tuple[RefineResult | None, dict]:
        """The errors-in-variables fit from ``building`` (``start`` names it), with its summary;
        None and the reason where the tangent is unstable or larger than ``tangent_max_mb``."""
        try:
            eiv = self._replay(building, problem, stories=problem.stories, ftol=EIV_FTOL, ground_noise="tangent",
                               tangent_max_mb=self.tangent_max_mb,
                               desc=f"[identify] errors-in-variables fit from the {start}")
        except NUMERICAL_FAILURES as err:
            return None, {"why": failure_text(err)}
        return eiv, {"start": start, "cost_initial": eiv.cost_initial, "cost_final": eiv.cost_final, "nfev": eiv.nfev,
                     "seconds": eiv.seconds}


def fit_or_fall_back(fit: Callable[..., Any], ground_noise: str) -> Any:
    """``fit(ground_noise=ground_noise)`` (a joint fit, :func:`hlaid.joint.fit.map_refine`
    with its other arguments bound); where the errors-in-variables weighting (``"tangent"``)
    fails numerically (:data:`hlaid.errors.NUMERICAL_FAILURES`), least squares instead, with a warning and a
    note in each event's record of the fit (``errors_in_variables``, kept in the clone's
    diagnostics). A least-squares fit that fails too is a :class:`~hlaid.errors.NotIdentifiableError`."""
    why = None
    if ground_noise == "tangent":
        try:
            return fit(ground_noise="tangent")
        except NUMERICAL_FAILURES as err:
            why = failure_text(err)
        _progress.warn(f"errors-in-variables stage skipped ({why}); the events are fitted by least squares")
    try:
        res = fit(ground_noise="ignore")
    except np.linalg.LinAlgError as err:
        raise NotIdentifiableError(f"the joint fit failed numerically ({one_line(err, 80)}): the "
                                   "records do not determine the parameters") from None
    if why is None:
        return res
    note = {"errors_in_variables": {"skipped": why, "fitted_by": "least squares"}}
    return dataclasses.replace(res, events=[{**e, **note} for e in res.events])


REFINERS: dict[str, type[Refiner]] = {"eiv": ErrorsInVariables, "least_squares": LeastSquares, "none": NoRefinement}
"""Refinements by name (``refine.method``)."""


def get_refiner(name: str, **settings) -> Refiner:
    """The refinement :data:`REFINERS` names, with the settings of ``refine`` (InputError listing
    the names for an unknown one)."""
    if name not in REFINERS:
        raise InputError(f"refine.method = {name!r} is unknown; expected one of {', '.join(map(repr, REFINERS))}")
    return REFINERS[name](**settings)

