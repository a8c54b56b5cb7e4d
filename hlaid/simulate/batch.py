"""GPU-free batch simulation of shear buildings under ground motions.

One call runs every combination of buildings x motions x scale factors (or zips them) with
fixed-step RK4 and a configurable number of sub-steps per record sample, the ground
acceleration linearly interpolated between samples. The default backend is compiled with
numba and runs batch elements in parallel; the ``"torch"`` backend steps the
:class:`~hlaid.model.BoucWenBuilding` module itself (slow, differentiable, the reference).
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from .. import _interrupt
from ..errors import InputError
from ..model import BoucWenBuilding, Building, BuildingTensors
from ..motions import GroundMotion
from . import _kernel, sensitivity

OUTPUTS = ("full", "acc", "peaks")
"""What :func:`simulate_response` keeps: every history, the floor accelerations only, or the peaks."""

HISTORY_FIELDS = ("disp", "vel", "acc", "drift", "force", "z", "eta", "energy")
"""Response histories of a full simulation, each ``(batch, time, story)``."""

STATUS = {_kernel.STATUS_OK: "ok", _kernel.STATUS_DRIFT_LIMIT: "drift limit", _kernel.STATUS_DIVERGED: "diverged"}


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Responses of a batch of simulations. Units N, mm, t, s.

    Histories are ``(batch, time, story)`` on each element's own sample grid
    (``k * dt[b]``), NaN after the element's last integrated sample; they are None when the
    simulation was run with ``outputs="peaks"``.

    Attributes
    ----------
    dt : (batch,) sample interval [s]
    n_time : (batch,) number of samples integrated (shorter if the element stopped)
    building_index, motion_index : (batch,) which building and motion each element ran
    scale : (batch,) scale factor applied to the motion
    status : (batch,) 0 ok, 1 stopped at the drift limit, 2 diverged (see :data:`STATUS`)
    peak_drift : (batch, story) peak absolute inter-story drift [mm]
    peak_acc : (batch, story) peak absolute floor acceleration [mm/s^2]
    residual_drift : (batch, story) drift at the last integrated sample [mm]
    final_state : (batch, 4*story) last state ``[u, v, z, e]``; ``(batch, 6*story)``
        ``[u, v, z, e, xp, xn]`` when a building has a collapse model (see BoucWenBuilding)
    disp, vel, acc, drift, force, z, eta, energy : (batch, time, story) histories: floor
        displacement relative to the ground, velocity, absolute acceleration, drift, Bouc-Wen
        spring force [N], hysteretic displacement, degradation, hysteretic work [N mm]
    """

    dt: np.ndarray
    n_time: np.ndarray
    building_index: np.ndarray
    motion_index: np.ndarray
    scale: np.ndarray
    status: np.ndarray
    peak_drift: np.ndarray
    peak_acc: np.ndarray
    residual_drift: np.ndarray
    final_state: np.ndarray
    disp: np.ndarray | None = None
    vel: np.ndarray | None = None
    acc: np.ndarray | None = None
    drift: np.ndarray | None = None
    force: np.ndarray | None = None
    z: np.ndarray | None = None
    eta: np.ndarray | None = None
    energy: np.ndarray | None = None

    @property
    def batch_size(self) -> int:
        return int(self.dt.shape[0])

    @property
    def time(self) -> np.ndarray:
        """Common sample times [s] ``(time,)``; only when every element has the same dt."""
        if not np.allclose(self.dt, self.dt[0]):
            raise ValueError("elements have different dt; use k * result.dt[b]")
        n = self.disp.shape[1] if self.disp is not None else int(self.n_time.max())
        return np.arange(n) * float(self.dt[0])


def _as_list(x, kind) -> list:
    if isinstance(x, kind):
        return [x]
    x = list(x)
    if not x or not all(isinstance(i, kind) for i in x):
        raise InputError(f"expected one or more {kind.__name__} objects")
    return x


