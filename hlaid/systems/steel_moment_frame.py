"""The steel moment-resisting frame: its prior, its collapse law, its default loss inventory."""

from __future__ import annotations

from ..model.collapse import COLLAPSE_MODELS
from ..record import STORY_LAWS
from .parts import (
    JOINTS_BOTH_SIDES,
    JOINTS_ONE_SIDE,
    OFFICE_NONSTRUCTURAL,
    Component,
    Inventory,
    Median,
    StructuralPrior,
    StructuralSystem,
)

NAME = "steel-moment-frame"

SYSTEM = StructuralSystem(
    name=NAME, title="steel moment-resisting frame", collapse=COLLAPSE_MODELS["steel-mrf"], law=STORY_LAWS["degrading"],
    damping_max=0.10,
    prior=StructuralPrior(
        name=NAME,
        cy=Median(median=0.3, beta=0.6), alpha=Median(median=0.1, beta=0.7), p=Median(median=2.0, beta=0.7),
        delta_eta=Median(median=0.1, beta=1.0), damping=Median(median=0.025, beta=0.5),
        sources=("Cy: FEMA P695 (2009) / NIST GCR 10-917-8 (2010) steel SMF archetypes, static overstrength "
                 "1.6-3.3 over Cs 0.044-0.125 (Vmax/W about 0.1-0.4); the E-Defense steel frame of Table 1 of "
                 "the paper: 0.31 (base story)",
                 "alpha: story hardening of steel frames 3-10 % of the elastic stiffness (FEMA P-440A 2009; "
                 "Ibarra, Medina & Krawinkler 2005: 3 %), Table 1: 0.12-0.23",
                 "p: Table 1: 1.5-2.5 (a near-bilinear loop, p > 3, is as likely as a round one, p < 1.5)",
                 "delta_eta: steel members keep their unloading stiffness (Lignos & Krawinkler 2011, J. Struct. "
                 "Eng. 137(11): unloading-stiffness deterioration of steel beams negligible)",
                 "damping: 2-3 % for steel buildings (ATC-72-1 2010; PEER TBI 2017: 2.5 %)")),
    inventory=Inventory(
        NAME, "steel special moment frame, office occupancy",
        (Component("B.10.35.021", "ea", "1,2", JOINTS_ONE_SIDE, "post-Northridge WUF moment connection, beam one "
                                                                "side, <= W27"),
         Component("B.10.35.031", "ea", "1,2", JOINTS_BOTH_SIDES, "post-Northridge WUF moment connection, beams both "
                                                                  "sides, <= W27"))
        + OFFICE_NONSTRUCTURAL, areal_mass_t_m2=0.5),
)
