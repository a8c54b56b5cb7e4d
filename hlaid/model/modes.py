"""The modes of a clone an engineer can check: frequency, damping ratio and shape of each mode of
its linear system at small amplitude, beside the records' own modes, with flags where either is
not a building's.

A clone's linear system at small amplitude is its initial one: every Bouc-Wen story at its
initial stiffness ``k0`` (``z`` follows ``x`` while ``|z| << dy``), less the P-Delta stiffness
where it is active, plus the linear coupling stiffness where the building has one
(:meth:`hlaid.model.Building.linear_stiffness`), with the building's damping matrix ``C``. Per
undamped mode ``phi`` (``K phi = w^2 M phi``) the damping ratio is ``phi^T C phi / (2 w phi^T M
phi)``: exact for classical damping (Rayleigh or per-mode damping built from these modes).

Light: numpy and scipy only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

FREQUENCY_TOLERANCE = 0.10
"""A clone mode whose frequency is more than this fraction off the records' mode of the same
number is flagged: the clone does not vibrate as the building does."""


@dataclass(frozen=True)
class Mode:
    """One mode: ``frequency_hz`` [Hz], viscous ``damping_ratio`` (0.05 is 5 %) and ``shape``
    ``(floor,)`` bottom to top, scaled to 1 at the roof (the floor of largest amplitude where the
    roof is a node)."""

    frequency_hz: float
    damping_ratio: float
    shape: tuple[float, ...]

    def to_dict(self) -> dict:
        return {"frequency_hz": float(self.frequency_hz), "damping_ratio": float(self.damping_ratio),
                "shape": [float(v) for v in self.shape]}

    @classmethod
    def from_dict(cls, d: Mapping, where: str = "mode") -> Mode:
        if not isinstance(d, Mapping) or set(d) != {"frequency_hz", "damping_ratio", "shape"}:
            raise InputError(f"field '{where}' must be a mapping of frequency_hz, damping_ratio and shape")
        f, z, s = d["frequency_hz"], d["damping_ratio"], d["shape"]
        if not (_finite(f) and f > 0 and _finite(z) and z >= 0 and isinstance(s, list) and s
                and all(_finite(v) for v in s)):
            raise InputError(f"field '{where}' must hold a frequency_hz > 0, a damping_ratio >= 0 and a shape "
                             "list of finite numbers")
        return cls(float(f), float(z), tuple(float(v) for v in s))


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def unit_roof(shape: np.ndarray) -> np.ndarray:
    """``shape`` scaled to 1 at the roof (at its largest entry where the roof hardly moves)."""
    s = np.asarray(shape, dtype=float)
    ref = s[-1] if abs(s[-1]) > 0.05 * np.max(np.abs(s)) else s[int(np.argmax(np.abs(s)))]
    return s / ref


def modes_of(K: np.ndarray, M: np.ndarray, C: np.ndarray) -> tuple[Mode, ...]:
    """The modes of the linear system ``M u'' + C u' + K u = 0``, lowest first.

    Parameters
    ----------
    K, M, C : (floor, floor) stiffness [N/mm], mass [t] and damping [N s/mm] matrices (K, M
        symmetric, M positive definite)
    """
    import scipy.linalg

    lam, phi = scipy.linalg.eigh(np.asarray(K, dtype=float), np.asarray(M, dtype=float))
    out = []
    for j in range(lam.size):
        w = float(np.sqrt(max(lam[j], 0.0)))
        v = phi[:, j]
        zeta = float(v @ C @ v / (2.0 * w * (v @ M @ v))) if w > 0 else float("inf")
        out.append(Mode(w / (2.0 * np.pi), zeta, tuple(float(x) for x in unit_roof(v))))
    return tuple(out)


def clone_modes(building) -> tuple[Mode, ...]:
    """The modes of ``building``'s linear system at small amplitude (see the module's doc)."""
    K = building.linear_stiffness() if hasattr(building, "linear_stiffness") else building.stiffness_matrix(pdelta=True)
    return modes_of(K, np.diag(np.asarray(building.mass, dtype=float)), building.damping_matrix())


@dataclass(frozen=True)
class ModalCheck:
    """The clone's modes beside the records' own, and what an engineer should look at.

    Attributes
    ----------
    clone : the clone's modes at small amplitude (:func:`clone_modes`), lowest first
    records : the records' identified modes (of their lowest-amplitude record), or () where none
        were identified
    damping_max : the largest damping ratio the structural system makes plausible
    system : the system named for ``damping_max`` (``"generic"`` where none was)
    """

    clone: tuple[Mode, ...]
    records: tuple[Mode, ...] = ()
    damping_max: float = 0.2
    system: str = "generic"

    def flags(self) -> list[str]:
        """Plain sentences: a clone mode damped beyond :attr:`damping_max`, a clone mode more than
        :data:`FREQUENCY_TOLERANCE` off the records' mode of the same number."""
        out = []
        high = [f"mode {j + 1} {100 * m.damping_ratio:.1f} %" for j, m in enumerate(self.clone)
                if not m.damping_ratio <= self.damping_max]
        if high:
            out.append(f"implausible modal damping: {', '.join(high)} (a {self.system} is damped at most about "
                       f"{100 * self.damping_max:g} %): the clone damps away a mode the building keeps")
        off = [f"mode {j + 1} {c.frequency_hz:.2f} Hz against the records' {r.frequency_hz:.2f} Hz "
               f"({100 * (c.frequency_hz / r.frequency_hz - 1):+.0f} %)" for j, (c, r) in enumerate(zip(self.clone,
                                                                                                    self.records))
               if not abs(c.frequency_hz / r.frequency_hz - 1) <= FREQUENCY_TOLERANCE]
        if off:
            out.append(f"clone modes more than {100 * FREQUENCY_TOLERANCE:g} % off the records': {'; '.join(off)}")
        return out

    def lines(self) -> list[str]:
        """One line per mode: the clone's frequency, damping and shape, and the records' beside."""
        out = []
        for j, m in enumerate(self.clone):
            line = (f"mode {j + 1}: {m.frequency_hz:.2f} Hz, damping {100 * m.damping_ratio:.1f} %, shape ("
                    + ", ".join(f"{v:.2f}" for v in m.shape) + ")")
            if j < len(self.records):
                r = self.records[j]
                line += (f"; records: {r.frequency_hz:.2f} Hz, {100 * r.damping_ratio:.1f} %, ("
                         + ", ".join(f"{v:.2f}" for v in r.shape) + ")")
            out.append(line)
        return out

    def to_dict(self) -> dict:
        return {"clone": [m.to_dict() for m in self.clone], "records": [m.to_dict() for m in self.records],
                "damping_max": float(self.damping_max), "system": self.system}

    @classmethod
    def from_dict(cls, d, *, source: str | None = None) -> ModalCheck:
        try:
            if not isinstance(d, Mapping) or not set(d) <= {"clone", "records", "damping_max", "system"}:
                raise InputError("field 'modes' must be a mapping of clone, records, damping_max and system")
            lists = {k: d.get(k) or [] for k in ("clone", "records")}
            if not all(isinstance(v, list) for v in lists.values()):
                raise InputError("fields 'modes.clone' and 'modes.records' must be lists of modes")
            dm = d.get("damping_max", 0.2)
            if not (_finite(dm) and 0 < dm <= 1):
                raise InputError("field 'modes.damping_max' must be a number in (0, 1]")
            system = d.get("system", "generic")
            if not isinstance(system, str):
                raise InputError("field 'modes.system' must be a string")
            return cls(tuple(Mode.from_dict(m, f"modes.clone[{j}]") for j, m in enumerate(lists["clone"])),
                       tuple(Mode.from_dict(m, f"modes.records[{j}]") for j, m in enumerate(lists["records"])),
                       float(dm), system)
        except InputError as e:
            raise InputError(str(e), source=source) from None


def modal_check(building, system: str | None, records: Sequence[Mode] = ()) -> ModalCheck:
    """The :class:`ModalCheck` of ``building`` under the structural ``system`` (None: generic)."""
    from ..systems import SYSTEMS

    name = system if system in SYSTEMS else "generic"
    return ModalCheck(clone_modes(building), tuple(records), SYSTEMS[name].damping_max, name)


__all__ = ["FREQUENCY_TOLERANCE", "Mode", "ModalCheck", "clone_modes", "modal_check", "modes_of", "unit_roof"]
