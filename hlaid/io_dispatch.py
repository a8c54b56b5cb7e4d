"""Reading a measurement from any supported file (hlaid NPZ/CSV and the formats of :mod:`hlaid.io`)."""

from __future__ import annotations

import os

from .io import read_any
from .measurement import Measurement, warn_unusual_rate


def read_measurement_any(path: str | os.PathLike, format: str | None = None, **kwargs) -> Measurement:
    """Read a measurement in any format :func:`hlaid.io.read_any` knows (a warning when its sample
    rate is legal but unusual, see :data:`hlaid.measurement.RATE_USUAL_HZ`)."""
    meas = read_any(path, format=format, **kwargs)
    warn_unusual_rate(meas)
    return meas
