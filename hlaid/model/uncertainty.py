"""Parameter uncertainty of an identified clone: a Gaussian in transformed parameters.

Each uncertain parameter is a slot ``(name, story)`` (story 0-based; ``("damping", -1)`` is the
Rayleigh ratio, ``("damping2", -1)`` the second one where the clone has one). Positive
parameters are carried as ``theta = log(x)`` (``transform "log"``),
a parameter at a zero lower bound (``delta_eta = 0``) as ``theta = x`` (``"linear"``). The
uncertainty is ``theta ~ N(centre, covariance)``; intervals and ensemble draws map back
through the transform and are clipped to the parameter's physical bounds. Parameters that
are not slots (those of stories the record did not drive past yield, which identification
does not refine) are held at their identified value.

This module imports only numpy and the model (scipy when an interval is asked for), so
:mod:`hlaid.clone` can hold one (``hlaid.uncertainty`` re-exports it).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from .params import Building
from .schema import DAMPING_RATIO_MAX, STORY_BOUNDS

TRANSFORMS = ("log", "linear", "logit", "log1")
"""``theta`` of a value ``x``: ``log x``; ``x``; ``logit(x / 0.95)`` (alpha, within its bounds);
``log(x - 1)`` (p, above 1)."""
ALPHA_SCALE = 0.95

MAX_THETA_STD = 10.0
"""Largest standard deviation of a parameter in its log (or logit) scale that a clone file may hold:
a factor e^10 per sigma; a wider one was not computed from a record (a hand-edited file), and its
ensemble would span absurd values. Checked where a file is read (:meth:`ParameterUncertainty.from_dict`)."""


def to_theta(transform: str, x):
    """The transformed value of ``x`` (:data:`TRANSFORMS`)."""
    x = np.asarray(x, dtype=float)
    if transform == "log":
        return np.log(x)
    if transform == "logit":
        y = np.clip(x / ALPHA_SCALE, 1e-12, 1 - 1e-12)
        return np.log(y / (1 - y))
    if transform == "log1":
        return np.log(np.maximum(x - 1.0, 1e-300))
    return x


def from_theta(transform: str, theta):
    """The value of transformed ``theta`` (the inverse of :func:`to_theta`)."""
    theta = np.asarray(theta, dtype=float)
    if transform == "log":
        return np.exp(np.minimum(theta, 700.0))
    if transform == "logit":
        return ALPHA_SCALE / (1.0 + np.exp(-np.clip(theta, -700.0, 700.0)))
    if transform == "log1":
        return 1.0 + np.exp(np.minimum(theta, 700.0))
    return theta
BOUNDS = {n: (STORY_BOUNDS[n].lo, min(float(STORY_BOUNDS[n].upper()), ALPHA_SCALE if n == "alpha" else math.inf))
          for n in ("k0", "alpha", "p", "dy", "delta_eta")} | {"damping": (0.0, DAMPING_RATIO_MAX),
                                                                  "damping2": (0.0, DAMPING_RATIO_MAX)}
"""Range of each parameter: the building's own (:data:`hlaid.model.schema.STORY_BOUNDS`; alpha
within the identification's 0.95, damping ratio within :data:`~hlaid.model.schema.DAMPING_RATIO_MAX`).
Draws and intervals are clipped to it, so every member of an ensemble is a building a clone file may hold."""


@dataclass(frozen=True, eq=False)
class ParameterUncertainty:
    """A Gaussian over the identified parameters in transformed space.

    Attributes
    ----------
    slots : tuple of ``(name, story)``, length P
    transform : tuple of ``"log"`` / ``"linear"``, length P
    centre : (P,) transformed values at the identified clone
    covariance : (P, P) covariance of the transformed values
    method : how the covariance was obtained (e.g. ``"laplace-sandwich"``)
    info : method details (noise level, effective samples, calibration factor, ...)
    """

    slots: tuple
    transform: tuple
    centre: np.ndarray
    covariance: np.ndarray
    method: str = "laplace-sandwich"
    info: dict | None = None

    def __post_init__(self):
        P = len(self.slots)
        c = np.asarray(self.centre, dtype=float).reshape(-1)
        S = np.asarray(self.covariance, dtype=float)
        if c.shape != (P,) or S.shape != (P, P) or len(self.transform) != P:
            raise InputError(f"uncertainty: {P} slots need a centre of {P} values, a {P}x{P} covariance and {P} "
                             f"transforms; got {c.shape}, {S.shape}, {len(self.transform)}")
        for n, _ in self.slots:
            if n not in BOUNDS:
                raise InputError(f"uncertainty: unknown parameter {n!r}; expected one of {', '.join(BOUNDS)}")
        bad = [t for t in self.transform if t not in TRANSFORMS]
        if bad:
            raise InputError(f"uncertainty: unknown transform {bad[0]!r}; expected one of {', '.join(TRANSFORMS)}")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(S))):
            raise InputError("uncertainty: centre and covariance must be finite")
        if not np.allclose(S, S.T, rtol=1e-8, atol=1e-14 * max(1.0, float(np.abs(S).max(initial=0.0)))):
            raise InputError("uncertainty: the covariance must be symmetric")
        if P and np.linalg.eigvalsh(0.5 * (S + S.T)).min() < -1e-9 * max(1e-300, float(np.abs(np.diag(S)).max())):
            raise InputError("uncertainty: the covariance must be positive semi-definite")
        object.__setattr__(self, "centre", c)
        object.__setattr__(self, "covariance", 0.5 * (S + S.T))
        object.__setattr__(self, "slots", tuple((str(n), int(i)) for n, i in self.slots))
        object.__setattr__(self, "transform", tuple(self.transform))

    def _tops(self) -> np.ndarray:
        """(P,) the largest standard deviation each slot may have in its scale: :data:`MAX_THETA_STD`
        (log, logit), its bounds' width (linear; infinite where they are)."""
        out = []
        for (n, _), t in zip(self.slots, self.transform):
            lo, hi = BOUNDS[n] if n in BOUNDS else (0.0, 1.0)
            out.append(MAX_THETA_STD if t != "linear" else float(hi - lo) if math.isfinite(hi - lo) else math.inf)
        return np.array(out, dtype=float)

    def capped(self) -> ParameterUncertainty:
        """This uncertainty with the spread of every parameter the record did not identify (a standard
        deviation above its bound, :meth:`_tops`) shrunk to that bound, its correlations kept (the
        covariance scaled by ``D S D``, ``D`` diagonal <= 1: still positive semi-definite), and such
        parameters named in ``info["unidentified"]``: what a clone file holds, so that every command
        reads what identification wrote. Itself when none is."""
        sd = self.std
        tops = self._tops()
        over = sd > tops
        if not over.any():
            return self
        f = np.where(over, tops / np.maximum(sd, 1e-300), 1.0)
        names = [k for k, o in zip(self.names, over) if o]
        info = {**dict(self.info or {}), "unidentified": sorted({*(self.info or {}).get("unidentified", []), *names})}
        return dataclasses.replace(self, covariance=self.covariance * np.outer(f, f), info=info)

    @property
    def unidentified(self) -> list[str]:
        """The parameters whose spread reached its bound (:meth:`capped`): the record did not identify them."""
        u = (self.info or {}).get("unidentified", [])
        return [str(k) for k in u] if isinstance(u, list) else []

    def check_spread(self, source: str | None = None) -> None:
        """Refuse a parameter whose standard deviation exceeds its bound (:data:`MAX_THETA_STD` in its
        scale, its bounds' width for a linear one), the same bound that :meth:`capped` gives what
        identification writes: a wider one was not written by hlaid."""
        S = self.covariance
        for j, ((n, i), t, top) in enumerate(zip(self.slots, self.transform, self._tops())):
            if S[j, j] > (top * (1 + 1e-9))**2:
                name = n if int(i) < 0 else f"{n}[{int(i) + 1}]"
                raise InputError(f"uncertainty: {name} has a standard deviation of {math.sqrt(S[j, j]):.3g} in its "
                                 f"{t} scale; hlaid writes at most {top:.3g} (an unidentified parameter is capped "
                                 "there and flagged): such a covariance was not written by hlaid identify; "
                                 "identify the clone again", source=source)

    # ------------------------------------------------------------------ values
    @property
    def names(self) -> list[str]:
        """``"k0[1]"`` style labels (1-based story numbers), ``"damping"`` for the ratio."""
        return [n if i < 0 else f"{n}[{i + 1}]" for n, i in self.slots]

    @property
    def std(self) -> np.ndarray:
        """(P,) standard deviations in transformed space (log: about the coefficient of variation)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def values(self, theta) -> np.ndarray:
        """Parameter values of transformed ``theta`` ``(..., P)``, clipped to their bounds."""
        theta = np.asarray(theta, dtype=float)
        x = np.stack([from_theta(t, theta[..., j]) for j, t in enumerate(self.transform)], axis=-1) \
            if self.transform else theta
        lo = np.array([BOUNDS[n][0] for n, _ in self.slots])
        hi = np.array([BOUNDS[n][1] for n, _ in self.slots])
        return np.clip(x, lo, hi)

    def interval(self, level: float = 0.9) -> dict[str, tuple[float, float]]:
        """Central ``level`` interval of every slot, ``{"k0[1]": (lo, hi), ...}`` (parameter units)."""
        if not (isinstance(level, (int, float)) and 0.0 < level < 1.0):
            raise InputError(f"interval level = {level!r}; expected a probability in (0, 1), e.g. 0.9")
        from scipy.stats import norm  # here, not at import: reading a clone needs no scipy

        z = float(norm.ppf(0.5 + 0.5 * level))
        lo = self.values(self.centre - z * self.std)
        hi = self.values(self.centre + z * self.std)
        return {k: (float(a), float(b)) for k, a, b in zip(self.names, lo, hi)}

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, P) parameter values drawn from the Gaussian (clipped to bounds)."""
        P = len(self.slots)
        w, V = np.linalg.eigh(self.covariance)
        L = V * np.sqrt(np.clip(w, 0.0, None))
        return self.values(self.centre + rng.standard_normal((n, P)) @ L.T)

    def apply(self, building: Building, x) -> Building:
        """``building`` with the slots set to the values ``x`` ``(P,)``."""
        fields = {n: np.array(getattr(building, n), dtype=float) for n in ("k0", "alpha", "p", "dy", "delta_eta")}
        ratio, ratio2 = building.damping.ratio, building.damping.ratio2
        for (n, i), v in zip(self.slots, np.asarray(x, dtype=float)):
            if n == "damping":
                ratio = float(v)
            elif n == "damping2":
                ratio2 = float(v)
            else:
                if i >= building.n_stories:
                    raise InputError(f"uncertainty slot {n}[{i + 1}] is beyond the building's "
                                     f"{building.n_stories} stories")
                fields[n][i] = v
        d = building.damping
        return building.replace(**fields, damping=dataclasses.replace(d, ratio=ratio, ratio2=ratio2))

    # ------------------------------------------------------------------ I/O
    def to_dict(self, level: float = 0.9) -> dict:
        """JSON-able: per parameter its slot, transform, value and ``level`` interval, and the covariance
        (of :meth:`capped`: a parameter the record did not identify is written with its spread at the
        bound the reader allows, and named in ``info["unidentified"]``)."""
        if self is not self.capped():
            return self.capped().to_dict(level)
        iv = self.interval(level)
        vals = self.values(self.centre)
        params = [{"name": n, "story": i + 1 if i >= 0 else None, "transform": t, "value": float(v),
                   "std": float(s), "interval": list(iv[k])}
                  for (n, i), t, v, s, k in zip(self.slots, self.transform, vals, self.std, self.names)]
        return {"method": self.method, "level": level, "parameters": params,
                "covariance": self.covariance.tolist(), "info": dict(self.info or {})}

    @classmethod
    def from_dict(cls, d, *, source: str | None = None) -> ParameterUncertainty:
        """Inverse of :meth:`to_dict` (strict: unknown fields are an :class:`InputError`)."""
        def bad(msg):
            return InputError(f"uncertainty.{msg}", source=source)

        if not isinstance(d, dict):
            raise bad("(the block) must be a mapping")
        unknown = [k for k in d if k not in ("method", "level", "parameters", "covariance", "info")]
        if unknown:
            raise bad(f"{unknown[0][:40]}: unknown field; expected method, level, parameters, covariance, info")
        params = d.get("parameters")
        if not isinstance(params, list):
            raise bad("parameters must be a list")
        slots, transforms, centre = [], [], []
        for j, p in enumerate(params):
            if not isinstance(p, dict):
                raise bad(f"parameters[{j}] must be a mapping")
            unknown = [k for k in p if k not in ("name", "story", "transform", "value", "std", "interval")]
            if unknown:
                raise bad(f"parameters[{j}].{unknown[0][:40]}: unknown field; expected name, story, transform, value, "
                          "std, interval")
            v: Any  # checked to be a finite number below
            name, story, t, v = p.get("name"), p.get("story"), p.get("transform"), p.get("value")
            if name not in BOUNDS:
                raise bad(f"parameters[{j}].name must be one of {', '.join(BOUNDS)}")
            if name in ("damping", "damping2"):
                story = 0
            elif isinstance(story, bool) or not isinstance(story, int) or story < 1:
                raise bad(f"parameters[{j}].story must be a story number >= 1")
            if t not in TRANSFORMS:
                raise bad(f"parameters[{j}].transform must be one of {', '.join(TRANSFORMS)}")
            number = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            if not number or (t == "log" and v <= 0) or (t == "log1" and v <= 1) or (t == "logit" and not
                                                                                        0 < v < ALPHA_SCALE):
                raise bad(f"parameters[{j}].value must be a finite number within its transform's range "
                          "(log: > 0, log1: > 1, logit: in (0, 0.95))")
            slots.append((name, story - 1))
            transforms.append(t)
            centre.append(float(to_theta(t, v)))
        cov = d.get("covariance")
        P = len(slots)
        try:
            S = np.array(cov, dtype=float)
        except (TypeError, ValueError):
            raise bad(f"covariance must be a {P}x{P} list of numbers") from None
        if S.shape != (P, P):
            raise bad(f"covariance must be a {P}x{P} list of numbers (one row per parameter)")
        info = d.get("info") or {}
        if not isinstance(info, dict):
            raise bad("info must be a mapping")
        try:
            out = cls(slots=tuple(slots), transform=tuple(transforms), centre=np.array(centre), covariance=S,
                      method=str(d.get("method", "")), info=info)
        except InputError as err:
            raise InputError(str(err), source=source) from None
        out.check_spread(source)
        return out
