"""The linear coupling of a building's floors beside its Bouc-Wen story springs.

A shear chain couples each floor only to the floors next to it, through the story between them:
its stiffness matrix is tridiagonal. A frame whose columns bend (a flexural, cantilever-like
part) also couples a floor to the floors two away. The coupling adds a linear floor force

    F = (shear-chain Bouc-Wen story forces) + K_c u

with ``u`` the floor displacements relative to the ground ``(floor,)`` [mm] and ``K_c`` a
symmetric positive semi-definite ``(floor, floor)`` matrix [N/mm]: per level ``j`` with a floor
above it (``j = 1 .. n-1``, floor 0 the ground) a flexural term ``kf_j b_j b_j^T``, ``b_j`` the
curvature ``u_{j-1} - 2 u_j + u_{j+1}`` of the displaced shape there. Each term is a rank-one
positive semi-definite matrix, so ``K_c`` is one for every ``kf >= 0``; with every ``kf`` zero (or
no coupling) the building is the shear chain it was, bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

KF_MAX = 1e12
"""Largest flexural coupling term [N/mm] a building may state (the bound of ``k0``)."""


def curvature_operator(n: int) -> np.ndarray:
    """``(n - 1, n)`` the rows ``b_j`` (curvature at level ``j = 1 .. n-1`` of floor displacements,
    the ground fixed at zero)."""
    B = np.zeros((max(n - 1, 0), n))
    for j in range(1, n):
        if j - 2 >= 0:
            B[j - 1, j - 2] = 1.0
        B[j - 1, j - 1] = -2.0
        B[j - 1, j] = 1.0
    return B


@dataclass(frozen=True)
class Coupling:
    """Flexural coupling terms ``kf`` [N/mm], one per level with a floor above it (``n - 1`` for
    ``n`` stories), each >= 0; see the module's doc."""

    flexural: tuple[float, ...]

    def __post_init__(self):
        try:
            kf = tuple(float(v) for v in self.flexural)
        except (TypeError, ValueError):
            raise InputError(f"coupling.flexural must be a list of numbers, got {self.flexural!r}") from None
        for j, v in enumerate(kf):
            if not 0.0 <= v <= KF_MAX:
                raise InputError(f"coupling.flexural[{j}] = {v!r}; expected a stiffness in 0..{KF_MAX:g} N/mm")
        object.__setattr__(self, "flexural", kf)

    @property
    def n_stories(self) -> int:
        return len(self.flexural) + 1

    @property
    def is_zero(self) -> bool:
        return not any(self.flexural)

    def matrix(self) -> np.ndarray:
        """``K_c`` ``(floor, floor)`` [N/mm], symmetric positive semi-definite."""
        B = curvature_operator(self.n_stories)
        return B.T @ (np.asarray(self.flexural)[:, None] * B)

    def to_dict(self) -> dict:
        return {"flexural": list(self.flexural)}

    @classmethod
    def from_dict(cls, d) -> Coupling:
        if not isinstance(d, Mapping) or set(d) != {"flexural"}:
            raise InputError("field 'coupling' must be a mapping with 'flexural': a list of stiffnesses [N/mm], "
                             "one per level with a floor above it")
        if not isinstance(d["flexural"], list):
            raise InputError("field 'coupling.flexural' must be a list of numbers")
        return cls(tuple(d["flexural"]))


def coupling_matrix(coupling: Coupling | None, n: int) -> np.ndarray:
    """``K_c`` of ``coupling`` for ``n`` stories (zeros where there is none)."""
    return np.zeros((n, n)) if coupling is None else coupling.matrix()


__all__ = ["KF_MAX", "Coupling", "coupling_matrix", "curvature_operator"]