def _layout(nb: int, nm: int, scales, pairing: str):
    """Indices (bi, mi, sc) of every batch element."""
    sc = np.asarray(scales, dtype=np.float64)
    if not np.all(np.isfinite(sc)):
        raise InputError("scale factors must be finite numbers")
    if pairing == "product":
        if sc.ndim <= 1:
            sc = np.broadcast_to(sc.reshape(-1), (nm, sc.size))
        elif sc.shape[0] != nm:
            raise InputError(f"scales of shape {sc.shape} need one row per motion ({nm})")
        ns = sc.shape[1]
        bi: np.ndarray
        mi: np.ndarray
        si: np.ndarray
        bi, mi, si = np.meshgrid(np.arange(nb), np.arange(nm), np.arange(ns), indexing="ij")
        bi, mi, si = bi.ravel(), mi.ravel(), si.ravel()
        return bi, mi, sc[mi, si]
    if pairing == "zip":
        sc = sc.reshape(-1)
        L = max(nb, nm, sc.size)
        for name, k in (("buildings", nb), ("motions", nm), ("scales", sc.size)):
            if k not in (1, L):
                raise InputError(f"pairing='zip' needs equal lengths (or 1); got {k} {name} for {L} elements")
        ar = np.arange(L)
        return (ar if nb > 1 else 0 * ar), (ar if nm > 1 else 0 * ar), np.broadcast_to(sc, (L,)).copy()
    raise InputError(f"unknown pairing {pairing!r}; expected 'product' or 'zip'")


def _stop_array(stop_drift, bi, n, nb) -> np.ndarray:
    if stop_drift is None:
        return np.full((bi.size, n), np.inf)
    s = np.asarray(stop_drift, dtype=np.float64)
    if s.ndim == 0:
        s = np.full((nb, n), float(s))
    elif s.ndim == 1:
        s = np.broadcast_to(s, (nb, n))
    if s.shape != (nb, n):
        raise InputError(f"stop_drift of shape {s.shape}; expected a number, (story,) or (building, story)")
    return np.ascontiguousarray(s[bi])


CHUNK_STEPS = 400_000
"""Story-steps (samples x sub-steps x stories) per thread in one call of the compiled kernel: a
call cannot be interrupted, so a large batch is run in chunks of about this much work (0.1-0.5 s
each), between which Ctrl-C and SIGTERM stop the run."""


def _chunks(steps: np.ndarray, per_sample: int) -> list[tuple[int, int]]:
    """``(start, stop)`` slices of the batch, each about :data:`CHUNK_STEPS` per numba thread of work
    (``steps`` samples of each element, ``per_sample`` story-steps per sample), at least one element."""
    import numba

    work = np.cumsum(np.maximum(np.asarray(steps, dtype=np.float64), 1.0) * max(per_sample, 1))
    budget = float(CHUNK_STEPS) * max(int(numba.get_num_threads()), 1)
    out, a = [], 0
    while a < work.size:
        base = work[a - 1] if a else 0.0
        b = max(int(np.searchsorted(work, base + budget, side="right")), a + 1)
        out.append((a, min(b, work.size)))
        a = b
    return out


def _run_numba(P: dict, ag, dt, nt, mi, bi, sc, nsub, y0, stop, outputs):
    B, n = bi.size, P["mass"].shape[1]
    S = y0.shape[1]
    T = int(nt.max())
    save, save_acc = outputs == "full", outputs == "acc"
    states = np.empty((B, T, S) if save else (0, 0, 0))
    acc = np.empty((B, T, n) if save_acc else (0, 0, 0))
    peak_drift, peak_acc = np.zeros((B, n)), np.zeros((B, n))
    final = np.zeros((B, S))
    n_done = np.zeros(B, dtype=np.int64)
    status = np.zeros(B, dtype=np.int64)
    kernel = _kernel.integrate_collapse if S == 6 * n else _kernel.integrate
    bw = _kernel.damping_bandwidth(P["damping"])
    cbw = _kernel.coupling_bandwidth(P["coupling"])
    for a, b in _chunks(nt[mi], int(nsub) * n):  # Ctrl-C and SIGTERM are honoured between chunks
        _interrupt.check()
        kernel(ag, dt, nt, mi[a:b], bi[a:b], sc[a:b], int(nsub), P["mass"], P["k0"], P["alpha"], P["p"], P["dy"],
               P["delta_eta"], P["kg"], P["damping"], bw, P["coupling"], cbw, P["collapse"], y0[a:b], stop[a:b],
               save, states[a:b] if save else states, save_acc, acc[a:b] if save_acc else acc, peak_drift[a:b],
               peak_acc[a:b], final[a:b], n_done[a:b], status[a:b])
    return (states if save else None), (acc if save_acc else None), peak_drift, peak_acc, final, n_done, status


