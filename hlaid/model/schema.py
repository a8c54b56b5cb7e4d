"""What a building's numbers may be, without torch: the bounds of the per-story parameters and
the damping model. Configs (``hlaid simulate``), clone files and :class:`~hlaid.model.Building`
are all checked against these declarations (:mod:`hlaid.bounds`), so a bad value is refused
before any heavy library is imported.

The bounds are wide (every real or laboratory building lies well inside them) but finite: a
``dy`` of ``1e-300`` mm or a ``k0`` of ``1e300`` N/mm is a typo, not a building.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..bounds import Bounds, bounded, check_bounds, show
from ..errors import InputError

STORY_BOUNDS: dict[str, Bounds] = {
    "mass": Bounds(1e-6, 1e8, unit="t"),
    "k0": Bounds(1e-6, 1e12, unit="N/mm"),
    "alpha": Bounds(0.0, 1.0),
    "p": Bounds(1.0, 50.0),
    "dy": Bounds(1e-6, 1e5, unit="mm"),
    "delta_eta": Bounds(0.0, 1e6, unit="s^2/m^2"),
    "height": Bounds(1.0, 1e6, unit="mm"),
    "gravity_load": Bounds(0.0, 1e12, unit="N"),
}
"""Bounds of the per-story parameters of a building (units N, mm, t, s)."""

DAMPING_RATIO_MAX = 0.5
"""Largest damping ratio an identification gives, an ensemble draws or a building file (a clone, a
config) may state: more than half the critical damping is no building's."""

STATE_BOUNDS: dict[str, Bounds] = {
    "drift": Bounds(-1e6, 1e6, unit="mm"),
    "z": Bounds(-1e6, 1e6, unit="mm"),
    "work": Bounds(-1e12, 1e12, unit="mm^2"),
    "peak_positive": Bounds(0.0, 1e6, unit="mm"),
    "peak_negative": Bounds(0.0, 1e6, unit="mm"),
}
"""Bounds of a carried state's per-story values (:class:`hlaid.model.state.BuildingState`):
a drift beyond the largest story height, or a hysteretic work beyond the largest ``dy`` times
that drift, is no state of a building."""

Z_SLACK = 1.05
"""A carried state's hysteretic displacement ``z`` stays within ``dy`` (eq 10 stops loading at
``|z| = dy``); this much beyond it (numerical overshoot) is still read, more is refused."""

EVENT_BOUNDS: dict[str, Bounds] = {
    "pga_g": Bounds(0.0, 100.0, unit="g"),
    "duration_s": Bounds(0.0, 1e7, lo_open=True, unit="s"),
    "dt": Bounds(1e-5, 0.2, unit="s"),
    "n_floors": Bounds(1, 10_000),
}
"""Bounds of the numbers a clone keeps of each event it learnt from (``events[]``)."""


def check_event(e: dict, i: int) -> None:
    """Refuse an ``events[i]`` entry of a clone whose numbers are no numbers or out of bounds, or
    whose digests are not text."""
    for key, b in EVENT_BOUNDS.items():
        v = e.get(key)
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"field 'events[{i}].{key}' must be a number")
        b.check(f"events[{i}].{key}", v)
    for key in ("name", "source", "sha256", "ground_sha256", "recorded"):
        if e.get(key) is not None and not isinstance(e[key], str):
            raise InputError(f"field 'events[{i}].{key}' must be a string")
    if e.get("replay") is not None:
        check_replay(e["replay"], f"events[{i}].replay")
    prof = e.get("ground_profile")
    if prof is not None and not (isinstance(prof, list) and 1 <= len(prof) <= 256 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and 0 <= x <= 1e3 for x in prof)):
        raise InputError(f"field 'events[{i}].ground_profile' must be a list of at most 256 numbers in 0..1000")


REPLAY_KEYS = ("band_hz", "peak_drift_error", "drift_r")
"""Fields of a clone's record of how its full replay of one of its own events met the records
(``events[i].replay``): the band compared ``[lo, hi]`` [Hz], and per story the signed peak-drift
error (a fraction: +0.1 is 10 % high) and the story-drift correlation R."""


