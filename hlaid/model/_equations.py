"""The degrading Bouc-Wen story law of the paper (eq 3-10), written once.

These functions use nothing but arithmetic operators and ``abs``, so the *same source*
runs on torch tensors (inside :class:`~hlaid.model.BoucWenBuilding`, differentiable) and
on floats compiled by numba (inside the batch simulator). There is no other copy of the
hysteretic equations in hlaid.

Per story, with drift ``x`` [mm], drift velocity ``dx`` [mm/s], hysteretic displacement
``z`` [mm] and ``e = integral(z dx)`` [mm^2]:

    f   = alpha*k0*x + (1-alpha)*k0*z                                   (eq 3)
    dz  = dx * (1 - 0.5*(sign(dx*z) + 1)*|z/dy|^p) / eta                (eq 10, A=1, beta=gamma)
    eta = 1 + delta_eta * eps,  eps = (1-alpha)*(k0/m)*e  in SI           (eq 7-8)

``k0/m`` in N/mm/t equals k0/m in s^-2, and ``e`` in mm^2 is 1e-6 m^2, hence the factor
:data:`ENERGY_SCALE`; ``delta_eta`` is in s^2/m^2 (DESIGN.md section 3).
"""

from __future__ import annotations

ENERGY_SCALE = 1e-6
"""Converts ``e = integral(z dx)`` from mm^2 to m^2 in the degradation energy ``eps``."""


def degradation(e, alpha, k0, mass, delta_eta):
    """Stiffness degradation ``eta = 1 + delta_eta * eps`` (eq 7-8), dimensionless."""
    return 1.0 + delta_eta * (ENERGY_SCALE * (1.0 - alpha) * (k0 / mass) * e)


def hysteretic_rate(dx, z, dy, p, eta):
    """``dz/dt`` of eq 10: smooth loading to ``|z| = dy``, linear unloading (``dx*z < 0``).

    ``loading = 0.5 (sign(dx z) + 1)`` is 0 or 1 wherever ``dx z != 0`` (and where it is 0 the
    rate is 0 whatever the bracket), so ``loading |z/dy|^p`` is written ``(loading |z/dy|)^p``:
    the same value, but the power of 0 on unloading costs the compiled simulator far less.
    """
    s = dx * z
    loading = 0.5 * ((s > 0.0) * 1.0 - (s < 0.0) * 1.0 + 1.0)
    return dx * (1.0 - (loading * abs(z / dy)) ** p) / eta


def spring_force(x, z, alpha, k0):
    """Story restoring force ``f = alpha k0 x + (1-alpha) k0 z`` [N] (eq 3)."""
    return alpha * k0 * x + (1.0 - alpha) * k0 * z


def elastic_stiffness(eta, alpha, k0):
    """Unloading (elastic) stiffness ``ke = alpha k0 + (1-alpha) k0 / eta`` [N/mm] (eq 11)."""
    return alpha * k0 + (1.0 - alpha) * k0 / eta
