"""What a structural system is made of: its prior, its loss inventory and the system itself.

Plain frozen data: each system of :data:`hlaid.systems.SYSTEMS` is one
:class:`StructuralSystem` in a module of its own beside this one. The code that acts on the parts
lives where it acts: the prior's residuals in :mod:`hlaid.joint.priors`, the inventory's CSV and
its checks in :mod:`hlaid.loss.inventory`, the collapse laws in :mod:`hlaid.model.collapse`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..model.collapse import CollapseModel, get_collapse_model
from ..record import STORY_LAWS, StoryLaw


# ----------------------------------------------------------------------------- the prior
@dataclass(frozen=True, kw_only=True)
class Median:
    """A parameter's prior: median (natural units) and standard deviation in prior units."""

    median: float
    beta: float


@dataclass(frozen=True, kw_only=True)
class StructuralPrior:
    """Prior of one structural system (:mod:`hlaid.joint.priors` says how it is used, and
    :func:`hlaid.joint.priors.prior_record` how a clone records it).

    Attributes
    ----------
    name : the structural system (:data:`hlaid.systems.SYSTEMS`; ``identify.system`` in a config)
    cy : base-story yield shear coefficient ``Cy = k0 dy / W`` (lognormal)
    alpha : post-yield stiffness ratio (``beta`` in logit units of ``alpha / 0.95``)
    p : loop smoothness (lognormal in ``p - 1``)
    delta_eta : degradation [s^2/m^2] (lognormal)
    damping : Rayleigh damping ratio (lognormal)
    story_spread : standard deviation of a story's shape parameter around the building's, in
        prior units
    k0_beta : log standard deviation of k0 around its start
    sources : where the values come from
    """

    name: str
    cy: Median
    alpha: Median
    p: Median
    delta_eta: Median
    damping: Median
    story_spread: float = 0.25
    k0_beta: float = 0.5
    sources: tuple[str, ...] = field(default_factory=tuple)


# ----------------------------------------------------------------------------- the loss inventory
M2_PER_FT2 = 0.09290304
EXAMPLE_FLOOR_M2 = 15000 * M2_PER_FT2
"""Floor area of one story of pelicun's FEMA P-58 example building (15 000 ft2)."""

EXAMPLE_TOTAL_M2 = 4 * EXAMPLE_FLOOR_M2


@dataclass(frozen=True)
class Component:
    """A FEMA P-58 fragility group and its density.

    id : FEMA P-58 component ID (pelicun's DLML, ``FEMA P-58 2nd Edition``)
    units : pelicun's quantity unit of ``per_m2`` x m2 (``ea``, ``m``, ``m2``)
    direction : ``"1,2"`` for directional components (the quantity is per direction), ``"0"`` otherwise
    per_m2 : quantity per m2 of floor area on every story (per building when ``building`` is true)
    building : one quantity for the whole building (on the first story), per m2 of total floor area
    what : a short description
    """

    id: str
    units: str
    direction: str
    per_m2: float
    what: str
    building: bool = False


OFFICE_NONSTRUCTURAL = (
    Component("B.20.22.031", "m2", "1,2", 0.26, "curtain wall, midrise stick-built, annealed monolithic glass"),
    Component("C.10.11.001a", "m", "1,2", 891 * 0.3048 / EXAMPLE_FLOOR_M2,
              "gypsum partition with metal studs, full height, fixed below and above"),
    Component("C.30.32.003b", "m2", "0", 1.0, "suspended ceiling, SDC D/E, 250-1000 ft2 rooms, vertical and lateral "
                                              "support"),
    Component("C.30.34.002", "ea", "0", 648 / EXAMPLE_FLOOR_M2, "independent pendant lighting, seismically rated"),
    Component("D.20.21.023a", "m", "0", 1230 * 0.3048 / EXAMPLE_FLOOR_M2, "potable water piping > 2.5 in, SDC D/E/F"),
    Component("D.30.41.021c", "m", "0", 1620 * 0.3048 / EXAMPLE_FLOOR_M2, "HVAC stainless steel ducting < 6 ft2"),
    Component("D.40.11.023a", "m", "0", 4320 * 0.3048 / EXAMPLE_FLOOR_M2, "fire sprinkler mains and branches"),
    Component("D.40.11.033a", "ea", "0", 194 / EXAMPLE_FLOOR_M2, "fire sprinkler drops into soft ceilings"),
    Component("D.10.14.011", "ea", "0", 1 / EXAMPLE_TOTAL_M2, "traction elevator", building=True),
)
"""The non-structural components (office occupancy) of every default inventory: pelicun's shipped
FEMA P-58 example (:mod:`hlaid.loss.inventory` says how the densities were derived)."""

