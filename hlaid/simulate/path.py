"""The story law driven along a given drift history (no building, no dynamics).

For a story whose drift ``x(t)`` is known (measured, or reconstructed), the hysteretic
displacement ``z`` and the work ``e = integral(z dx)`` follow from eq 3-10 alone: the same
compiled functions of :mod:`hlaid.model._equations` that the batch simulator uses, integrated
by RK4 along the path. This is how the identification generates its training half cycles:
every simulated half cycle has the measured half cycle's own path and differs only in the
story parameters.

Between two samples the path is the cubic Hermite interpolant of the drift and the drift
velocity when the velocity is given (what the batch simulator integrates, to RK4 accuracy),
else the straight line between the samples (for measured paths, whose velocity is noisier
than their drift increments).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..model import equations as eq
from ..model.collapse import N_COLLAPSE
from ._kernel import _FASTMATH, _degradation, _hysteretic_rate, _spring_force


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _rk4_step(z, e, d0, dm, d1, h, al, k0, m, p, dy, de):
    """One RK4 step of ``(z, e)`` with drift rates ``d0, dm, d1`` at the start, middle, end."""
    eta = _degradation(e, al, k0, m, de)
    k1 = _hysteretic_rate(d0, z, dy, p, eta)
    l1 = z * d0
    z2 = z + 0.5 * h * k1
    eta = _degradation(e + 0.5 * h * l1, al, k0, m, de)
    k2 = _hysteretic_rate(dm, z2, dy, p, eta)
    l2 = z2 * dm
    z3 = z + 0.5 * h * k2
    eta = _degradation(e + 0.5 * h * l2, al, k0, m, de)
    k3 = _hysteretic_rate(dm, z3, dy, p, eta)
    l3 = z3 * dm
    z4 = z + h * k3
    eta = _degradation(e + h * l3, al, k0, m, de)
    k4 = _hysteretic_rate(d1, z4, dy, p, eta)
    l4 = z4 * d1
    return z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), e + h / 6.0 * (l1 + 2.0 * l2 + 2.0 * l3 + l4)


@nb.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", inline="always")
def _hermite_rate(tau, x0, x1, v0, v1, dt):
    """Derivative of the cubic Hermite interpolant at ``tau`` in [0, 1] of a sample interval."""
    t2 = tau * tau
    return ((6.0 * t2 - 6.0 * tau) * (x0 - x1) / dt + (3.0 * t2 - 4.0 * tau + 1.0) * v0
            + (3.0 * t2 - 2.0 * tau) * v1)


@nb.njit(cache=True, parallel=True, fastmath=_FASTMATH, error_model="numpy")
def _drive(x, v, dt, hermite, k0, al, p, dy, de, m, nsub, state, force, z_out, e_out):
    """Integrate every parameter set ``b`` along path ``x[b % n_paths]``; see :func:`drive_story`.
    A sample whose step lets ``|z|`` overshoot ``dy`` is redone with up to 16x the sub-steps (as
    the batch simulator does); beyond that it takes the law's limit (elastic to ``|z| = dy``).
    ``z_out`` and ``e_out`` are written only with ``state`` (the force alone halves the memory
    traffic of a large batch)."""
    B = k0.shape[0]
    P, T = x.shape
    for b in nb.prange(B):
        xb = x[b % P]
        vb = v[b % P]
        z = 0.0
        e = 0.0
        force[b, 0] = _spring_force(xb[0], z, al[b], k0[b])
        if state:
            z_out[b, 0] = z
            e_out[b, 0] = e
        for k in range(T - 1):
            x0 = xb[k]
            x1 = xb[k + 1]
            ns = nsub
            while True:  # a step that lets |z| overshoot dy is redone with 2x, 4x, ... 16x the sub-steps
                zs = z
                es = e
                h = dt / ns
                for s in range(ns):
                    if hermite:
                        r0 = _hermite_rate((s + 0.0) / ns, x0, x1, vb[k], vb[k + 1], dt)
                        r1 = _hermite_rate((s + 0.5) / ns, x0, x1, vb[k], vb[k + 1], dt)
                        r2 = _hermite_rate((s + 1.0) / ns, x0, x1, vb[k], vb[k + 1], dt)
                        zs, es = _rk4_step(zs, es, r0, r1, r2, h, al[b], k0[b], m, p[b], dy[b], de[b])
                    else:
                        d = (x1 - x0) / dt
                        zs, es = _rk4_step(zs, es, d, d, d, h, al[b], k0[b], m, p[b], dy[b], de[b])
                if abs(zs) <= dy[b] * (1.0 + 1e-5) or ns >= 16 * nsub:
                    break
                ns *= 2
            if not abs(zs) <= dy[b] * (1.0 + 1e-5):
                # still over (a drift increment of many dy in one sample): the law's limit for such a
                # step, elastic to the yield surface and no further (|z| <= dy holds for the exact law)
                eta = _degradation(e, al[b], k0[b], m, de[b])
                zs = min(max(z + (x1 - x0) / eta, -dy[b]), dy[b])
                es = e + 0.5 * (z + zs) * (x1 - x0)
            z = zs
            e = es
            force[b, k + 1] = _spring_force(x1, z, al[b], k0[b])
            if state:
                z_out[b, k + 1] = z
                e_out[b, k + 1] = e


@dataclass(frozen=True, eq=False)
class PathResponse:
    """Response of the story law along a drift path; every field is ``(batch, time)``.

    Attributes
    ----------
    force : spring force ``alpha k0 x + (1-alpha) k0 z`` [N]
    z : hysteretic displacement [mm] (None when driven with ``state=False``)
    energy : ``e = integral(z dx)`` [mm^2] (None when driven with ``state=False``)
    """

    force: np.ndarray
    z: np.ndarray | None
    energy: np.ndarray | None

    def elastic_stiffness(self, k0, alpha, delta_eta, mass) -> np.ndarray:
        """``ke(t) = alpha k0 + (1-alpha) k0 / eta(t)`` (eq 11), ``(batch, time)`` [N/mm]."""
        if self.energy is None:
            raise ValueError("this response was driven with state=False; drive it with state=True for ke(t)")
        k0, alpha, delta_eta = (np.asarray(a, float).reshape(-1, 1) for a in (k0, alpha, delta_eta))
        eta = _degradation(self.energy, alpha, k0, mass, delta_eta)
        return alpha * k0 + (1.0 - alpha) * k0 / eta


def drive_story(drift: np.ndarray, *, k0, alpha, p, dy, delta_eta, mass: float, dt: float,
                velocity: np.ndarray | None = None, substeps: int = 4, state: bool = True,
                collapse=None) -> PathResponse:
    """Drive the degrading Bouc-Wen story law along drift paths, batched over parameters.

    Parameters
    ----------
    drift : ``(time,)`` or ``(path, time)`` drift [mm]; parameter set ``b`` follows path
        ``b % path`` (one path for all, one per parameter set, or any number that divides the
        parameter sets)
    k0, alpha, p, dy, delta_eta : scalars or ``(batch,)`` story parameters
    mass : floor mass above the story [t] (enters the degradation energy, eq 8)
    dt : sample interval [s]
    velocity : drift velocity [mm/s], the shape of ``drift``: cubic Hermite path between
        samples; None: straight lines between samples
    substeps : RK4 sub-steps per sample
    state : also return the ``z`` and ``energy`` histories (False: the force only)
    collapse : None (the paper's law), or ``(8,)`` / ``(batch, 8)`` collapse gap springs
        (:meth:`hlaid.model.Building.collapse_values`): the force is then the collapse law
        (:func:`hlaid.model._equations.collapse_spring_force`) with the largest drift of each
        direction taken over the path's samples (``z`` does not depend on it)

    Returns
    -------
    PathResponse with ``(batch, time)`` arrays; starts from rest (``z = e = 0``).
    """
    x = np.atleast_2d(np.ascontiguousarray(drift, dtype=np.float64))
    hermite = velocity is not None
    v = np.atleast_2d(np.ascontiguousarray(velocity, dtype=np.float64)) if hermite else np.zeros((1, 1))
    if hermite and v.shape != x.shape:
        raise ValueError(f"velocity has shape {v.shape}; expected the drift's {x.shape}")
    pars = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (k0, alpha, p, dy,
                                                                                          delta_eta)))
    B = max(pars[0].shape[0], x.shape[0])
    k0_, al_, p_, dy_, de_ = (np.ascontiguousarray(np.broadcast_to(a, (B,))) for a in pars)
    if B % x.shape[0]:
        raise ValueError(f"{x.shape[0]} paths for {B} parameter sets; expected a number that divides {B}")
    if substeps < 1:
        raise ValueError(f"substeps = {substeps}; expected >= 1")
    T = x.shape[1]
    force = np.empty((B, T))
    z, e = (np.empty((B, T) if state else (1, 1)) for _ in range(2))
    if collapse is not None and not state:
        z, e = (np.empty((B, T)) for _ in range(2))
    _drive(x, v if hermite else np.zeros_like(x), float(dt), hermite, k0_, al_, p_, dy_, de_, float(mass),
           int(substeps), bool(state or collapse is not None), force, z, e)
    if collapse is not None:
        c = np.broadcast_to(np.asarray(collapse, dtype=np.float64), (B, N_COLLAPSE))[:, :, None]
        xb = x[np.arange(B) % x.shape[0]]
        xp = np.maximum.accumulate(np.maximum(xb, 0.0), axis=1)
        xn = np.maximum.accumulate(np.maximum(-xb, 0.0), axis=1)
        force = eq.collapse_spring_force(xb, z, xp, xn, al_[:, None], k0_[:, None], *(c[:, j] for j in
                                                                                      range(N_COLLAPSE)))
    return PathResponse(force=force, z=z if state else None, energy=e if state else None)
