"""Replay refinement: least squares of the replayed against the measured floor accelerations.

The regressions and classifiers of the paper give a building close to the truth; starting
there, a bounded trust-region search over the story parameters matches the clone's absolute
floor accelerations to the measured ones (:class:`~hlaid.identify.residuals.ReplayResiduals`).
:class:`ParameterVector` maps the adjusted parameters to buildings; :func:`fit_residuals` runs
the search on any residual function of buildings; :func:`refine_replay` puts the two together
for one measurement. Jacobians come from one batch of the simulator: the replay and its tangent-linear
model (:mod:`hlaid.simulate.sensitivity`), or full replays differenced (see :func:`fit_residuals`).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ParamSpec, Protocol, TypeVar

import numpy as np
from scipy.optimize import least_squares

from .. import _progress
from .._threads import blas_threads
from ..errors import InputError
from ..measurement import Measurement
from ..model import Building
from ..simulate.sensitivity import linearised
from .residuals import ReplayResiduals

_BLAS_ONE_THREAD = 1e8
"""Residuals x parameters^2 (the flops of the Jacobian's SVD) below which the refinement runs BLAS
on one thread: Table 1's 7e6, a 20-story building's 2e9."""

_P = ParamSpec("_P")
_R = TypeVar("_R")

JACOBIANS = ("tangent", "difference")
"""How :func:`fit_residuals` takes its Jacobians: tangent-linear replays or full replays differenced."""

_LIMITS = {"k0": (1e-6, np.inf), "alpha": (0.0, 0.95), "p": (1.0, 10.0), "dy": (1e-6, np.inf),
           "delta_eta": (0.0, np.inf)}


@dataclass(frozen=True)
class RefineResult:
    """Outcome of :func:`refine_replay`.

    Attributes
    ----------
    building : the refined building
    cost_initial, cost_final : half the sum of squared normalised residuals
    nfev : residual evaluations; seconds : wall time; message : the optimiser's
    slots : the adjusted parameters as ``(name, story)`` pairs (story -1: the damping ratio)
    x : their values at the solution, shape ``(n_params,)``
    jacobian : d residuals / d x at the solution (the optimiser's last Jacobian), shape
        ``(n_time * n_floors, n_params)``, rows time-major
    residuals : normalised residuals at the solution, shape ``(n_time * channels,)``
        (``reshape(n_time, channels)`` gives one column per channel); both feed
        :mod:`hlaid.uncertainty`
    channels : residual columns: the floors, and with ``ground_noise="tangent"`` one more
        (the ground correction's)
    converged : the search stopped on a tolerance, not on ``max_iterations``
    criterion : the ``ground_noise`` the residuals were fitted with
    plain_cost : half the sum of squared normalised residuals at the solution *before* any
        whitening (``cost_final`` itself with ``ground_noise="ignore"``): the scale of the
        noise-consistency test, whatever the fit's weighting
    """

    building: Building
    cost_initial: float
    cost_final: float
    nfev: int
    seconds: float
    message: str
    slots: tuple = ()
    x: np.ndarray | None = None
    jacobian: np.ndarray | None = None
    residuals: np.ndarray | None = None
    channels: int = 0
    plain_cost: float | None = None
    converged: bool = True
    criterion: str = "ignore"


def _blas_threads(fn: Callable[_P, _R]) -> Callable[_P, _R]:
    """Run ``fn`` (:func:`refine_replay`) with BLAS on one thread for small problems.

    Its threads and the compiled replays' (OpenMP) share the cores, and when they met, a
    Jacobian's 2 ms SVD took 0.1 s at random (the refinement of Table 1: 2.2-2.5 s against
    1.45-1.5 s with one BLAS thread). A 20-story building's SVDs (2e9 flops) need both threads
    (its refinement 83 s against 96 s on one). The call's own arguments say which: residuals x
    parameters^2 against :data:`_BLAS_ONE_THREAD`.
    """
    sig = inspect.signature(fn)

    @functools.wraps(fn)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        a = sig.bind(*args, **kwargs)
        a.apply_defaults()
        n_params = len(a.arguments["parameters"]) * a.arguments["building"].n_stories + bool(a.arguments["damping"])
        small = np.asarray(a.arguments["measurement"].floor_acc).size * n_params**2 < _BLAS_ONE_THREAD
        with blas_threads(1 if small else None):
            return fn(*args, **kwargs)

    return wrapper


@_blas_threads
def refine_replay(building: Building, measurement: Measurement, *, parameters=("k0", "alpha", "p", "dy", "delta_eta"),
                  stories=None, damping: bool = False, band_hz=(0.1, 20.0), max_iterations: int = 40,
                  substeps: int = 4, upper_factor: float | None = 10.0, ftol: float = 1e-10,
                  jac_substeps: int | None = None, ground_noise: str = "ignore",
                  ground_memory_s: float | None = None, tangent_max_mb: float | None = None,
                  desc: str = "[identify] replay fit", jacobian: str = "tangent") -> RefineResult:
    """Refine ``building`` so that its replay matches ``measurement``'s floor accelerations.

    Parameters
    ----------
    building : the starting point (masses, heights and P-Delta are kept)
    measurement : ground and floor accelerations
    parameters : story parameters to adjust
    stories : 0-based stories whose parameters are adjusted (default all); for the others
        only ``k0`` is adjusted
    damping : also adjust the Rayleigh damping ratio
    upper_factor : k0, dy and delta_eta are bounded above by this factor times their start
        (delta_eta's start taken as at least 0.5 s^2/m^2), so that a parameter the data
        hardly constrain cannot run away; None: open above
    ftol : stop when a step lowers the cost by less than this fraction of it
    jac_substeps : RK4 sub-steps of the replays that build the Jacobian
        (default: ``substeps``). The Jacobian only steers the search; the residuals, and so the
        optimum, keep ``substeps``. Its base point is replayed with the same sub-steps as its
        columns, so the difference quotient carries no discretisation offset.
    ground_noise : ``"ignore"`` (least squares of the residuals) or ``"tangent"``: whitened
        against the ground noise carried to the floors by the time-varying tangent of the replay
        of ``building``, i.e. maximum likelihood with the true ground as a nuisance (every
        channel's noise a common fraction of its RMS, as :func:`hlaid.synthetic.simulate_measurement`
        adds it; :class:`~hlaid.identify.residuals.ReplayResiduals`). The residuals are then
        low-passed only (``band_hz[0]`` is not used) and compared at every third sample of a
        200 Hz record low-passed at 20 Hz; ``cost_*`` and ``residuals`` are then of the whitened
        residuals, ``(samples / stride, floors + 1)``.
    ground_memory_s : with ``"tangent"``, seconds of the floors' response kept after each
        ground sample; None: :func:`~hlaid.identify.eiv.ground_memory` of ``building``
    tangent_max_mb : with ``"tangent"``, raise :class:`~hlaid.errors.TangentTooLargeError` where the
        tangent would take more than this many MiB (None: only the hard limit)
    desc : the name of the search in the progress messages
    jacobian : ``"tangent"`` (forward-mode sensitivities of the replay) or ``"difference"`` (full
        replays differenced); see :func:`fit_residuals`
    """
    t0 = time.perf_counter()
    residuals = ReplayResiduals(measurement, band_hz=band_hz, substeps=substeps, ground_noise=ground_noise,
                                at=building, tangent_substeps=substeps if jac_substeps is None else jac_substeps,
                                memory_s=ground_memory_s, max_mb=tangent_max_mb)
    vector = ParameterVector(building, parameters=parameters, stories=stories, damping=damping,
                             upper_factor=upper_factor)
    return fit_residuals(vector, residuals, max_iterations=max_iterations, ftol=ftol,
                         jac_substeps=substeps if jac_substeps is None else jac_substeps, t0=t0, desc=desc,
                         jacobian=jacobian)


class ParameterVector:
    """The adjusted parameters of a building as a bounded vector ``x``.

    Parameters
    ----------
    building : the starting point (its values are ``x0``; the rest of it is kept)
    parameters, stories, damping, upper_factor : as :func:`refine_replay`

    Attributes
    ----------
    slots : ``(name, story)`` per entry of ``x`` (story -1: the damping ratio)
    x0, lower, upper : the start (nudged inside the bounds) and the bounds, ``(n_params,)``
    scale : the search's scale per entry (the start's magnitude, at least 1e-3)
    """

    def __init__(self, building: Building, *, parameters: Sequence[str] = ("k0", "alpha", "p", "dy", "delta_eta"),
                 stories=None, damping: bool = False, upper_factor: float | None = 10.0):
        self.building = building
        stories = range(building.n_stories) if stories is None else stories
        slots = [(name, i) for i in range(building.n_stories) for name in parameters if i in stories or name == "k0"]
        x0 = np.array([getattr(building, name)[i] for name, i in slots], dtype=float)
        if damping:
            slots.append(("damping", -1))
            x0 = np.append(x0, building.damping.ratio)
        lo = np.array([_LIMITS[n][0] if n != "damping" else 0.0 for n, _ in slots])
        hi = np.array([_LIMITS[n][1] if n != "damping" else 0.5 for n, _ in slots])
        if upper_factor is not None:
            for j, (n, _) in enumerate(slots):
                if n in ("k0", "dy", "delta_eta"):
                    hi[j] = upper_factor * (max(x0[j], 0.5) if n == "delta_eta" else x0[j])
        pad = 1e-6 * np.maximum(np.abs(x0), 1e-6)
        self.slots = slots
        self.lower, self.upper = lo, hi
        self.x0 = np.minimum(np.maximum(x0, lo + pad), np.where(np.isfinite(hi), hi - pad, np.inf))
        self.scale = np.maximum(np.abs(self.x0), 1e-3)

    def building_at(self, x: np.ndarray) -> Building:
        """The building with the adjusted parameters set to ``x``."""
        b = self.building
        fields = {n: np.array(getattr(b, n), dtype=float) for n in _LIMITS}
        ratio = b.damping.ratio
        for (name, i), v in zip(self.slots, x):
            if name == "damping":
                ratio = float(v)
            else:
                fields[name][i] = v
        return b.replace(**fields, damping=dataclasses.replace(b.damping, ratio=ratio))


class SearchVector(Protocol):
    """The parameters a search moves (:class:`ParameterVector`, or the prior units of
    :class:`hlaid.joint.vector.PriorVector`)."""

    slots: list
    x0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    scale: np.ndarray

    def building_at(self, x: np.ndarray) -> Building: ...


class Residuals(Protocol):
    """Buildings to residuals (:class:`~hlaid.identify.residuals.ReplayResiduals`, or the
    posterior's of :class:`hlaid.joint.vector.PosteriorResiduals`)."""

    substeps: int
    channels: int
    criterion: str

    def __call__(self, buildings: Sequence[Building], substeps: int | None = None
                 ) -> tuple[np.ndarray, np.ndarray]: ...


def fit_residuals(vector: SearchVector, residuals: Residuals, *, max_iterations: int = 40,
                  ftol: float = 1e-10, jac_substeps: int | None = None, t0: float | None = None,
                  desc: str = "[identify] replay fit", jacobian: str = "tangent") -> RefineResult:
    """Least squares of ``residuals`` over ``vector``'s parameters from its start (scipy's
    trust-region reflective search within the bounds). Its progress is one
    :func:`hlaid._progress.stage` named ``desc``, counted in evaluations of the cost (at most
    ``max_iterations``).

    Jacobians: one batch of replays with ``jac_substeps`` RK4 sub-steps (default the residuals'
    own) of the buildings at ``x`` and at ``x + h e_j`` (``h`` 1e-4 of each entry's scale),
    differenced. With ``jacobian="tangent"`` (default) the batch is run
    :func:`~hlaid.simulate.sensitivity.linearised`: the replay at ``x`` and its tangent-linear
    model in the direction of every other building (forward-mode sensitivities, a fraction of a
    replay each, through any linear post-processing of the replays: band-pass, whitening, the
    states carried from event to event), so the difference quotient is the derivative of the
    discrete replay along ``vector``'s map; ``"difference"``: full replays of every building,
    forward differences.

    BLAS runs on one thread where residuals x parameters^2 is below :data:`_BLAS_ONE_THREAD`
    (``residuals.n_residuals`` where it has one): the search's SVDs of a tall, narrow Jacobian
    gain nothing from a second thread and lost up to 10x to it when the compiled replays or other
    jobs held the cores (a joint fit's 48000 x 16 SVD: 47 ms on one thread, 0.63 s on two)."""
    if jacobian not in JACOBIANS:
        raise InputError(f"jacobian = {jacobian!r}; expected one of {', '.join(map(repr, JACOBIANS))}")
    n_res = getattr(residuals, "n_residuals", None)
    small = n_res is not None and int(n_res) * len(vector.x0) ** 2 < _BLAS_ONE_THREAD
    with blas_threads(1 if small else None):
        return _fit_residuals(vector, residuals, max_iterations=max_iterations, ftol=ftol, jac_substeps=jac_substeps,
                              t0=t0, tangent=jacobian == "tangent", desc=desc)


def _fit_residuals(vector: SearchVector, residuals: Residuals, *, max_iterations: int, ftol: float,
                   jac_substeps: int | None, t0: float | None, tangent: bool, desc: str) -> RefineResult:
    t0 = time.perf_counter() if t0 is None else t0
    make, xs, hi_b = vector.building_at, vector.scale, vector.upper
    jac_substeps = residuals.substeps if jac_substeps is None else jac_substeps
    cache: dict = {}
    plain_of: dict = {}  # the unweighted cost of every point the search evaluated (a float each)
    cost_of: dict = {}  # and its cost

    best, counting = [np.inf], [True]
    bar = _progress.stage(f"{desc} ({vector.x0.size} parameters)", max_iterations, unit="evaluations")

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            res, plain = residuals([make(x)])
            cache[key], plain_of[key], cost_of[key] = res[0], float(plain[0]), 0.5 * float(np.sum(res[0] ** 2))
            best[0] = min(best[0], cost_of[key])
            if counting[0]:
                bar.update(1, note=f"cost {best[0]:.4g}")
        return cache[key]

    def jac(x):
        _progress.debug(f"{desc}: Jacobian at cost {0.5 * float(np.sum(fun(x) ** 2)):.4g}")
        h = 1e-4 * xs
        xp = x + h
        over = xp > hi_b
        xp[over] = x[over] - h[over]
        trial = [make(np.where(np.arange(x.size) == j, xp, x)) for j in range(x.size)]
        if tangent:
            with linearised():
                both = residuals([make(x)] + trial, jac_substeps)[0]
            r0, rp = both[0], both[1:]
        elif jac_substeps == residuals.substeps:
            rp, r0 = residuals(trial)[0], fun(x)
        else:
            both = residuals([make(x)] + trial, jac_substeps)[0]
            r0, rp = both[0], both[1:]
        rp -= r0[None]  # in place: the batch is (n_params, n_residuals), 0.2 GB at 20 stories
        rp /= (xp - x)[:, None]
        return rp.T

    x0 = vector.x0
    with bar:
        sol = least_squares(fun, x0, jac=jac, bounds=(vector.lower, hi_b), x_scale=xs, method="trf",
                            max_nfev=max_iterations, xtol=1e-10, ftol=ftol, gtol=1e-10)
        counting[0], bar.n = False, int(sol.nfev)
        fun(sol.x)  # its plain cost (the last point evaluated may have been a rejected trial)
        plain = plain_of[sol.x.tobytes()]
        cost0 = cost_of.get(np.asarray(x0, dtype=float).tobytes())  # its first evaluation (not replayed again)
        cost0 = 0.5 * float(np.sum(fun(x0) ** 2)) if cost0 is None else cost0
        bar.done(f"cost {cost0:.4g} -> {float(sol.cost):.4g}" + ("" if sol.status > 0 else " (not converged)"))
    return RefineResult(building=make(sol.x), cost_initial=cost0, cost_final=float(sol.cost), nfev=int(sol.nfev),
                        seconds=time.perf_counter() - t0, message=str(sol.message), slots=tuple(vector.slots),
                        x=np.array(sol.x), jacobian=np.array(sol.jac), residuals=np.array(sol.fun),
                        channels=residuals.channels, plain_cost=plain, converged=bool(sol.status > 0),
                        criterion=residuals.criterion)
