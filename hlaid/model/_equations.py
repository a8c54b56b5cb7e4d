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


# ---------------------------------------------------------------------- collapse (strength loss)
# With a collapse model (hlaid.model.collapse) each story also carries the largest past drift in
# each direction, ``xp = max(x)`` and ``xn = max(-x)`` [mm] (>= 0). The Bouc-Wen force is scaled by
# a strength factor of that memory, per direction (peak-oriented): positive forces by the factor
# of ``xp``, negative ones by that of ``xn``. The factor makes the monotonic envelope the modified
# IMK backbone: Bouc-Wen up to the capping drift ``xc``, then a straight line of slope ``kpc`` (< 0)
# from the capping strength ``fc = (1-alpha) k0 dy + alpha k0 xc`` down to the residual ``fr``, which
# falls to zero with the same slope beyond the ultimate drift ``xu``. Nothing here but arithmetic
# and abs: ``max(a, b) = (a + b + |a - b|) / 2``.

def _pos(a):
    """``max(a, 0)``."""
    return 0.5 * (a + abs(a))


def strength_factor(xi, alpha, k0, dy, xc, kpc, fr, xu):
    """Strength factor in (0, 1] of a story whose largest past drift in one direction is ``xi`` [mm].

    ``B(xi) = max(fc + kpc (xi - xc)+, max(fr + kpc (xi - xu)+, 0))`` is the target backbone and
    ``alpha k0 xi + (1-alpha) k0 dy`` the yielded Bouc-Wen envelope it scales (at ``max(xi, xc)``, so
    that the factor is exactly 1 up to the cap).
    """
    qy = (1.0 - alpha) * k0 * dy
    ka = alpha * k0
    fc = qy + ka * xc
    b = fc + kpc * _pos(xi - xc)
    r = _pos(fr + kpc * _pos(xi - xu))
    b = 0.5 * (b + r + abs(b - r))
    d = xi - xc
    env = qy + ka * (xc + _pos(d))
    q = b / env
    return 0.5 * (q + 1.0 - abs(q - 1.0))


def collapse_force(fbw, rp, rn):
    """Story force [N] of the collapse law: the Bouc-Wen force ``fbw`` scaled by ``rp`` where it is
    positive and by ``rn`` where it is negative (continuous: both vanish with ``fbw``)."""
    pos = (fbw > 0.0) * 1.0
    return fbw * (pos * rp + (1.0 - pos) * rn)


def peak_rate(x, xd, xi):
    """``d xi/dt`` of the largest past drift ``xi`` in the direction of positive ``x`` (call with
    ``-x, -xd`` for the other direction): ``xd`` while ``x >= xi`` and moving outwards, else 0.
    Steppers also set ``xi = max(xi, x)`` after each step, which this rate makes exact."""
    return ((x - xi) >= 0.0) * _pos(xd)


def collapse_spring_force(x, z, xp, xn, alpha, k0, dy, xc, kpc, fr, xu):
    """Story force [N] with strength loss: ``spring_force`` scaled per direction by the strength
    factor of the largest drift so far, the current drift included (``max(xp, x)``, ``max(xn, -x)``)."""
    fbw = spring_force(x, z, alpha, k0)
    rp = strength_factor(xp + _pos(x - xp), alpha, k0, dy, xc, kpc, fr, xu)
    rn = strength_factor(xn + _pos(-x - xn), alpha, k0, dy, xc, kpc, fr, xu)
    return collapse_force(fbw, rp, rn)
