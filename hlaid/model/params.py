"""Parameter sets of the degrading Bouc-Wen shear building, as frozen dataclasses."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..bounds import with_bounds
from ..errors import InputError, escape_controls
from ..units import G_MM_S2, kn_to_n, n_to_kn, weight_kn_to_mass_t
from .collapse import CollapseModel, get_collapse_model, no_collapse
from .coupling import Coupling, coupling_matrix
from .schema import STORY_BOUNDS, Damping, check_damping_ratios, check_story_value

if TYPE_CHECKING:  # torch is imported where a building is simulated, not where one is checked
    import torch

STORY_FIELDS = ("mass", "k0", "alpha", "p", "dy", "delta_eta")
"""Per-story parameters of the hysteretic model, in this order."""

def _check_range(name: str, values: np.ndarray, source: str | None) -> None:
    for i, v in enumerate(values):
        try:
            check_story_value(name, v)
        except InputError as e:
            raise InputError(f"story {i + 1}: {e}", source=source) from None


def _frozen_array(values: Any, name: str, n: int | None, source: str | None) -> np.ndarray:
    try:
        a = np.array(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a list of numbers, got {values!r}", source=source) from None
    if n is not None and a.shape[0] != n:
        raise InputError(f"{name} has {a.shape[0]} values but the building has {n} stories", source=source)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True, eq=False)
class Building:
    """A shear building with one degrading Bouc-Wen spring per story.

    Stories are listed bottom to top; every array is ``(story,)``. Units N, mm, t, s.

    Attributes
    ----------
    mass : floor masses [t] (floor ``i`` at the top of story ``i``)
    k0 : initial story stiffness [N/mm]
    alpha : post-yield stiffness ratio, in [0, 1]
    p : smoothness of the elastic-plastic transition, >= 1
    dy : yield displacement [mm], > 0
    delta_eta : stiffness degradation per unit dissipated energy [s^2/m^2], >= 0
    height : story heights [mm], or None when unknown (no P-Delta, no drift ratios)
    gravity_load : gravity load on each floor [N]; None means ``mass * g``
    damping : viscous damping model
    pdelta : include the geometric stiffness ``-P_i/h_i``; None means "when heights are known"
    collapse : strength loss beyond a capping drift (:class:`~hlaid.model.collapse.CollapseModel`,
        a name of :data:`~hlaid.model.collapse.COLLAPSE_MODELS` or a mapping); None (``"none"``):
        the paper's law. Needs story heights.
    coupling : a linear floor coupling beside the story springs (:class:`~hlaid.model.coupling.Coupling`,
        or a mapping of it), the restoring force ``F = shear-chain story forces + K_c u``; None:
        the shear chain
    name : a label
    """

    mass: np.ndarray = with_bounds(STORY_BOUNDS["mass"])
    k0: np.ndarray = with_bounds(STORY_BOUNDS["k0"])
    alpha: np.ndarray = with_bounds(STORY_BOUNDS["alpha"])
    p: np.ndarray = with_bounds(STORY_BOUNDS["p"])
    dy: np.ndarray = with_bounds(STORY_BOUNDS["dy"])
    delta_eta: np.ndarray = with_bounds(STORY_BOUNDS["delta_eta"])
    height: np.ndarray | None = with_bounds(STORY_BOUNDS["height"], None)
    gravity_load: np.ndarray | None = with_bounds(STORY_BOUNDS["gravity_load"], None)
    damping: Damping = field(default_factory=Damping)
    pdelta: bool | None = None
    collapse: CollapseModel | None = None
    coupling: Coupling | None = None
    name: str = ""
    source: str | None = field(default=None, repr=False)

    def __post_init__(self):
        n = None
        for name in STORY_FIELDS:
            a = _frozen_array(getattr(self, name), name, n, self.source)
            n = a.shape[0]
            object.__setattr__(self, name, a)
        if n == 0:
            raise InputError("a building needs at least one story", source=self.source)
        for name in ("height", "gravity_load"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen_array(getattr(self, name), name, n, self.source))
        for name in STORY_BOUNDS:
            a = getattr(self, name)
            if a is not None:
                _check_range(name, a, self.source)
        if self.pdelta and self.height is None:
            raise InputError("pdelta is on but story heights are unknown; give height for every story",
                             source=self.source)
        if not isinstance(self.damping, Damping):
            raise InputError(f"damping must be a Damping, got {type(self.damping).__name__}", source=self.source)
        try:
            self.damping.check_modes(self.n_stories)
            c = self.coupling
            if c is not None and not isinstance(c, Coupling):
                c = Coupling.from_dict(c)
            if c is not None and c.n_stories != self.n_stories:
                raise InputError(f"coupling.flexural has {len(c.flexural)} terms; a building of {self.n_stories} "
                                 f"stories has {self.n_stories - 1} (one per level with a floor above it)")
            object.__setattr__(self, "coupling", None if c is None or c.is_zero else c)
        except InputError as e:
            raise InputError(str(e), source=self.source) from None
        try:
            object.__setattr__(self, "collapse", get_collapse_model(self.collapse))
            if self.collapse is not None:
                if self.height is None:
                    raise InputError("a collapse model needs story heights (its ratios are drift ratios); "
                                     "give height for every story")
                self.collapse_values()
        except InputError as e:
            raise InputError(str(e).removeprefix(f"{escape_controls(self.source)}: "), source=self.source) from None

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_stories(cls, stories: Sequence[Mapping[str, float]], **kwargs) -> Building:
        """Build from per-story mappings, bottom to top.

        Each story gives ``mass_t`` (or ``weight_kN``), ``k0``, ``alpha``, ``p``, ``dy``,
        ``delta_eta`` and optionally ``height_mm`` and ``gravity_kN``.
        """
        source = kwargs.get("source")
        cols: dict[str, Any] = {k: [] for k in STORY_FIELDS}
        heights, gravity = [], []
        for i, s in enumerate(stories):
            s = dict(s)
            if ("mass_t" in s) == ("weight_kN" in s):
                raise InputError(f"story {i + 1}: give exactly one of mass_t or weight_kN", source=source)
            cols["mass"].append(s.pop("mass_t") if "mass_t" in s else weight_kn_to_mass_t(s.pop("weight_kN")))
            for k in STORY_FIELDS[1:]:
                if k not in s:
                    raise InputError(f"story {i + 1}: missing {k}", source=source)
                cols[k].append(s.pop(k))
            heights.append(s.pop("height_mm", None))
            gravity.append(s.pop("gravity_kN", None))
            if s:
                raise InputError(f"story {i + 1}: unknown field(s) {sorted(s)}", source=source)
        for name, vals in (("height_mm", heights), ("gravity_kN", gravity)):
            if any(v is None for v in vals) and not all(v is None for v in vals):
                raise InputError(f"{name} is given for some stories but not all", source=source)
        if heights[0] is not None:
            kwargs.setdefault("height", heights)
        if gravity[0] is not None:
            kwargs.setdefault("gravity_load", kn_to_n(np.asarray(gravity, dtype=float)))
        return cls(**cols, **kwargs)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, source: str | None = None) -> Building:
        """Inverse of :meth:`to_dict`."""
        d = dict(d)
        stories = d.pop("stories")
        check_damping_ratios(d.get("damping", {}), source)
        dd = dict(d.pop("damping", {}))
        if "higher" in dd:
            dd["higher"] = tuple(dd["higher"])
        damping = Damping(**dd)
        return cls.from_stories(stories, damping=damping, source=source, **d)

    def to_dict(self) -> dict:
        """A JSON-able description (units N, mm, t, s)."""
        stories = []
        for i in range(self.n_stories):
            s = {"mass_t": float(self.mass[i])}
            s.update({k: float(getattr(self, k)[i]) for k in STORY_FIELDS[1:]})
            if self.height is not None:
                s["height_mm"] = float(self.height[i])
            if self.gravity_load is not None:
                s["gravity_kN"] = n_to_kn(float(self.gravity_load[i]))
            stories.append(s)
        out: dict[str, Any] = {"stories": stories, "damping": self.damping.to_dict(), "pdelta": self.pdelta}
        if self.collapse is not None:
            out["collapse"] = self.collapse.to_dict()
        if self.coupling is not None:
            out["coupling"] = self.coupling.to_dict()
        if self.name:
            out["name"] = self.name
        return out

    def replace(self, **changes) -> Building:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    # ------------------------------------------------------------------ derived
    @property
    def n_stories(self) -> int:
        return int(self.mass.shape[0])

    @property
    def pdelta_active(self) -> bool:
        return bool(self.height is not None if self.pdelta is None else self.pdelta)

    def floor_gravity(self) -> np.ndarray:
        """Gravity load on each floor [N], ``(story,)``."""
        return self.mass * G_MM_S2 if self.gravity_load is None else np.asarray(self.gravity_load)

    def geometric_stiffness(self) -> np.ndarray:
        """P-Delta stiffness ``P_i / h_i`` [N/mm] subtracted from each story, zeros when inactive."""
        if not self.pdelta_active:
            return np.zeros(self.n_stories)
        return np.cumsum(self.floor_gravity()[::-1])[::-1] / self.height

    def collapse_values(self) -> np.ndarray:
        """Resolved collapse gap springs ``(story, 8)``: ``x1, dk1, ..., x4, dk4`` [mm, N/mm]
        (:meth:`CollapseModel.resolve`); springs that never engage without a model."""
        if self.collapse is None:
            return no_collapse(self.n_stories)
        return self.collapse.resolve(k0=self.k0, alpha=self.alpha, dy=self.dy, height=self.height)

    def _t(self, name):
        import torch
        return torch.tensor(np.asarray(getattr(self, name)), dtype=torch.float64)[None]

    def rayleigh(self) -> tuple[float, float]:
        """Damping coefficients ``(a0, a1)`` of ``C = a0 M + a1 K0`` (none for ``modal`` damping)."""
        from . import _structure as S
        if self.damping.kind == "modal":
            raise InputError("modal damping has no Rayleigh coefficients (C is built from the modes)",
                             source=self.source)
        a0, a1 = S.rayleigh_coefficients(self._t("k0"), self._t("mass"), self.damping.kind,
                                         self.damping.ratio, self.damping.modes, self.damping.ratio2)
        return float(a0[0]), float(a1[0])

    def damping_matrix(self) -> np.ndarray:
        """``C`` [N s/mm], ``(story, story)``: Rayleigh's, or for ``modal`` damping
        ``M Phi diag(2 zeta_j w_j) Phi^T M`` over the mass-normalised modes ``Phi`` of the initial
        linear system (:meth:`linear_stiffness`)."""
        import torch

        from . import _structure as S
        if self.damping.kind == "modal":
            import scipy.linalg

            lam, phi = scipy.linalg.eigh(self.linear_stiffness(), np.diag(self.mass))
            w = np.sqrt(np.maximum(lam, 0.0))
            zeta = np.asarray(self.damping.mode_ratios(self.n_stories))
            mp = self.mass[:, None] * phi
            C = mp @ np.diag(2.0 * zeta * w) @ mp.T
            return 0.5 * (C + C.T)
        a0, a1 = self.rayleigh()
        return S.damping_matrix(self._t("k0"), self._t("mass"), torch.tensor([a0], dtype=torch.float64),
                                torch.tensor([a1], dtype=torch.float64))[0].numpy()

    def stiffness_matrix(self, pdelta: bool = False) -> np.ndarray:
        """Initial elastic stiffness matrix ``K0`` [N/mm], ``(story, story)``; with ``pdelta``
        less the P-Delta stiffness (:meth:`geometric_stiffness`, zero when inactive)."""
        import torch

        from . import _structure as S
        k = self._t("k0")
        if pdelta:
            k = k - torch.as_tensor(self.geometric_stiffness(), dtype=torch.float64)[None]
        return S.stiffness_matrix(k)[0].numpy()

    def coupling_matrix(self) -> np.ndarray:
        """``K_c`` [N/mm], ``(story, story)``: the linear coupling's (zeros for a shear chain)."""
        return coupling_matrix(self.coupling, self.n_stories)

    def linear_stiffness(self) -> np.ndarray:
        """The stiffness matrix of the initial linear system [N/mm], ``(story, story)``: the story
        springs at ``k0`` less the P-Delta stiffness (where active), plus the coupling ``K_c``."""
        return self.stiffness_matrix(pdelta=True) + self.coupling_matrix()

    def periods(self) -> np.ndarray:
        """Initial elastic periods [s], longest first, ``(story,)`` (of the story springs and the
        coupling; P-Delta left out)."""
        from . import _structure as S
        if self.coupling is not None:
            import scipy.linalg

            lam = scipy.linalg.eigvalsh(self.stiffness_matrix() + self.coupling_matrix(), np.diag(self.mass))
            return 2.0 * np.pi / np.sqrt(np.maximum(lam, 1e-300))
        w = S.natural_frequencies(self._t("k0"), self._t("mass"))[0].numpy()
        return 2.0 * np.pi / w

    def elastic_stiffness(self, eta: np.ndarray) -> np.ndarray:
        """``ke = alpha k0 + (1-alpha) k0 / eta`` [N/mm] for degradation ``eta`` ``(..., story)``."""
        from ._equations import elastic_stiffness
        return elastic_stiffness(np.asarray(eta), self.alpha, self.k0)