JOINTS_ONE_SIDE, JOINTS_BOTH_SIDES = 2 / EXAMPLE_FLOOR_M2, 3 / EXAMPLE_FLOOR_M2
"""Frame joints per m2, per story and direction: that example's 2 beam-one-side and 3
beams-both-sides joints per 1393.5 m2."""


@dataclass(frozen=True)
class Inventory:
    """A structural system's default inventory and replacement values.

    name, description : the structural system (:data:`hlaid.systems.SYSTEMS`) and what the
        inventory stands for
    components : structural then non-structural :class:`Component` densities
    areal_mass_t_m2 : floor mass per m2 used to estimate floor areas from the clone's masses when
        none are given (typical seismic weight of office floors; an assumption)
    replacement_cost_usd_m2 : replacement cost per m2 of total floor area [USD_2011]
    replacement_time_wd_m2 : replacement time per m2 of total floor area [worker-days]
    """

    name: str
    description: str
    components: tuple
    areal_mass_t_m2: float
    replacement_cost_usd_m2: float = 12.5e6 / EXAMPLE_TOTAL_M2
    replacement_time_wd_m2: float = 15000 / EXAMPLE_TOTAL_M2


INVENTORY_SOURCE = ("inventory: the component set and densities of pelicun's FEMA P-58 example 001 (a 4-story office "
                    "of 15 000 ft2 per floor), its replacement cost and time over its floor area")


# ----------------------------------------------------------------------------- the system
@dataclass(frozen=True, kw_only=True)
class StructuralSystem:
    """A structural system: everything hlaid knows of it, under one name.

    Attributes
    ----------
    name : registry key (``identify.system`` in a config, ``--system`` on the command line)
    title : the system, in words
    collapse : its collapse law (:class:`~hlaid.model.collapse.CollapseModel`, one of
        :data:`hlaid.model.COLLAPSE_MODELS` or its own; None: the Bouc-Wen law alone, no strength
        loss; a name is looked up)
    prior : the identification's prior (:class:`StructuralPrior`)
    law : the story law its stories follow unless the records say otherwise (one of
        :data:`hlaid.record.STORY_LAWS`)
    inventory : the loss assessment's default component inventory, or None (the user gives one)
    damping_max : the largest viscous damping ratio of any mode that the system makes plausible
        at the small amplitudes of the linear system (a clone mode damped more is flagged,
        :mod:`hlaid.model.modes`)
    """

    name: str
    title: str
    collapse: CollapseModel | None
    prior: StructuralPrior
    law: StoryLaw = STORY_LAWS["degrading"]
    inventory: Inventory | None = None
    damping_max: float = 0.2

    def __post_init__(self):
        if not isinstance(self.collapse, (CollapseModel, type(None))):
            object.__setattr__(self, "collapse", get_collapse_model(self.collapse))
        named = {"prior": self.prior.name, **({"inventory": self.inventory.name} if self.inventory else {})}
        for part, name in named.items():
            if name != self.name:
                raise ValueError(f"structural system {self.name!r}: its {part} is named {name!r}")

    @property
    def collapse_name(self) -> str:
        """Its collapse law's name (``"none"``: none)."""
        return "none" if self.collapse is None else self.collapse.name

    @property
    def sources(self) -> tuple[str, ...]:
        """Where the system's numbers come from: its prior's sources, and its inventory's."""
        return self.prior.sources + ((INVENTORY_SOURCE,) if self.inventory is not None else ())


__all__ = ["Component", "EXAMPLE_FLOOR_M2", "EXAMPLE_TOTAL_M2", "INVENTORY_SOURCE", "Inventory", "JOINTS_BOTH_SIDES",
           "JOINTS_ONE_SIDE", "M2_PER_FT2", "Median", "OFFICE_NONSTRUCTURAL", "StructuralPrior", "StructuralSystem"]
