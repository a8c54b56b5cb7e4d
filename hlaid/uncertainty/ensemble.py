"""Ensembles of buildings from a clone's uncertainty."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model import Building
from .config import MAX_ENSEMBLE


def check_uncertain_clone(clone) -> None:
    """Refuse anything but a :class:`~hlaid.clone.Clone` that carries an uncertainty."""
    from ..clone import Clone

    if not isinstance(clone, Clone):
        raise InputError(f"expected an hlaid Clone (hlaid.load_clone(path)), got {type(clone).__name__}")
    if clone.uncertainty is None:
        raise InputError("this clone has no uncertainty (a version 1 file, or identified without the replay "
                         "refinement): identify it again with refine.method 'replay' to get one")


def check_ensemble_size(n, what: str = "n") -> int:
    """``n`` as an int, refused unless a whole number in 1..:data:`MAX_ENSEMBLE` (``what`` names it)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_ENSEMBLE:
        raise InputError(f"{what} = {n!r}; expected a whole number of ensemble members in 1..{MAX_ENSEMBLE}")
    return int(n)


def clone_ensemble(clone, n: int, *, seed: int = 0) -> list[Building]:
    """``n`` buildings drawn from ``clone.uncertainty`` (reproducible for a given ``seed``).

    Each member is the clone's building with its uncertain parameters replaced by one draw of
    the Gaussian in log-parameter space (clipped to the parameters' bounds); parameters
    without uncertainty keep their identified value. Members are named ``<name>#<j>``.

    Raises
    ------
    InputError : a clone without uncertainty, or ``n`` outside 1..100000
    """
    check_uncertain_clone(clone)
    n = check_ensemble_size(n)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed = {seed!r}; expected a whole number >= 0")
    u = clone.uncertainty
    X = u.sample(n, np.random.default_rng(int(seed)))
    b = clone.building
    base = b.name or "clone"
    return [u.apply(b, x).replace(name=f"{base}#{j}") for j, x in enumerate(X)]
