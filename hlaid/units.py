"""Units used inside hlaid and the conversions applied at the I/O boundary.

Inside the package every quantity is in the consistent system **N, mm, t (tonne), s**:
1 t * 1 mm/s^2 = 1 N, stiffness in N/mm, displacement in mm, acceleration in mm/s^2.
Files in g, m/s^2, cm/s^2, inches or kN are converted where they are read or written,
nowhere else.
"""

from __future__ import annotations

G_MM_S2 = 9806.65
"""Standard gravity [mm/s^2]."""

G_M_S2 = 9.80665
"""Standard gravity [m/s^2]."""

INCH_MM = 25.4
"""One inch [mm]."""

KN_N = 1000.0
"""One kilonewton [N]."""

# Factor that converts an acceleration in the named unit to mm/s^2.
ACCELERATION_UNITS: dict[str, float] = {
    "g": G_MM_S2,
    "m/s^2": 1000.0,
    "m/s2": 1000.0,
    "cm/s^2": 10.0,
    "cm/s2": 10.0,
    "gal": 10.0,
    "mm/s^2": 1.0,
    "mm/s2": 1.0,
    "in/s^2": INCH_MM,
    "in/s2": INCH_MM,
}

# Factor that converts a length in the named unit to mm.
LENGTH_UNITS: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": INCH_MM, "ft": 12 * INCH_MM}

UNITS_JSON = {"force": "N", "length": "mm", "mass": "t", "time": "s",
              "stiffness": "N/mm", "acceleration": "mm/s^2", "energy": "N*mm",
              "delta_eta": "s^2/m^2"}
"""The unit block written into every hlaid JSON file."""


def _lookup(table: dict[str, float], unit: str, what: str) -> float:
    key = unit.strip().lower().replace(" ", "")
    if key not in table:
        raise ValueError(f"unknown {what} unit {unit!r}; expected one of {sorted(set(table))}")
    return table[key]


def acceleration_factor(unit: str) -> float:
    """Factor converting an acceleration in ``unit`` to mm/s^2.

    >>> acceleration_factor("g")
    9806.65
    """
    return _lookup(ACCELERATION_UNITS, unit, "acceleration")


def check_units(unit: str | None, field: str) -> None:
    """Refuse acceleration units (the setting ``field``) that are not in :data:`ACCELERATION_UNITS`
    (None: the file states its own)."""
    if unit is None:
        return
    from .errors import InputError

    if not isinstance(unit, str) or unit.strip().lower().replace(" ", "") not in ACCELERATION_UNITS:
        shown = repr(unit) if isinstance(unit, str) and len(unit) <= 20 and unit.isprintable() else "that"
        raise InputError(f"{field} = {shown} is no acceleration unit; expected one of "
                         f"{', '.join(sorted(ACCELERATION_UNITS))}")


def length_factor(unit: str) -> float:
    """Factor converting a length in ``unit`` to mm."""
    return _lookup(LENGTH_UNITS, unit, "length")


def kn_to_n(force_kn):
    """Force [kN] to [N]; a number or an array."""
    return force_kn * KN_N


def n_to_kn(force_n):
    """Force [N] to [kN]; a number or an array."""
    return force_n / KN_N


def weight_kn_to_mass_t(weight_kn: float) -> float:
    """Floor weight [kN] to mass [t] with standard gravity (171.85 kN -> 17.524 t)."""
    return kn_to_n(weight_kn) / G_MM_S2
