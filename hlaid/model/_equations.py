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
:data:`ENERGY_SCALE`; ``delta_eta`` is in s^2/m^2 (docs/DESIGN.md section 3).
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
# each direction, ``xp = max(x)`` and ``xn = max(-x)`` [mm] (>= 0), and its force gets up to four
# *gap springs* in parallel with the Bouc-Wen spring. Gap spring j changes the slope of the story's
# monotonic envelope by ``dk_j`` beyond the drift ``x_j``: its force is ``dk_j (x - h_j)``, with
# ``h_j`` the deformation of an elastic-perfectly-plastic gap element of unit stiffness yielding at
# ``x_j`` in each direction whose gap grows with the plastic deformation (OpenSees'
# ``ElasticPPGap ... damage``):
#
#     h_j = min((x - (xp - x_j)+)+, x_j) - min((-x - (xn - x_j)+)+, x_j)
#
# so ``x - h_j`` is 0 while |x| has never passed x_j, ``x - x_j`` on a first excursion beyond it,
# and after it a constant offset (the strength lost at the peak is kept) that closes only near zero
# drift. The four kinks of the modified-IMK backbone (cap, residual, ultimate, zero strength) are
# four such springs. Nothing here but arithmetic and abs: ``min(a, b) = (a + b - |a - b|) / 2``.

def _pos(a):
    """``max(a, 0)``."""
    return 0.5 * (a + abs(a))


def gap_offset(x, xp, xn, xj):
    """``x - h_j`` [mm] of a gap spring yielding at ``xj`` with memory ``xp``, ``xn`` (see above)."""
    a = _pos(x - _pos(xp - xj))
    b = _pos(-x - _pos(xn - xj))
    return x - 0.5 * (a + xj - abs(a - xj)) + 0.5 * (b + xj - abs(b - xj))


def gap_force(x, xp, xn, x1, d1, x2, d2, x3, d3, x4, d4):
    """Force of a story's four gap springs ``sum dk_j (x - h_j)`` [N] (kink drifts ``x1..x4`` [mm],
    slope changes ``d1..d4`` [N/mm]): what the collapse law adds to the Bouc-Wen force."""
    return (d1 * gap_offset(x, xp, xn, x1) + d2 * gap_offset(x, xp, xn, x2) + d3 * gap_offset(x, xp, xn, x3)
            + d4 * gap_offset(x, xp, xn, x4))


def collapse_spring_force(x, z, xp, xn, alpha, k0, x1, d1, x2, d2, x3, d3, x4, d4):
    """Story force [N] with strength loss: the Bouc-Wen force plus the gap springs. P-Delta excluded."""
    return spring_force(x, z, alpha, k0) + gap_force(x, xp, xn, x1, d1, x2, d2, x3, d3, x4, d4)


def peak_rate(x, xd, xi):
    """``d xi/dt`` of the largest past drift ``xi`` in the direction of positive ``x`` (call with
    ``-x, -xd`` for the other direction): ``xd`` while ``x >= xi`` and moving outwards, else 0.
    Steppers also set ``xi = max(xi, x)`` after each step, which this rate makes exact."""
    return ((x - xi) >= 0.0) * _pos(xd)
