"""Identifiers by name, for the command line (``hlaid identify --method``) and the studies."""

from __future__ import annotations

from collections.abc import Callable

from ..errors import InputError
from ..estimators import BaseIdentifier, HLASVMIdentifier
from .gradient import GradientIdentifier
from .ukf import UKFIdentifier

IDENTIFIERS: dict[str, Callable[..., BaseIdentifier]] = {
    "hlasvm": lambda **kw: HLASVMIdentifier(refine="none", **kw),
    "hlasvm_replay": lambda **kw: HLASVMIdentifier(refine=None, **kw),
    "gradient": GradientIdentifier,
    "ukf": UKFIdentifier,
}
"""Identifiers by name: the paper's method alone (``hlasvm``), with the refinement its config
names (``hlasvm_replay``; the default config's: errors in variables), least squares through the
differentiable model (``gradient``) and the unscented Kalman filter (``ukf``). Each value makes an
unfitted identifier from keyword parameters."""


def get_identifier(name: str, **params) -> BaseIdentifier:
    """An unfitted identifier of :data:`IDENTIFIERS` with keyword ``params``.

    Raises
    ------
    InputError
        ``name`` is not in :data:`IDENTIFIERS` (the message lists the known names).
    """
    if name not in IDENTIFIERS:
        raise InputError(f"unknown identifier {name!r}; expected one of {list(IDENTIFIERS)}")
    return IDENTIFIERS[name](**params)
