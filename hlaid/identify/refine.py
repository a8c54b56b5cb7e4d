"""Replay refinement: least squares of the replayed against the measured floor accelerations.

The regressions and classifiers of the paper give a building close to the truth; starting
there, a bounded Levenberg-Marquardt search over the story parameters matches the clone's
absolute floor accelerations to the measured ones (both band-passed alike). Accelerations
are compared because they carry white sensor noise only, not the integration errors of
displacements. Jacobians are finite differences computed as one batch of the simulator.
"""

from __future__ import annotations

import functools
import inspect
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import ParamSpec, TypeVar

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from .. import _progress
from ..errors import InputError
from ..measurement import Measurement, measured_ground
from ..model import Building, Damping
from ..signal import bandpass, cap_corner, lowpass
from ..simulate import simulate_response
from ..simulate.tangent import GroundTangent, ground_tangent
from .eiv import TangentWhitener, ground_transfer, lowpass_gain, whiten

_CHUNK = 8
"""Replays band-passed together in the refinement: filtering a whole Jacobian batch at once
(0.2 GB for 101 replays of a 20-story building) spent up to 4x longer allocating than filtering."""

_BLAS_ONE_THREAD = 1e8
"""Residuals x parameters^2 (the flops of the Jacobian's SVD) below which the refinement runs BLAS
on one thread: Table 1's 7e6, a 20-story building's 2e9."""