@dataclass(frozen=True)
class BuildingTensors:
    """Batched parameters of buildings with the same number of stories.

    Every per-story field is ``(batch, story)``; ``damping`` is ``(batch, story, story)``;
    ``kg`` is the P-Delta stiffness ``P/h`` (zeros where inactive); ``collapse`` is
    ``(batch, story, 8)`` (gap springs ``x1, dk1, ..., x4, dk4``, :meth:`Building.collapse_values`) or None when no
    building of the batch has a collapse model. It is used when the state carries the collapse
    memory (``6*story`` wide, see :class:`~hlaid.model.BoucWenBuilding`). ``coupling`` is the
    linear coupling ``K_c`` ``(batch, story, story)`` (:mod:`hlaid.model.coupling`), or None
    when no building of the batch has one.
    """

    mass: torch.Tensor
    k0: torch.Tensor
    alpha: torch.Tensor
    p: torch.Tensor
    dy: torch.Tensor
    delta_eta: torch.Tensor
    kg: torch.Tensor
    damping: torch.Tensor
    collapse: torch.Tensor | None = None
    coupling: torch.Tensor | None = None

    @classmethod
    def stack(cls, buildings: Sequence[Building], dtype=None, device=None) -> BuildingTensors:
        import torch
        dtype = torch.float64 if dtype is None else dtype
        buildings = list(buildings)
        if not buildings:
            raise InputError("no buildings given")
        n = {b.n_stories for b in buildings}
        if len(n) != 1:
            raise InputError(f"buildings in one batch must have the same number of stories, got {sorted(n)}")

        def t(values):
            return torch.tensor(np.stack(values), dtype=dtype, device=device)

        fields = {k: t([getattr(b, k) for b in buildings]) for k in STORY_FIELDS}
        fields["kg"] = t([b.geometric_stiffness() for b in buildings])
        fields["damping"] = t([b.damping_matrix() for b in buildings])
        if any(b.collapse is not None for b in buildings):
            fields["collapse"] = t([b.collapse_values() for b in buildings])
        if any(b.coupling is not None for b in buildings):
            fields["coupling"] = t([b.coupling_matrix() for b in buildings])
        return cls(**fields)

    @property
    def has_collapse(self) -> bool:
        return self.collapse is not None

    def collapse_array(self) -> np.ndarray:
        """``(batch, story, 8)`` collapse gap springs for the compiled simulator (inactive ones when None)."""
        if self.collapse is not None:
            return np.ascontiguousarray(self.collapse.detach().cpu().numpy())
        n = self.mass.shape[-1]
        return np.broadcast_to(no_collapse(n), (self.batch_size, n, no_collapse(n).shape[1])).copy()

    def coupling_array(self) -> np.ndarray:
        """``(batch, story, story)`` coupling ``K_c`` for the compiled simulator (zeros when None)."""
        if self.coupling is not None:
            return np.ascontiguousarray(self.coupling.detach().cpu().numpy())
        n = self.mass.shape[-1]
        return np.zeros((self.batch_size, n, n))

    @property
    def batch_size(self) -> int:
        return int(self.mass.shape[0])

    def index(self, idx) -> BuildingTensors:
        """Select (or repeat) batch rows: ``idx`` is a 1-D index tensor or array."""
        import torch
        idx = torch.as_tensor(idx, dtype=torch.long, device=self.mass.device)
        fields: dict[str, Any] = {f.name: None if getattr(self, f.name) is None else getattr(self, f.name)[idx]
                                  for f in dataclasses.fields(self)}
        return BuildingTensors(**fields)

    def numpy(self) -> dict[str, np.ndarray]:
        """Every field as an array; ``collapse`` and ``coupling`` always (no-loss values, zeros
        when None)."""
        out = {f.name: getattr(self, f.name).detach().cpu().numpy() for f in dataclasses.fields(self)
               if f.name not in ("collapse", "coupling")}
        out["collapse"] = self.collapse_array()
        out["coupling"] = self.coupling_array()
        return out
