"""Collapse-capable story law: capping, post-capping softening and residual strength.

The degrading Bouc-Wen law of the paper (eq 3-10) has no strength loss and a positive post-yield
stiffness ``alpha k0``, so a clone can only "collapse" at the IDA drift limit. A *collapse model*
gives every story the monotonic envelope of the modified Ibarra-Medina-Krawinkler (IMK) backbone:

* up to the capping drift ``xc = dy + theta_p h`` the story is the Bouc-Wen story, unchanged
  (capping strength ``Fc = (1-alpha) k0 dy + alpha k0 xc``, the yielded Bouc-Wen force there);
* beyond it, the strength falls along a straight line of slope ``kpc = -Fc / (theta_pc h)``
  (``theta_pc`` is the drift from the cap to zero strength, IMK's definition) down to the residual
  strength ``Fr = kappa k0 dy``;
* beyond the ultimate drift ``xu = theta_u h`` the residual falls to zero with the same slope
  (when the post-capping line reaches zero before ``xu`` there is no residual plateau).

The kinks are gap springs in parallel with the Bouc-Wen spring (elastic-perfectly-plastic, the gap
growing with plastic deformation: OpenSees' ``ElasticPPGap ... damage``), written once in
:mod:`hlaid.model._equations`. Their memory is the largest past drift in each direction: strength
lost at a peak is not regained on reloading (beyond the plastic offset). P-Delta (``-P/h x``) is
added as before, and the net story stiffness beyond the cap is negative: IDA curves flatten for a
physical reason.

Named models (:data:`COLLAPSE_MODELS`) give literature ratios for the structural system; a
mapping of the four ratios gives user values. ``"none"`` is the paper's law, bit for bit.
Plastic rotations of the literature are taken as story plastic drift ratios (beam-hinging
frames: the story's plastic drift is the hinges' plastic rotation); see docs/collapse.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

import numpy as np

from ..bounds import bounded, check_bounds
from ..errors import InputError

NO_CAP = 1e290
"""Capping and ultimate drift [mm] of a story without a collapse model (never reached)."""

N_COLLAPSE = 8
"""Resolved per-story collapse values: four gap springs ``x1, dk1, ..., x4, dk4`` (kink drift [mm],
change of the envelope's slope there [N/mm])."""


@dataclass(frozen=True, kw_only=True)
class CollapseModel:
    """Strength-deterioration ratios of a story (modified IMK backbone, drift-ratio form).

    Attributes
    ----------
    name : a label (the preset's name, or ``"user"``)
    theta_p : plastic drift ratio from yield to the capping point, > 0 (0.025 is 2.5 %)
    theta_pc : post-capping drift ratio from the cap to zero strength, > 0
    kappa : residual strength as a fraction of the yield strength ``k0 dy``, in [0, 1)
    theta_u : ultimate drift ratio, where the residual strength starts to fall to zero; it
        must exceed the capping drift ratio ``dy/h + theta_p`` of every story
    beta_p : the logarithmic standard deviation of ``theta_p`` over the members the median comes
        from (the law's scatter, conditioned on what a building survived in
        :mod:`hlaid.model.capacity`); 0: ``theta_p`` known
    source : where the ratios come from
    """

    name: str = "user"
    theta_p: float = bounded(lo=1e-5, hi=1.0, hi_open=True)
    theta_pc: float = bounded(lo=1e-5, hi=10.0, hi_open=True)
    kappa: float = bounded(lo=0.0, hi=1.0, hi_open=True)
    theta_u: float = bounded(lo=1e-5, hi=10.0, hi_open=True)
    beta_p: float = bounded(0.4, lo=0.0, hi=2.0)
    source: str = ""

    def __post_init__(self):
        check_bounds(self, prefix="collapse.")  # also refuses a value that is no number
        if self.theta_u <= self.theta_p:
            raise InputError(f"collapse.theta_u = {self.theta_u:g} must exceed theta_p = {self.theta_p:g} "
                             "(the ultimate drift lies beyond the cap)")

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def backbone(self, *, k0, alpha, dy, height) -> dict[str, np.ndarray]:
        """The IMK points of every story ``(story,)``: ``xc, fc, kpc, fr, xr`` (start of the
        residual plateau, inf when there is none), ``xu`` and ``xz`` (zero strength) [mm, N, N/mm]."""
        k0, alpha, dy, h = (np.asarray(a, dtype=np.float64) for a in (k0, alpha, dy, height))
        xc = dy + self.theta_p * h
        fc = (1.0 - alpha) * k0 * dy + alpha * k0 * xc
        xu = self.theta_u * h
        bad = np.flatnonzero(xu <= xc)
        if bad.size:
            i = int(bad[0])
            raise InputError(f"collapse.theta_u = {self.theta_u:g} is below the capping drift ratio "
                             f"{xc[i] / h[i]:.4g} of story {i + 1} (dy/h + theta_p); give a larger theta_u")
        kpc = -fc / (self.theta_pc * h)
        fr = self.kappa * k0 * dy
        xr = xc + (fc - fr) / -kpc
        plateau = xr < xu
        xz = np.where(plateau, xu + fr / -kpc, xc + fc / -kpc)
        return {"xc": xc, "fc": fc, "kpc": kpc, "fr": fr, "xr": np.where(plateau, xr, np.inf), "xu": xu, "xz": xz}

    def resolve(self, *, k0, alpha, dy, height) -> np.ndarray:
        """Per-story gap springs ``(story, 8)``: ``x1, dk1, ..., x4, dk4`` (see :data:`N_COLLAPSE`)."""
        b = self.backbone(k0=k0, alpha=alpha, dy=dy, height=height)
        ka = np.asarray(alpha, dtype=np.float64) * np.asarray(k0, dtype=np.float64)
        kpc, plateau = b["kpc"], np.isfinite(b["xr"])
        out = no_collapse(kpc.shape[0])
        out[:, 0], out[:, 1] = b["xc"], kpc - ka  # cap: Bouc-Wen slope -> post-capping slope
        out[:, 2], out[:, 3] = np.where(plateau, b["xr"], b["xz"]), -kpc  # residual plateau, or zero strength
        out[:, 4] = np.where(plateau, b["xu"], NO_CAP)  # ultimate: the residual falls...
        out[:, 5] = np.where(plateau, kpc, 0.0)
        out[:, 6] = np.where(plateau, b["xz"], NO_CAP)  # ...to zero
        out[:, 7] = np.where(plateau, -kpc, 0.0)
        return out


def accommodate(law: CollapseModel, *, dy, height, survived=None) -> tuple[CollapseModel, list[str]]:
    """``law`` made consistent with a building that survived drifts ``survived`` ``(story,)`` [mm]
    (None: unknown), and notes saying how.

    * A capping drift ``dy/h + theta_p`` below a survived drift contradicts the record (the story
      would have been losing strength in an event it came through): ``theta_p`` is raised so that
      every story caps at or beyond its survived drift, and ``theta_u`` with it (the post-capping
      branch and the residual plateau keep their extent).
    * An ultimate drift ``theta_u`` not beyond every story's capping drift (a story of large
      ``dy``) is raised to ``dy/h + theta_p`` of that story plus the law's own ``theta_u - theta_p``.

    ``dy``, ``height`` ``(story,)`` [mm]. An InputError where the survived drifts exceed the story
    heights (no law caps beyond them: check the heights).
    """
    dy, h = np.asarray(dy, dtype=float), np.asarray(height, dtype=float)
    theta_p, theta_u = law.theta_p, law.theta_u
    notes: list[str] = []
    if survived is not None:
        s = np.asarray(survived, dtype=float)
        need = (s - dy) / h
        i = int(np.argmax(need))
        if need[i] > theta_p:
            if s[i] >= h[i]:
                raise InputError(f"story {i + 1} survived a drift of {s[i]:.4g} mm, beyond its height {h[i]:g} mm: "
                                 "check the story heights (heights_mm, --heights)")
            theta_p = float(need[i])
            theta_u = law.theta_u + (theta_p - law.theta_p)
            notes.append(f"collapse law {law.name!r}: its capping drift dy/h + {law.theta_p:g} lay below a drift the "
                         f"building survived (story {i + 1}: {s[i]:.1f} mm, {s[i] / h[i]:.2%} of its height "
                         f"{h[i]:g} mm; all stories: " + ", ".join(f"{v:.1f}" for v in s)
                         + f" mm): theta_p raised to {theta_p:.4g} and theta_u to {theta_u:.4g}, so every story caps "
                         "at or beyond the drift it survived")
    cap = float(np.max(dy / h)) + theta_p
    if theta_u <= cap:
        theta_u = cap + (law.theta_u - law.theta_p)
        notes.append(f"collapse law {law.name!r}: theta_u raised to {theta_u:.4g}, beyond every story's capping drift "
                     f"ratio (largest {cap:.4g}, dy/h + theta_p)")
    if not notes:
        return law, notes
    if theta_p >= 1.0 or theta_u >= 10.0:
        raise InputError(f"collapse law {law.name!r}: the drifts survived need a capping drift ratio of {theta_p:.3g}, "
                         "beyond any story's: check the story heights (heights_mm, --heights)")
    return replace(law, theta_p=theta_p, theta_u=theta_u), notes


def no_collapse(n_stories: int) -> np.ndarray:
    """Resolved values ``(story, 8)`` of stories without strength loss (springs that never engage)."""
    out = np.zeros((n_stories, N_COLLAPSE))
    out[:, 0::2] = NO_CAP
    return out


_LK2011 = ("Lignos & Krawinkler (2011), J. Struct. Eng. 137(11):1291-1302, RBS beam medians "
           "(theta_p ~ 0.025 with a logarithmic scatter ~ 0.3, theta_pc ~ 0.16-0.20, kappa ~ 0.4, "
           "theta_u 0.06-0.08); NIST GCR 10-917-8")
_H2016 = ("Haselton, Liel, Taylor-Lange & Deierlein (2016), ACI Struct. J. 113(6):1141-1152 and "
          "PEER 2007/03 (Haselton et al. 2008): conforming RC columns (theta_cap,pl ~ 0.05-0.06, "
          "theta_pc ~ 0.10, capped at 0.10), FEMA P695 RC SMF archetypes")
_LIEL = ("Haselton et al. (2008, 2016) equations for non-conforming columns (low transverse steel, "
         "high axial load) as used by Liel, Haselton & Deierlein (2011), J. Struct. Eng. 137(4):492-502")

COLLAPSE_MODELS: dict[str, CollapseModel | None] = {
    "none": None,
    "steel-mrf": CollapseModel(name="steel-mrf", theta_p=0.025, theta_pc=0.16, kappa=0.4, theta_u=0.08,
                               beta_p=0.32, source=_LK2011),
    "rc-frame": CollapseModel(name="rc-frame", theta_p=0.05, theta_pc=0.10, kappa=0.2, theta_u=0.10,
                              beta_p=0.54, source=_H2016),
    "rc-frame-nonductile": CollapseModel(name="rc-frame-nonductile", theta_p=0.02, theta_pc=0.04, kappa=0.1,
                                         theta_u=0.05, beta_p=0.54, source=_LIEL),
}
"""Named collapse models: ``"none"`` (the paper's law: no strength loss) and literature presets."""

_USER_KEYS = ("theta_p", "theta_pc", "kappa", "theta_u")
_USER_OPTIONAL = ("name", "source", "beta_p")


def get_collapse_model(spec) -> CollapseModel | None:
    """A collapse model from a name in :data:`COLLAPSE_MODELS`, a mapping of user ratios
    (``theta_p``, ``theta_pc``, ``kappa``, ``theta_u``, optionally ``name`` and ``source``), a
    :class:`CollapseModel`, or None (``"none"``). Unknown names and keys are an :class:`InputError`."""
    if spec is None or isinstance(spec, CollapseModel):
        return spec
    if isinstance(spec, str):
        try:
            return COLLAPSE_MODELS[spec]
        except KeyError:
            raise InputError(f"unknown collapse model {spec!r}; expected one of {', '.join(COLLAPSE_MODELS)} "
                             f"or a mapping of {', '.join(_USER_KEYS)}") from None
    if isinstance(spec, Mapping):
        d = dict(spec)
        unknown = sorted(set(d) - set(_USER_KEYS) - set(_USER_OPTIONAL))
        if unknown:
            raise InputError(f"collapse: unknown field(s) {unknown}; expected {', '.join(_USER_KEYS)} "
                             f"(and optionally {', '.join(_USER_OPTIONAL)})")
        missing = [k for k in _USER_KEYS if k not in d]
        if missing:
            raise InputError(f"collapse: missing {', '.join(missing)}; a user collapse model gives "
                             f"{', '.join(_USER_KEYS)}")
        return CollapseModel(**d)
    raise InputError(f"collapse must be a name ({', '.join(COLLAPSE_MODELS)}) or a mapping, got "
                     f"{type(spec).__name__}")