_P = ParamSpec("_P")
_R = TypeVar("_R")

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
    jacobian : d residuals / d x at the solution (the optimiser's last finite-difference
        Jacobian), shape ``(n_time * n_floors, n_params)``, rows time-major
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
        with threadpool_limits(limits=1 if small else None, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper


@_blas_threads
def refine_replay(building: Building, measurement: Measurement, *, parameters=("k0", "alpha", "p", "dy", "delta_eta"),
                  stories=None, damping: bool = False, band_hz=(0.1, 20.0), max_iterations: int = 40,
                  substeps: int = 4, upper_factor: float | None = 10.0, ftol: float = 1e-10,
                  jac_substeps: int | None = None, ground_noise: str = "ignore",
                  ground_memory_s: float | None = None, tangent_max_mb: float | None = None) -> RefineResult:
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
    jac_substeps : RK4 sub-steps of the replays that build the finite-difference Jacobian
        (default: ``substeps``). The Jacobian only steers the search; the residuals, and so the
        optimum, keep ``substeps``. Its base point is replayed with the same sub-steps as its
        columns, so the difference quotient carries no discretisation offset.
    ground_noise : ``"ignore"`` (least squares of the residuals); ``"whiten"``: the residuals
        whitened per frequency by their covariance with the measured ground's noise propagated
        through the linear building being evaluated (:mod:`hlaid.identify.eiv`; every channel's
        noise a common fraction of its RMS, as :func:`hlaid.synthetic.simulate_measurement`
        adds it). ``"tangent"``: whitened against the ground noise carried to the floors by the
        time-varying tangent of the replay of ``building`` (:func:`_tangent_whitener`), i.e.
        maximum likelihood with the true ground as a nuisance; the same noise model. The
        residuals are then low-passed only (``band_hz[0]`` is not used) and compared at every
        ``stride``-th sample, three samples per period of the upper corner (every third sample of
        a 200 Hz record low-passed at 20 Hz). ``cost_*`` and ``residuals`` are then of the
        whitened residuals, ``(samples / stride, floors + 1)``.
    ground_memory_s : with ``"tangent"``, seconds of the floors' response kept after each
        ground sample; None: :func:`ground_memory` of ``building``
    tangent_max_mb : with ``"tangent"``, raise :class:`~hlaid.errors.TangentTooLargeError` where the
        tangent would take more than this many MiB (None: only the hard limit)
    """
    t0 = time.perf_counter()
    dt = measurement.dt
    hi = cap_corner(band_hz[1], dt)
    if ground_noise == "tangent":  # its noise model has no high-pass (with one the optimum moved, docs)
        band_hz = (0.0, band_hz[1])
    ground = measured_ground(measurement, hi)
    target = bandpass(np.asarray(measurement.floor_acc), dt, (band_hz[0], hi))
    scale = np.sqrt(np.mean(target**2, axis=0))
    if ground_noise not in ("ignore", "whiten", "tangent"):
        raise InputError(f"ground_noise = {ground_noise!r}; expected 'ignore', 'whiten' or 'tangent'")
    transfer = _ground_noise_transfer(measurement, hi, scale) if ground_noise == "whiten" else None
    tangent, stride = None, 1
    if ground_noise == "tangent":
        _progress.info("[identify] tangent of the replay to the ground motion (errors in the input)")
        stride = max(int(1.0 / (3.0 * hi * dt)), 1)  # the low-passed residuals, sampled at 3x their corner
        memory = ground_memory(building) if ground_memory_s is None else ground_memory_s
        tangent = _tangent_whitener(building, measurement, ground, hi, scale, memory,  # a weighting:
                                    substeps if jac_substeps is None else jac_substeps, stride,  # 2 sub-steps do
                                    tangent_max_mb)
    channels = measurement.n_floors + (tangent is not None)
    stories = range(building.n_stories) if stories is None else stories
    slots = [(name, i) for i in range(building.n_stories) for name in parameters
             if i in stories or name == "k0"]
    x0 = np.array([getattr(building, name)[i] for name, i in slots], dtype=float)
    if damping:
        slots.append(("damping", -1))
        x0 = np.append(x0, building.damping.ratio)
    lo = np.array([_LIMITS[n][0] if n != "damping" else 0.0 for n, _ in slots])
    hi_b = np.array([_LIMITS[n][1] if n != "damping" else 0.5 for n, _ in slots])
    if upper_factor is not None:
        for j, (n, _) in enumerate(slots):
            if n in ("k0", "dy", "delta_eta"):
                hi_b[j] = upper_factor * (max(x0[j], 0.5) if n == "delta_eta" else x0[j])
    pad = 1e-6 * np.maximum(np.abs(x0), 1e-6)
    x0 = np.minimum(np.maximum(x0, lo + pad), np.where(np.isfinite(hi_b), hi_b - pad, np.inf))
    xs = np.maximum(np.abs(x0), 1e-3)

    def make(x):
        fields = {n: np.array(getattr(building, n), dtype=float) for n in _LIMITS}
        ratio = building.damping.ratio
        for (name, i), v in zip(slots, x):
            if name == "damping":
                ratio = float(v)
            else:
                fields[name][i] = v
        return building.replace(**fields, damping=Damping(kind=building.damping.kind, ratio=ratio,
                                                          modes=building.damping.modes))

    jac_substeps = substeps if jac_substeps is None else jac_substeps

    def residuals_of(bs, n_sub=substeps):
        r = simulate_response(bs, ground, substeps=n_sub, outputs="acc")
        acc = r.acc
        acc[r.status != 0] = 0.0  # only a stopped replay has NaN (after its stop); no copy of the rest
        res = np.empty((len(bs), len(range(0, acc.shape[1], stride)) * channels))
        plain = np.empty(len(bs))

        v = [] if transfer is None else transfer.of(bs)

        def chunk(i):  # a few replays at a time: the same values, without fresh large temporaries
            part = bandpass(acc[i:i + _CHUNK], dt, (band_hz[0], hi), axis=1)
            part -= target[None]
            part /= scale
            plain[i:i + _CHUNK] = 0.5 * np.sum(part.reshape(len(part), -1) ** 2, axis=1)
            if transfer is not None:
                for k in range(len(part)):
                    part[k] = whiten(part[k], v[i + k], transfer.floor_std)
            if tangent is not None:
                part = tangent(part[:, ::stride])
            res[i:i + _CHUNK] = part.reshape(len(part), -1)

        starts = range(0, len(bs), _CHUNK)
        if len(starts) == 1:
            chunk(0)
        else:  # scipy's filter releases the GIL: the chunks share the cores (disjoint rows of res)
            with ThreadPoolExecutor(min(len(starts), os.cpu_count() or 1)) as ex:
                list(ex.map(chunk, starts))
        res[r.status != 0] = 1e3  # a diverged trial is far from the data
        plain[r.status != 0] = np.inf
        return res, plain

    cache: dict = {}
    plain_of: dict = {}  # the unweighted cost of every point the search evaluated (a float each)

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            res, plain = residuals_of([make(x)])
            cache[key], plain_of[key] = res[0], float(plain[0])
        return cache[key]

    n_jac = [0]

    def jac(x):
        n_jac[0] += 1
        _progress.info(f"[identify] refinement step {n_jac[0]} (at most {max_iterations} evaluations): "
                       f"{x.size} parameters, cost {0.5 * float(np.sum(fun(x) ** 2)):.4g}")
        h = 1e-4 * xs
        xp = x + h
        over = xp > hi_b
        xp[over] = x[over] - h[over]
        trial = [make(np.where(np.arange(x.size) == j, xp, x)) for j in range(x.size)]
        if jac_substeps == substeps:
            rp, r0 = residuals_of(trial)[0], fun(x)
        else:
            both = residuals_of([make(x)] + trial, jac_substeps)[0]
            r0, rp = both[0], both[1:]
        rp -= r0[None]  # in place: the batch is (n_params, n_residuals), 0.2 GB at 20 stories
        rp /= (xp - x)[:, None]
        return rp.T

    sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi_b), x_scale=xs, method="trf",
                        max_nfev=max_iterations, xtol=1e-10, ftol=ftol, gtol=1e-10)
    fun(sol.x)  # its plain cost (the last point evaluated may have been a rejected trial)
    plain = plain_of[sol.x.tobytes()]
    cost0 = 0.5 * float(np.sum(fun(x0) ** 2))
    return RefineResult(building=make(sol.x), cost_initial=cost0, cost_final=float(sol.cost), nfev=int(sol.nfev),
                        seconds=time.perf_counter() - t0, message=str(sol.message), slots=tuple(slots),
                        x=np.array(sol.x), jacobian=np.array(sol.jac), residuals=np.array(sol.fun),
                        channels=channels, plain_cost=plain, converged=bool(sol.status > 0), criterion=ground_noise)


def ground_memory(building: Building, decays: float = 4.0, limits_s=(2.0, 10.0)) -> float:
    """Seconds of the floors' response to a ground sample that the tangent keeps by default:
    ``decays`` first-mode decay times ``T1 / (2 pi zeta)`` of the linear building (initial
    stiffness, its damping ratio), within ``limits_s``. Table 1 (T1 0.38 s, 5 %): 4.9 s, after
    which 0.2-0.6 % of the tangent's energy is left on its five records (yielding lengthens the
    tail); the tangent only weights the residuals, so a shorter memory costs efficiency, not
    consistency."""
    zeta = building.damping.ratio if building.damping.kind != "none" else 0.0
    t1 = float(building.periods()[0])
    tau = t1 / (2.0 * np.pi * zeta) if zeta > 0 else np.inf
    return float(np.clip(decays * tau, *limits_s))


def _tangent_whitener(building: Building, meas: Measurement, ground, hi_hz: float, scale: np.ndarray,
                      memory_s: float, substeps: int, stride: int, max_mb: float | None = None) -> TangentWhitener:
    """:class:`~hlaid.identify.eiv.TangentWhitener` of the refinement's residuals, low-passed at
    ``hi_hz`` and sampled every ``stride`` samples.

    The replay's ground is the measured one low-passed at ``hi_hz``, so a ground sensor's white
    noise reaches it through that low-pass: the tangent is taken for the low-pass's impulse
    response at every ``stride``-th sample (white noise of std ``s`` per sample is then
    ``sqrt(stride) s`` per perturbation), its floor responses low-passed, sampled and divided by
    ``scale`` like the residuals (the 0.1 Hz high-pass is left out: white noise has next to no
    power below it). The floor noise, white of std ``s`` per sample and low-passed, is white of
    std ``s / sqrt(stride)`` on the coarse grid within the band. Every channel's noise a common
    fraction of its RMS (the fraction cancels).
    """
    dt = meas.dt
    half = int(np.ceil(4.0 / (hi_hz * dt)))
    imp = np.zeros(8 * half + 1)
    imp[4 * half] = 1.0
    shape = lowpass(imp, dt, hi_hz)[2 * half:6 * half + 1]  # room before lag 0 for the output's low-pass
    lags = max(int(round(memory_s / (dt * stride))), 1)
    gt = ground_tangent(building, ground, lags=lags, shape=shape, substeps=substeps, stride=stride, lowpass_hz=hi_hz,
                        max_mb=max_mb)
    floor = np.asarray(meas.floor_acc)
    rms_f = np.sqrt(np.mean(floor**2, axis=0))
    rms_g = float(np.sqrt(np.mean(np.asarray(meas.ground_acc) ** 2)))
    resp = GroundTangent(response=gt.response / scale[None, None, :], lead=gt.lead, dt=gt.dt)
    return TangentWhitener(resp, rms_f / scale / np.sqrt(stride), rms_g * np.sqrt(stride))


class _GroundNoise:
    """The ground noise's spectrum relative to the floor noise, ``v(w)`` of
    :func:`hlaid.identify.eiv.whiten`, per building (cached on k0 and damping: the other
    parameters leave the linear building as it is).

    Attributes
    ----------
    gain : ``s_g L(w) / s_f`` per frequency and floor, shape ``(n_freq, n_floors)``
    freq : the ``rfft`` frequencies [Hz], shape ``(n_freq,)``
    floor_std : floor noise std in units of the normalised residuals (up to the common noise
        fraction), shape ``(n_floors,)``
    """

    def __init__(self, gain: np.ndarray, freq: np.ndarray, floor_std: np.ndarray):
        self.gain, self.freq, self.floor_std = gain, freq, floor_std
        self._cache: dict = {}

    def of(self, buildings) -> list[np.ndarray]:
        out = []
        for b in buildings:
            key = np.asarray(b.k0, dtype=float).tobytes() + repr(b.damping).encode()
            if key not in self._cache:
                if len(self._cache) > 64:
                    self._cache.clear()
                self._cache[key] = self.gain * ground_transfer(b, self.freq)
            out.append(self._cache[key])
        return out


def _ground_noise_transfer(meas: Measurement, hi_hz: float, scale: np.ndarray) -> _GroundNoise:
    """:class:`_GroundNoise` of ``meas``: every channel's noise std a common fraction of its RMS
    (the fraction cancels), the replay's ground low-passed at ``hi_hz``, residuals divided by ``scale``."""
    floor = np.asarray(meas.floor_acc)
    n, dt = floor.shape[0], meas.dt
    rms_f = np.sqrt(np.mean(floor**2, axis=0))
    rms_g = float(np.sqrt(np.mean(np.asarray(meas.ground_acc) ** 2)))
    gain = lowpass_gain(n, dt, hi_hz)[:, None] * (rms_g / rms_f)[None, :]
    return _GroundNoise(gain, np.fft.rfftfreq(n, dt), rms_f / scale)