def _run_torch(P: dict, ag, dt, nt, mi, bi, sc, nsub, y0, stop, outputs):
    """Eager torch RK4 over the module; the same arithmetic as the compiled kernel (always full states)."""
    if np.isfinite(stop).any():
        raise InputError("backend 'torch' does not stop at a drift limit; use backend='numba'")
    params = _tensors(P, y0.shape[1]).index(bi)
    model = BoucWenBuilding(params)
    g = torch.as_tensor(ag[mi] * sc[:, None])
    dt_b = torch.as_tensor(dt[mi])[:, None]
    y = torch.as_tensor(y0)
    T = int(nt.max())
    states: Any = torch.empty((bi.size, T, y.shape[1]), dtype=y.dtype)  # a tensor, then its array
    states[:, 0] = y
    with torch.no_grad():
        for k in range(T - 1):
            y = model.rk4_sample(y, g[:, k], g[:, k + 1], dt_b, nsub)
            states[:, k + 1] = y
    n_done = nt[mi].astype(np.int64)
    states = states.numpy()
    for b in range(bi.size):
        states[b, n_done[b]:] = np.nan
    final = states[np.arange(bi.size), n_done - 1]
    status = np.where(np.isfinite(final).all(axis=1), _kernel.STATUS_OK, _kernel.STATUS_DIVERGED)
    return states, None, None, None, final, n_done, status


def _tensors(P: dict, width: int) -> BuildingTensors:
    """The parameters as tensors; the collapse values only for a collapse-law (6*story) state, the
    coupling only where a building has one."""
    n = P["mass"].shape[1]
    skip = {k for k, keep in (("collapse", width == 6 * n), ("coupling", bool(np.any(P["coupling"])))) if not keep}
    return BuildingTensors(**{k: torch.as_tensor(v) for k, v in P.items() if k not in skip})


BACKENDS: dict[str, Callable] = {"numba": _run_numba, "torch": _run_torch}
"""Integrators by name: ``"numba"`` (compiled, parallel) and ``"torch"`` (eager reference)."""


_LAST_BATCH: list = []
"""The buildings (weak references) and parameter arrays of the last batch: a fit over several
events replays one batch of buildings under each event in turn, and their damping matrices (a
modal analysis each) were 4-10 % of its time."""


def _parameters(buildings: list[Building]) -> dict:
    """``BuildingTensors.stack(buildings).numpy()``, reused when the same building objects (frozen)
    come again in the same order."""
    if _LAST_BATCH:
        refs, P = _LAST_BATCH
        if len(refs) == len(buildings) and all(r() is b for r, b in zip(refs, buildings)):
            return P
    P = BuildingTensors.stack(buildings).numpy()
    _LAST_BATCH[:] = [[weakref.ref(b) for b in buildings], P]
    return P


