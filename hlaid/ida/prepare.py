"""The building an IDA runs: a clone or building with P-Delta, heights, gravity loads and the
collapse model resolved, and notes on what was decided (:func:`prepare_building`)."""

from __future__ import annotations

import os

import numpy as np

from ..clone import Clone
from ..errors import InputError
from ..limits import check_count
from ..model import Building
from ..model.collapse import accommodate, get_collapse_model
from .capacity import chosen_law, law_posterior


def prepare_building(model: Clone | Building | str | os.PathLike, *, pdelta: bool | None = None,
                     heights=None, gravity_load=None, require_heights: bool = True,
                     collapse=None) -> tuple[Building, list[str]]:
    """The building an IDA runs, with P-Delta resolved, and notes on what was decided.

    P-Delta (``pdelta=None``): on when story heights are known, even when a clone file says
    ``pdelta: false`` (clones identified from P-Delta-free responses store false). For a
    mass-normalised clone the default gravity loads, relative mass x g, are per unit of total
    mass like its stiffnesses, so P-Delta stays consistent; absolute gravity loads [N] cannot be
    combined with it. Story heights are required (``require_heights``): IDA reports drift ratios.
    ``collapse`` (a name, a mapping or a CollapseModel; see :mod:`hlaid.model.collapse`) replaces
    the clone's strength-loss model; None keeps the clone's, else the collapse law of the
    clone's structural system (``clone.system``), else ``none``. The law in force is conditioned
    on the drifts the building was measured to survive (:mod:`hlaid.model.capacity`: its capping
    drift's posterior median, never below a drift a story came through intact), with a note
    saying how.
    """
    source = None
    if isinstance(model, (str, os.PathLike)):
        source = str(model)
        model = Clone.load(model)
    system = None
    if isinstance(model, Clone):
        building, normalised, system = model.building, model.mass_normalised, model.system
    elif isinstance(model, Building):
        building, normalised = model, False
    else:
        raise InputError(f"expected a Clone, a Building or a clone file, got {type(model).__name__}")
    source = source or building.source
    check_count(building.n_stories, "STORIES", "stories", source=source)
    notes: list[str] = []
    law = building.collapse  # resolved below, once the heights are known and against them
    building = building.replace(collapse=None)
    if heights is not None:
        building = building.replace(height=heights)
    if gravity_load is not None:
        building = building.replace(gravity_load=gravity_load)
    if building.height is None and require_heights:
        raise InputError("story heights are unknown; IDA reports drift ratios and needs them: give the heights "
                         "in mm, bottom to top: IDAConfig(heights_mm=[...])", source=source)
    want = (building.height is not None) if pdelta is None else bool(pdelta)
    if want and building.height is None:
        raise InputError("P-Delta needs story heights: give the heights in mm, bottom to top, "
                         "IDAConfig(heights_mm=[...]), or leave P-Delta out, IDAConfig(pdelta=False)",
                         source=source)
    if normalised and gravity_load is not None:
        raise InputError("the clone is mass-normalised (forces per unit of total mass): absolute gravity loads "
                         "cannot be combined with it; leave IDAConfig(gravity_kN=[...]) out (gravity is taken as "
                         "relative mass x g, per unit mass like the clone)", source=source)
    if want and normalised:
        notes.append("mass-normalised clone: P-Delta from relative mass x g, per unit of total mass")
    if want and pdelta is None and building.pdelta is False:
        notes.append("P-Delta on (story heights known) although the clone says pdelta: false "
                     "(identification without P-Delta); to keep it off set pdelta: false in the IDA settings (ida: "
                     "{pdelta: false} in a run config, hlaid ida --no-pdelta, IDAConfig(pdelta=False))")
    elif not want:
        notes.append("P-Delta off" + (" (requested)" if pdelta is False else " (story heights unknown)"))
    building = building.replace(pdelta=want)
    if want:
        kg, k0 = building.geometric_stiffness(), np.asarray(building.k0, dtype=float)
        k = int(np.argmax(kg / k0))
        if kg[k] >= k0[k]:
            raise InputError(f"the gravity load gives story {k + 1} a P-Delta stiffness P/h = {kg[k]:.4g} N/mm, not "
                             f"below its elastic stiffness k0 = {k0[k]:.4g} N/mm: the building would buckle under its "
                             "own weight; check the gravity loads (gravity_kN) and story heights", source=source)
    building = building.replace(collapse=_collapse_law(model, building, law, collapse, system, notes, source))
    if want:
        kg = building.geometric_stiffness()
        post = building.alpha * building.k0 - kg
        notes.append("P-Delta on: P/h = " + ", ".join(f"{v:.4g}" for v in kg) + " N/mm per story")
        if np.all(post > 0) and building.collapse is None:
            notes.append("every story keeps a positive post-yield stiffness alpha*k0 - P/h: collapse can "
                         "only come from the drift limit or the slope criterion")
    return building, notes


def _collapse_law(model, building: Building, law, collapse, system: str | None, notes: list[str],
                  source: str | None = None):
    """The collapse law in force: ``collapse`` where given, else the clone's own, else its
    structural system's; conditioned on the drifts the building was measured to survive
    (:func:`hlaid.ida.capacity.law_posterior`); with notes."""
    if collapse is not None:
        law = get_collapse_model(collapse)
    elif law is None and system is not None:
        law = chosen_law(model, None, notes)
    if law is not None and building.height is not None:
        try:
            post = law_posterior(model, law, building)
        except InputError as err:  # said of the clone whose events give the drifts
            if err.source:
                raise
            raise InputError(f"{err} (the drifts of the clone's recorded events)", source=source) from None
        if post.informative:
            notes.append(post.note())
        law, changed = accommodate(post.conditioned(), dy=building.dy, height=building.height)
        notes.extend(changed)
    c = building.replace(collapse=law).collapse  # as the building holds it
    if c is None:
        notes.append("collapse model 'none': the stories never lose strength, so collapse comes only from the "
                     "drift limit or the slope criterion (optimistic); choose one with collapse: steel-mrf, "
                     "rc-frame, rc-frame-nonductile or your own ratios (docs/collapse.md)")
    else:
        notes.append(f"collapse model {c.name!r}: cap at dy/h + {c.theta_p:.4g}, post-capping drift {c.theta_pc:g} "
                     f"to zero strength, residual {c.kappa:g} k0 dy, ultimate drift {c.theta_u:.4g}")
    return law
