"""Sequential updating: one more event added to a clone.

The clone's posterior is the prior (:func:`~hlaid.events.vector.prior_of_clone`), the state
its last event left the building in is where the new event's replay starts, and the new
event's record is the data. On the same events this agrees with the joint fit of
:func:`hlaid.identify_clone` within the clone's intervals (the joint fit sees every
record at once; the update only what the earlier clone kept of them, its posterior and state).
"""

from __future__ import annotations

import dataclasses

from .. import _progress
from ..clone import Clone
from ..errors import InputError
from ..hla.config import fixed
from ..identify.auto import resolve_like
from ..identify.config import IdentifyConfig
from ..identify.result import IdentificationResult
from ..identify.stages import analyse
from ..measurement import Measurement, check_not_learnt
from .fit import best_fit, joint_fit
from .identify import announce, result_of_joint, with_choices
from .priors import get_prior
from .vector import PriorVector, prior_of_clone


def update_clone(clone: Clone, measurement: Measurement, config: IdentifyConfig | None = None, *,
                 widen: float = 1.0) -> IdentificationResult:
    """The clone after one more event.

    Parameters
    ----------
    clone : the clone so far
    measurement : the new event (recorded after the clone's last one)
    config : identification settings (its ``refine`` section; ``system``: the clone's own by
        default)
    widen : the clone's posterior standard deviations multiplied by this before the update (1:
        the building changes through its events only, as the model says)

    The event is fitted from the clone's carried state and from an undamaged start; the start of
    higher posterior is kept and recorded (``clone.events[-1]["start"]``): a building whose
    softening during an event recovers before the next (most buildings in small events) is
    predicted from an undamaged start by ``start="auto"``.

    Returns
    -------
    IdentificationResult whose ``clone`` has learnt from the clone's events and this one
    """
    settings = resolve_like(clone.provenance, measurement, config or IdentifyConfig())
    announce(settings)
    cfg = settings.config
    b = clone.building
    src = measurement.source or None
    if measurement.n_floors != b.n_stories:
        raise InputError(f"{measurement.n_floors} floor channels, but the clone has {b.n_stories} stories: the "
                         "measurement is not of this building", source=src)
    check_not_learnt(clone.events, measurement)
    last = clone.events[-1].get("recorded") if clone.events else None
    if last is not None and measurement.recorded is not None and str(measurement.recorded) <= str(last):
        raise InputError(f"recorded {measurement.recorded}, not after the clone's last event ({last})", source=src)
    if not 0 < widen < 100:
        raise InputError(f"widen = {widen}; expected a factor in (0, 100), 1 for none")
    b = b.replace(collapse=None)
    system = get_prior(cfg.system or clone.system or "generic")
    vector = PriorVector(b, damping=fixed(cfg.refine.damping, "refine.damping"))
    prior = prior_of_clone(clone.uncertainty, b, vector, system, widen)
    y0 = None if clone.state is None else clone.state.vector()
    earlier = [e.get("name") or f"event {k + 1}" for k, e in enumerate(clone.events)]
    name = measurement.name or f"event {len(earlier) + 1}"
    _progress.info(f"[update] {b.name or 'clone'}: adding {name}")
    event = analyse(measurement, cfg)
    fits = [joint_fit(b, [measurement], prior, cfg, y0=y0, names=[name])]
    if y0 is not None:  # the carried state is a hypothesis: the event itself says whether it holds
        fits.append(joint_fit(b, [measurement], prior, cfg, y0=None, names=[name]))
    fit = best_fit(fits)
    carried = y0 is not None and fit is fits[0]
    if y0 is not None and not carried:
        _progress.warn(f"{name} is explained better from an undamaged start than from the state the earlier events "
                       "left: the building recovered between them (softening that is not damage); predictions from "
                       "this clone start undamaged (start 'auto')")
    fit = dataclasses.replace(fit, states=[dataclasses.replace(s, events=tuple(earlier) + (name,))
                                           for s in fit.states])
    return with_choices(result_of_joint([event], [measurement], fit, cfg, system=system, start=b,
                                        history=clone.events, y0=y0 if carried else None,
                                        last_start="carried" if carried else "undamaged"), settings)
