"""A building whose structural system is not known: a wide prior, no collapse law, no default
loss inventory (the user gives one)."""

from __future__ import annotations

from ..record import STORY_LAWS
from .parts import Median, StructuralPrior, StructuralSystem

NAME = "generic"

SYSTEM = StructuralSystem(
    name=NAME, title="unknown structural system", collapse=None, law=STORY_LAWS["degrading"],
    prior=StructuralPrior(
        name=NAME,
        cy=Median(median=0.3, beta=1.0), alpha=Median(median=0.1, beta=1.0), p=Median(median=2.0, beta=1.0),
        delta_eta=Median(median=0.3, beta=1.5), damping=Median(median=0.04, beta=0.7),
        sources=("the union of the steel and RC entries, widened",)),
)
