"""The ``assess:`` block of a run config: a schema that loads without torch or scipy."""

from __future__ import annotations

from dataclasses import dataclass

from ..bounds import SEED, bounded, check_bounds, with_bounds

MAX_ENSEMBLE = 100_000
"""Most clones an ensemble may hold."""

PLACARDS = {"green": "INSPECTED (re-occupancy permitted)", "yellow": "RESTRICTED USE (engineering evaluation)",
            "red": "UNSAFE (do not re-occupy)"}
"""The re-occupancy indicator's ATC-20 placard wording."""

N_ENSEMBLE = 20
"""Clones drawn from a clone's identification uncertainty wherever an ensemble is asked for and
its size is not given (assessment, prediction band, loss demands, fleet)."""


@dataclass(frozen=True, kw_only=True)
class AssessConfig:
    """The ``assess:`` block of a run config (``hlaid run``, ``hlaid demo``): :func:`hlaid.ida.assess`
    settings.

    n_ensemble : clones drawn from the identification uncertainty, each given a full IDA
    n_boot : record bootstrap resamples per member for the bands
    ci : level of the bands
    seed : seed of the ensemble and the bootstrap
    """

    n_ensemble: int = bounded(N_ENSEMBLE, lo=1, hi=MAX_ENSEMBLE)
    n_boot: int = bounded(30, lo=0, hi=10_000)
    ci: float = bounded(0.90, lo=0.01, hi=0.999)
    seed: int = with_bounds(SEED, 0)

    def __post_init__(self):
        check_bounds(self, prefix="assess.")


__all__ = ["AssessConfig", "MAX_ENSEMBLE", "N_ENSEMBLE", "PLACARDS"]
