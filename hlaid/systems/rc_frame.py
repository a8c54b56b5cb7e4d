"""The reinforced-concrete moment frame: its prior, its collapse law, its default loss inventory."""

from __future__ import annotations

from ..model.collapse import COLLAPSE_MODELS
from ..record import STORY_LAWS
from .parts import (
    EXAMPLE_FLOOR_M2,
    JOINTS_BOTH_SIDES,
    JOINTS_ONE_SIDE,
    OFFICE_NONSTRUCTURAL,
    Component,
    Inventory,
    Median,
    StructuralPrior,
    StructuralSystem,
)

NAME = "rc-frame"

SYSTEM = StructuralSystem(
    name=NAME, title="reinforced-concrete moment frame", collapse=COLLAPSE_MODELS["rc-frame"],
    law=STORY_LAWS["degrading"], damping_max=0.10,
    prior=StructuralPrior(
        name=NAME,
        cy=Median(median=0.2, beta=0.6), alpha=Median(median=0.05, beta=0.7), p=Median(median=1.3, beta=0.7),
        delta_eta=Median(median=1.0, beta=1.0), damping=Median(median=0.05, beta=0.5),
        sources=("Cy: FEMA P695 (2009) RC SMF archetypes (Haselton & Deierlein 2007): Vmax/W about 0.1-0.35",
                 "alpha: post-yield hardening of RC members 2-5 % (Haselton, Liel, Taylor Lange & Deierlein "
                 "2016, ACI Struct. J. 113(6))",
                 "p: round loops of RC members, n about 1-1.5 (Oh, Kim & Song 2023, IJNLM 148:104263)",
                 "delta_eta: unloading stiffness of RC falls with ductility (Takeda, Sozen & Nielsen 1970: "
                 "k_u = k_y (d_max/d_y)^-0.4)",
                 "damping: 5 % (ASCE 7-22; ASCE 41-17 for concrete)")),
    inventory=Inventory(
        NAME, "reinforced concrete special moment frame with post-tensioned slabs, office occupancy",
        (Component("B.10.41.001a", "ea", "1,2", JOINTS_ONE_SIDE, "ACI 318 SMF joint, 24 x 24 in, beam one side"),
         Component("B.10.41.001b", "ea", "1,2", JOINTS_BOTH_SIDES, "ACI 318 SMF joint, 24 x 24 in, beams both sides"),
         Component("B.10.49.031", "ea", "0", 15 / EXAMPLE_FLOOR_M2, "post-tensioned slab-column connection with "
                                                                    "shear reinforcement"))
        + OFFICE_NONSTRUCTURAL, areal_mass_t_m2=0.8),
)
