"""Shear-building matrices and damping, in torch so they are batched and differentiable.

Shapes are batch-first: per-story quantities ``(batch, story)``, matrices
``(batch, story, story)``. Story ``i`` joins floor ``i-1`` (floor 0 is the ground) to
floor ``i``; the mass of floor ``i`` sits at the top of story ``i``.
"""

from __future__ import annotations

from collections.abc import Callable

import torch


def stiffness_matrix(k: torch.Tensor) -> torch.Tensor:
    """Tridiagonal stiffness matrix of a shear building.

    Parameters
    ----------
    k : (batch, story) story stiffnesses [N/mm]

    Returns
    -------
    (batch, story, story) [N/mm]
    """
    k_above = torch.nn.functional.pad(k[..., 1:], (0, 1))
    K = torch.diag_embed(k + k_above)
    off = -k[..., 1:]
    return K + torch.diag_embed(off, 1) + torch.diag_embed(off, -1)


def natural_frequencies(k: torch.Tensor, mass: torch.Tensor) -> torch.Tensor:
    """Circular natural frequencies [rad/s], ascending, ``(batch, story)``."""
    s = mass.rsqrt()
    A = stiffness_matrix(k) * s[..., :, None] * s[..., None, :]
    lam = torch.linalg.eigvalsh(A)
    return lam.clamp_min(0.0).sqrt()


def _rayleigh(k, mass, ratio, modes, ratio2=None):
    w = natural_frequencies(k, mass)
    n = w.shape[-1]
    i, j = (min(m, n) - 1 for m in modes)
    wi, wj = w[..., i], w[..., j]
    if ratio2 is None or i == j:
        a0 = 2.0 * ratio * wi * wj / (wi + wj)
        a1 = 2.0 * ratio / (wi + wj)
        return a0, a1
    # zeta(w) = a0 / (2 w) + a1 w / 2 through (wi, ratio) and (wj, ratio2)
    d = wj * wj - wi * wi
    a0 = 2.0 * wi * wj * (ratio * wj - ratio2 * wi) / d
    a1 = 2.0 * (ratio2 * wj - ratio * wi) / d
    return a0, a1


def _stiffness_proportional(k, mass, ratio, modes, ratio2=None):
    w1 = natural_frequencies(k, mass)[..., min(modes[0], k.shape[-1]) - 1]
    return torch.zeros_like(w1), 2.0 * ratio / w1


def _mass_proportional(k, mass, ratio, modes, ratio2=None):
    w1 = natural_frequencies(k, mass)[..., min(modes[0], k.shape[-1]) - 1]
    return 2.0 * ratio * w1, torch.zeros_like(w1)


def _no_damping(k, mass, ratio, modes, ratio2=None):
    z = torch.zeros(k.shape[:-1], dtype=k.dtype, device=k.device)
    return z, z


DAMPING_KINDS: dict[str, Callable] = {
    "rayleigh": _rayleigh,
    "stiffness": _stiffness_proportional,
    "mass": _mass_proportional,
    "none": _no_damping,
}
"""Named damping models -> function returning Rayleigh coefficients ``(a0, a1)``, each ``(batch,)``."""


def rayleigh_coefficients(k0, mass, kind="rayleigh", ratio=0.05, modes=(1, 2), ratio2=None):
    """Coefficients ``(a0, a1)`` of ``C = a0 M + a1 K0`` for a named damping model.

    ``K0`` is the initial (elastic) spring stiffness matrix; geometric (P-Delta) stiffness is
    not included. A building with fewer stories than a named mode uses its highest mode.
    ``ratio2`` (``rayleigh``): the ratio of the second mode named, independent of ``ratio``
    (None: ``ratio``). A ratio2 far above ratio can make ``a0`` negative: the Rayleigh curve
    then dips below zero between the modes only where they are far apart (not checked here).
    """
    try:
        fn = DAMPING_KINDS[kind]
    except KeyError:
        raise ValueError(f"unknown damping kind {kind!r}; expected one of {sorted(DAMPING_KINDS)}") from None
    return fn(k0, mass, ratio, modes, ratio2)


def damping_matrix(k0, mass, a0, a1):
    """``C = a0 M + a1 K0``, ``(batch, story, story)`` [N s/mm]."""
    return a0[..., None, None] * torch.diag_embed(mass) + a1[..., None, None] * stiffness_matrix(k0)



