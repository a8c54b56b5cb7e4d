"""Ground-motion intensity measures (IM) for IDA, by name.

Every IM is a number per record, reported in g, proportional to the record's scale factor
(so a record is brought to an IM level by one multiplication).

``sa_t1``
    Sa(T1, 5%): the 5 %-damped pseudo-spectral acceleration at the building's first
    elastic period (initial stiffness K0, without P-Delta: :meth:`Building.periods`), from
    hlaid's own exact response spectrum (:func:`response_spectrum`).
``pga``
    Peak ground acceleration.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model import Building
from ..motions import GroundMotion
from ..units import G_MM_S2
from ._spectrum import response_spectrum

__all__ = ["INTENSITY_MEASURES", "IntensityMeasure", "get_intensity_measure", "intensity", "record_intensities",
           "response_spectrum"]


@dataclass(frozen=True)
class IntensityMeasure:
    """A named intensity measure.

    Attributes
    ----------
    name : registry key (``"sa_t1"``, ``"pga"``)
    label : axis label, e.g. ``"Sa(T1, 5%)"``
    needs_period : whether the IM depends on the building's period
    compute : ``compute(motions, period [s], damping) -> (record,)`` IM [mm/s^2]
    """

    name: str
    label: str
    needs_period: bool
    compute: Callable[[list[GroundMotion], float, float], np.ndarray]

    units: str = "g"


def _sa(motions, period, damping):
    return response_spectrum(motions, [period], damping)[:, 0]


def _pga(motions, period, damping):
    return np.array([m.pga for m in motions])


INTENSITY_MEASURES: dict[str, IntensityMeasure] = {
    "sa_t1": IntensityMeasure("sa_t1", "Sa(T1, 5%)", True, _sa),
    "pga": IntensityMeasure("pga", "PGA", False, _pga),
}
"""Intensity measures by name."""


def get_intensity_measure(name: str) -> IntensityMeasure:
    """The intensity measure called ``name``; an unknown name lists the valid ones."""
    try:
        return INTENSITY_MEASURES[name]
    except KeyError:
        raise InputError(f"unknown intensity measure {name!r}; expected one of "
                         f"{', '.join(sorted(INTENSITY_MEASURES))}") from None


def intensity(motions: GroundMotion | Sequence[GroundMotion], im: str = "sa_t1", *,
              building: Building | None = None, period: float | None = None,
              damping: float = 0.05) -> np.ndarray:
    """Intensity of each record [g].

    Parameters
    ----------
    motions : records [mm/s^2]
    im : a name in :data:`INTENSITY_MEASURES`
    building : gives the period T1 for ``sa_t1`` (its first elastic period)
    period : the period [s] to use instead of the building's
    damping : damping ratio of the spectrum (5 % by definition of Sa(T1, 5%))

    Returns
    -------
    (record,) intensity [g]
    """
    m = get_intensity_measure(im)
    motions = [motions] if isinstance(motions, GroundMotion) else list(motions)
    T = period_for(m, building, period)
    return m.compute(motions, T, damping) / G_MM_S2


def period_for(m: IntensityMeasure, building: Building | None, period: float | None) -> float:
    """The period [s] an IM is evaluated at (nan when it needs none)."""
    if not m.needs_period:
        return float("nan")
    if period is not None:
        if not (np.isfinite(period) and period > 0):
            raise InputError(f"period = {period}; expected a positive period [s]")
        return float(period)
    if building is None:
        raise InputError(f"intensity measure {m.name!r} needs a building (for T1) or a period")
    return float(building.periods()[0])


def record_intensities(motions: list[GroundMotion], im: str, building: Building,
                       period: float | None = None) -> tuple[IntensityMeasure, float, np.ndarray]:
    """``(measure, period [s], (record,) IM [g])`` of records for ``building`` (its T1 unless
    ``period``); a record of zero intensity (it could not be scaled) is an InputError naming it."""
    measure = get_intensity_measure(im)
    T = period_for(measure, building, period)
    im0 = measure.compute(motions, T, 0.05) / G_MM_S2
    if np.any(~(im0 > 0)):
        bad = [m.name for m, v in zip(motions, im0) if not v > 0]
        raise InputError(f"record(s) with zero {measure.label}: {', '.join(bad)}")
    return measure, T, im0