def check_replay(r, where: str) -> None:
    """Refuse a replay record (see :data:`REPLAY_KEYS`) that is no mapping of finite number lists."""
    import math

    if not isinstance(r, dict):
        raise InputError(f"field '{where}' must be a mapping with {', '.join(REPLAY_KEYS)}")
    unknown = sorted(set(r) - set(REPLAY_KEYS))
    if unknown:
        raise InputError(f"field '{where}.{unknown[0]}' is unknown; expected {', '.join(REPLAY_KEYS)}")
    for key in REPLAY_KEYS:
        v = r.get(key)
        if v is None:
            continue
        if (not isinstance(v, list) or len(v) > 10_000
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
            raise InputError(f"field '{where}.{key}' must be a list of finite numbers")
        if key == "band_hz" and (len(v) != 2 or not 0 <= v[0] < v[1]):
            raise InputError(f"field '{where}.band_hz' must be [lo, hi] with 0 <= lo < hi (Hz)")


STATE_DRIFT_RATIO = 0.2
"""Largest residual or peak drift of a carried state as a fraction of its story's height: a story
that drifted a fifth of its height has collapsed, it carries no state to the next event."""


def check_state(z, dy, *, drift=None, peaks=(), height=None) -> None:
    """Refuse a carried state whose hysteretic displacement ``z`` [mm] exceeds its story's ``dy``
    (by more than :data:`Z_SLACK`): no replay of the clone's law leaves one there; and, where the
    story ``height`` [mm] is known, a residual ``drift`` or a peak (``peaks``: arrays of peak
    drifts) beyond :data:`STATE_DRIFT_RATIO` of it."""
    import numpy as np

    if height is not None:
        h = np.asarray(height, dtype=float)
        for name, v in (("drift", drift), *peaks):
            if v is None:
                continue
            ratio = np.abs(np.asarray(v, dtype=float)) / h
            k = int(np.argmax(ratio))
            if ratio[k] > STATE_DRIFT_RATIO:
                raise InputError(f"state.{name}[{k}] = {show(float(np.asarray(v)[k]))} mm is {ratio[k]:.3g} x the "
                                 f"story's height of {show(float(h[k]))} mm; a story that drifted more than "
                                 f"{STATE_DRIFT_RATIO:.0%} of its height has collapsed")

    ratio = np.abs(np.asarray(z, dtype=float)) / np.asarray(dy, dtype=float)
    k = int(np.argmax(ratio))
    if ratio[k] > Z_SLACK:
        raise InputError(f"state.z[{k}] = {show(float(np.asarray(z)[k]))} mm is beyond the story's dy = "
                         f"{show(float(np.asarray(dy)[k]))} mm; the hysteretic displacement stays within +-dy")


WEIGHT_KN = Bounds(1e-5, 1e9, unit="kN")
"""Bounds of a floor weight or gravity load given in kN (configs)."""

DAMPING_KINDS = ("rayleigh", "stiffness", "mass", "none", "modal")
"""Names of the damping models (their equations: :data:`hlaid.model.structure.DAMPING_KINDS`)."""


def check_story_value(name: str, value: float) -> None:
    """Raise :class:`InputError` if a per-story parameter lies outside :data:`STORY_BOUNDS`."""
    STORY_BOUNDS[name].check(name, value)


@dataclass(frozen=True, kw_only=True)
class Damping:
    """Viscous damping of the shear building: ``C = a0 M + a1 K0``.

    Attributes
    ----------
    kind : ``"rayleigh"`` (``ratio`` on the two ``modes``, or ``ratio`` on ``modes[0]`` and
        ``ratio2`` on ``modes[1]``), ``"stiffness"`` or ``"mass"`` (proportional, ``ratio`` on
        ``modes[0]``), or ``"none"``.
    ratio : damping ratio (0.05 is 5 %).
    modes : the two modes (1-based) that get ``ratio``; none beyond the building's stories
        (a one-story building keeps the default ``[1, 2]``: its only mode).
    ratio2 : ``rayleigh`` only: the damping ratio of ``modes[1]``, independent of ``ratio``
        (None: ``ratio``): the higher modes' damping is then the records', not the first
        mode's. ``C = a0 M + a1 K0`` still, with ``a0, a1`` solving the two ratios.
        ``modal``: the damping ratio of mode 2 (None: ``ratio``).
    higher : ``modal`` only: the damping ratios of modes 3 and up (a mode beyond the list takes
        its last entry, or ``ratio2`` where it is empty). ``modal`` damping gives every mode of
        the initial linear system (:meth:`hlaid.model.Building.linear_stiffness`) its own ratio:
        ``C = M Phi diag(2 zeta_j w_j) Phi^T M`` with ``Phi`` the mass-normalised modes, ``ratio``
        for mode 1.
    """

    kind: str = "rayleigh"
    ratio: float = bounded(0.05, lo=0.0, hi=1.0, hi_open=True)
    modes: tuple[int, int] = bounded((1, 2), lo=1, hi="STORIES")
    ratio2: float | None = bounded(None, lo=0.0, hi=1.0, hi_open=True)
    higher: tuple[float, ...] = bounded((), lo=0.0, hi=1.0, hi_open=True)

    def __post_init__(self):
        if self.kind not in DAMPING_KINDS:
            raise InputError(f"damping kind {self.kind!r} is unknown; expected one of {sorted(DAMPING_KINDS)}")
        try:
            modes = tuple(int(m) for m in self.modes)
        except (TypeError, ValueError):
            raise InputError(f"damping.modes = {self.modes!r}; expected two mode numbers such as [1, 2]") from None
        if len(modes) != 2:
            raise InputError(f"damping.modes = {list(modes)}; expected two mode numbers such as [1, 2]")
        check_bounds(self, prefix="damping.")
        object.__setattr__(self, "modes", modes)
        if self.ratio2 is not None and self.kind not in ("rayleigh", "modal"):
            raise InputError(f"damping.ratio2 = {self.ratio2!r} with kind {self.kind!r}; a second ratio is for "
                             "kind 'rayleigh' or 'modal' only")
        try:
            higher = tuple(float(v) for v in self.higher)
        except (TypeError, ValueError):
            raise InputError(f"damping.higher = {self.higher!r}; expected a list of damping ratios") from None
        if higher and self.kind != "modal":
            raise InputError(f"damping.higher with kind {self.kind!r}; the ratios of modes 3 and up are for kind "
                             "'modal' only")
        if not all(0.0 <= v < 1.0 for v in higher):
            raise InputError(f"damping.higher = {list(higher)}; expected damping ratios in [0, 1)")
        object.__setattr__(self, "higher", higher)
        if self.ratio2 is not None and self.kind == "rayleigh" and modes[0] == modes[1]:
            raise InputError(f"damping.ratio2 with damping.modes = {list(modes)}; expected two different modes")

    def mode_ratios(self, n_modes: int) -> tuple[float, ...]:
        """``modal``: the damping ratio of each of ``n_modes`` modes, lowest first."""
        second = self.ratio if self.ratio2 is None else self.ratio2
        rest = self.higher or (second,)
        return ((self.ratio, second) + tuple(rest[min(j, len(rest) - 1)] for j in range(max(n_modes - 2, 0))))[:n_modes]

    def check_modes(self, n_stories: int) -> None:
        """Refuse a mode beyond the building's ``n_stories`` (a one-story building keeps ``[1, 2]``)."""
        used = self.modes if self.kind == "rayleigh" else self.modes[:1]
        if self.kind not in ("none", "modal") and max(used) > max(n_stories, 2):
            raise InputError(f"damping.modes = {list(self.modes)}: a building of {n_stories} stories has modes "
                             f"1..{n_stories}")

    def to_dict(self) -> dict:
        return {"kind": self.kind, "ratio": self.ratio, "modes": list(self.modes),
                **({"ratio2": self.ratio2} if self.ratio2 is not None else {}),
                **({"higher": list(self.higher)} if self.higher else {})}


def check_damping_ratios(damping: object, source: str | None = None) -> None:
    """Refuse a file's ``damping`` block (a mapping) whose ratio or ratio2 exceeds
    :data:`DAMPING_RATIO_MAX` (0.99 is no building's: a percent typed as a ratio?)."""
    if not isinstance(damping, dict):
        return
    for key in ("ratio", "ratio2"):
        r = damping.get(key)
        if isinstance(r, (int, float)) and not isinstance(r, bool) and r > DAMPING_RATIO_MAX:
            raise InputError(f"damping.{key} = {r:g}; a building's damping ratio is at most {DAMPING_RATIO_MAX:g} "
                             "(0.05 is 5 %)", source=source)
    higher = damping.get("higher")
    if isinstance(higher, (list, tuple)):
        for r in higher:
            if isinstance(r, (int, float)) and not isinstance(r, bool) and r > DAMPING_RATIO_MAX:
                raise InputError(f"damping.higher holds {r:g}; a building's damping ratio is at most "
                                 f"{DAMPING_RATIO_MAX:g} (0.05 is 5 %)", source=source)


__all__ = ["check_damping_ratios", "STORY_BOUNDS", "DAMPING_RATIO_MAX", "WEIGHT_KN", "DAMPING_KINDS", "Damping",
           "check_story_value"]