def _ground(motions: list[GroundMotion]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The motions as the kernels take them: ``(motion, time)`` accelerations zero-padded to the
    longest, ``(motion,)`` time steps and ``(motion,)`` lengths."""
    ag = np.zeros((len(motions), max(m.npts for m in motions)))
    for j, m in enumerate(motions):
        ag[j, : m.npts] = m.acc
    return ag, np.array([m.dt for m in motions]), np.array([m.npts for m in motions], dtype=np.int64)


def _initial_states(y0, batch: int, S: int, n: int) -> np.ndarray:
    """``(batch, S)`` initial states: at rest where ``y0`` is None, else ``y0`` broadcast."""
    if y0 is None:
        return np.zeros((batch, S))
    try:  # a writable copy: a read-only view would make numba compile the kernel a second time
        return np.broadcast_to(np.asarray(y0, dtype=np.float64), (batch, S)).copy()
    except ValueError:
        raise InputError(f"y0 of shape {np.shape(y0)}; expected (batch, {S // n}*story) = ({batch}, {S}) "
                         f"or ({S},)") from None


def simulate_response(buildings: Building | Sequence[Building], motions: GroundMotion | Sequence[GroundMotion],
                      scales: float | Sequence[float] | np.ndarray = 1.0, *, substeps: int = 4,
                      pairing: str = "product", outputs: str = "full", backend: str = "numba",
                      free_vibration: float = 0.0, stop_drift: float | np.ndarray | None = None,
                      y0: np.ndarray | None = None) -> SimulationResult:
    """Simulate buildings under ground motions.

    Parameters
    ----------
    buildings : one or more :class:`~hlaid.model.Building` with the same number of stories
    motions : one or more :class:`~hlaid.motions.GroundMotion` (any dt and length)
    scales : scale factors applied to the motions: a number, ``(scale,)`` shared by every
        motion, or ``(motion, scale)`` one row per motion
    substeps : RK4 steps per record sample (the step is ``dt / substeps``)
    pairing : ``"product"``: every building x motion x scale, batch index
        ``((building * n_motions) + motion) * n_scales + scale``; ``"zip"``: element-wise
    outputs : ``"full"`` (every history), ``"acc"`` (the absolute floor accelerations only: what
        a replay against accelerometers needs, without the full state history) or ``"peaks"``
        (peaks and final state only, low memory)
    backend : a name in :data:`BACKENDS`
    free_vibration : seconds of zero ground motion appended to every record
    stop_drift : |drift| [mm] at which an element stops (status 1): a number, ``(story,)``
        or ``(building, story)``; None never stops
    y0 : (batch, 4*story) initial states (``6*story`` when a building has a collapse model);
        None starts at rest

    Within :func:`hlaid.simulate.sensitivity.linearised`, a batch of ``outputs="acc"`` under one
    motion is the first building's replay and every other element's first-order (tangent-linear)
    response about it, unless that replay needs a refined sample; see that module.

    Returns
    -------
    SimulationResult
    """
    buildings = _as_list(buildings, Building)
    motions = _as_list(motions, GroundMotion)
    if backend not in BACKENDS:
        raise InputError(f"unknown backend {backend!r}; expected one of {sorted(BACKENDS)}")
    if outputs not in OUTPUTS:
        raise InputError(f"outputs = {outputs!r}; expected one of {', '.join(map(repr, OUTPUTS))}")
    if int(substeps) < 1:
        raise InputError(f"substeps = {substeps}; expected an integer >= 1")
    if free_vibration > 0:
        motions = [m.padded(free_vibration) for m in motions]
    P = _parameters(buildings)
    n = P["mass"].shape[1]
    S = (6 if any(b.collapse is not None for b in buildings) else 4) * n
    bi, mi, sc = _layout(len(buildings), len(motions), scales, pairing)
    ag, dt, nt = _ground(motions)
    y0 = _initial_states(y0, bi.size, S, n)
    stop = _stop_array(stop_drift, bi, n, len(buildings))
    linear = (outputs == "acc" and backend == "numba" and sensitivity.is_linearised()
              and sensitivity.covers(P, len(motions), sc, bi, stop, S))
    if linear:  # a replay and its tangent, unless the replay needs a refined sample
        acc, final, peak_drift, peak_acc, n_done, status = sensitivity.run_linearised(P, ag[0] * sc[0], dt[0],
                                                                                     int(substeps), y0)
        states = None
        linear = status[0] != sensitivity.STATUS_REFINED
    if not linear:
        states, acc, peak_drift, peak_acc, final, n_done, status = BACKENDS[backend](
            P, ag, dt, nt, mi.astype(np.int64), bi.astype(np.int64), sc, int(substeps), y0, stop, outputs)
    params = _tensors(P, S).index(bi)
    res = result_from_states(params, states, dt=dt[mi], n_time=n_done, building_index=bi, motion_index=mi,
                             scale=sc, status=status, final_state=final, peak_drift=peak_drift,
                             peak_acc=peak_acc, keep_histories=outputs != "peaks")
    if outputs == "acc":  # only the accelerations: the compiled kernel wrote them, the torch backend has all
        changes: dict[str, Any] = {**dict.fromkeys(HISTORY_FIELDS), "acc": res.acc if acc is None else acc}
        res = dataclasses.replace(res, **changes)
    return res


def result_from_states(params: BuildingTensors, states: np.ndarray | None, *, final_state: np.ndarray,
                       keep_histories: bool = True, peak_drift=None, peak_acc=None, **fields) -> SimulationResult:
    """Assemble a :class:`SimulationResult`; histories come from the module's ``responses``.

    ``states`` is ``(batch, time, 4*story)`` (NaN after each element's end) or None; missing
    peaks are taken from the histories.
    """
    hist = {}
    if states is not None:
        with torch.no_grad():
            hist = {k: v.numpy() for k, v in BoucWenBuilding(params).responses(torch.as_tensor(states)).items()}
        if peak_drift is None:
            peak_drift = np.nanmax(np.abs(hist["drift"]), axis=1)
            peak_acc = np.nanmax(np.abs(hist["acc"]), axis=1)
    n = params.mass.shape[-1]
    u = final_state[:, :n]
    residual = u - np.pad(u, ((0, 0), (1, 0)))[:, :-1]
    if not keep_histories:
        hist = {}
    return SimulationResult(peak_drift=peak_drift, peak_acc=peak_acc, residual_drift=residual,
                            final_state=final_state, **fields, **hist)
