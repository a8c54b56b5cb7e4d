"""Sequential updating: one more event added to a clone.

The clone's posterior is the prior (:func:`~hlaid.joint.vector.prior_of_clone`, over the
entries its stories' laws leave free), the state its last event left the building in is where the
new event's replay starts, and the new event's record is the data; the earlier events' records
check that the Gaussian posterior did not forget them (:mod:`hlaid.events.guard`). On the same
events this agrees with the joint fit of :func:`hlaid.identify_clone` within the clone's
intervals (the joint fit sees every record at once; the update only what the earlier clone kept
of them, its posterior and state).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

from .. import _progress
from ..clone import Clone
from ..errors import InputError, NotIdentifiableError
from ..identify.auto import resolve_like
from ..identify.config import IdentifyConfig
from ..identify.result import IdentificationResult
from ..identify.stages import analyse
from ..joint.fallback import run_stage
from ..joint.fit import best_fit, joint_fit
from ..joint.priors import get_prior
from ..joint.vector import PriorVector, prior_of_clone
from ..measurement import Measurement, check_not_learnt
from ..record import LawChoice
from .guard import check_against_earlier
from .identify import announce, result_of_joint
from .prequential import predicted, with_history


def update_clone(clone: Clone, measurement: Measurement, config: IdentifyConfig | None = None, *,
                 widen: float = 1.0, earlier: Sequence[Measurement] | None = None) -> IdentificationResult:
    """The clone after one more event.

    Parameters
    ----------
    clone : the clone so far
    measurement : the new event (recorded after the clone's last one)
    config : identification settings (its ``refine`` section; ``system``: the clone's own by
        default)
    widen : the clone's posterior standard deviations multiplied by this before the update (1:
        the building changes through its events only, as the model says)
    earlier : the clone's earlier events, in its order (for the check of the update); None: read
        from the files its events name (a missing or changed file: the update is kept unchecked,
        and the clone says so)

    The event is fitted from the clone's carried state and from an undamaged start; the start of
    higher posterior is kept and recorded (``clone.events[-1].start``). Before the fit, the
    clone predicts the event from its carried state and from rest (recorded with the event,
    ``prequential``): the start rule of the updated clone's next prediction
    (:mod:`hlaid.events.prequential`). The stories keep the clone's laws. After the fit, the
    earlier events are replayed by the clone before and after (:mod:`hlaid.events.guard`); where
    their misfit grew by more than the posterior predicted, the update forgot them, and the events
    are fitted jointly again from their records, warm-started at the update.

    Returns
    -------
    IdentificationResult whose ``clone`` has learnt from the clone's events and this one
    """
    settings = resolve_like(clone.settings, measurement, config or IdentifyConfig())
    announce(settings)
    cfg = settings.config
    _check_inputs(clone, measurement, widen, earlier)
    kept = LawChoice.kept_by_update(clone.laws, clone.building.n_stories)
    laws = kept.chosen
    b = clone.building.replace(collapse=None)
    system = get_prior(cfg.system or clone.system or "generic")
    vector = PriorVector(b, damping=cfg.resolved().damping, laws=laws)
    prior = prior_of_clone(clone.uncertainty, b, vector, system, widen)
    y0 = None if clone.state is None else clone.state.vector()
    earlier_names = [e.label(k) for k, e in enumerate(clone.events)]
    name = measurement.name or f"event {len(earlier_names) + 1}"
    notes: list[dict] = []
    _progress.info(f"[update] {b.name or 'clone'}: adding {name}")
    foretold = run_stage(f"the prediction of {name} by the clone", functools.partial(
        predicted, clone, measurement, cfg.hla, earlier_names), None, notes,
        used=f"{name} is not in the start rule's history")
    event = analyse(measurement, cfg)
    fits = [joint_fit(b, [measurement], prior, cfg, y0=y0, names=[name], laws=laws)]
    if y0 is not None:  # the carried state is a hypothesis: the event itself says whether it holds
        fits.append(joint_fit(b, [measurement], prior, cfg, y0=None, names=[name], laws=laws))
    fit = best_fit(fits)
    carried = y0 is not None and fit is fits[0]
    if y0 is not None and not carried:
        _progress.warn(f"{name} is explained better from an undamaged start than from the state the earlier events "
                       "left: the building recovered between them (softening that is not damage)")
    fit = dataclasses.replace(fit, states=[dataclasses.replace(s, events=tuple(earlier_names) + (name,))
                                           for s in fit.states])
    check, stored = check_against_earlier(clone.events, b, fit.building, prior, vector, cfg.resolved(), earlier,
                                          notes)
    history = {len(clone.events): foretold} if foretold is not None else {}
    result = None
    if stored is not None:  # the update forgot the earlier events: all of them fitted jointly again
        meas_all, names = [*stored, measurement], [*earlier_names, name]
        evs = [analyse(m, cfg) for m in stored] + [event]
        joint = run_stage("the joint refit of the stored events", functools.partial(
            joint_fit, fit.building, meas_all, system, cfg, names=names, k0_ref=evs[0].hla.k0, laws=laws), None,
            notes, used="the update is kept", extra=(NotIdentifiableError,))
        if joint is not None:
            check = dataclasses.replace(check, refitted=True)
            result = result_of_joint(evs, meas_all, joint, cfg, system=system, start=fit.building, settings=settings)
            result = dataclasses.replace(result, clone=dataclasses.replace(  # the earlier events as the clone kept them
                result.clone, events=(*clone.events, result.clone.events[-1])))
    if result is None:
        result = result_of_joint([event], [measurement], fit, cfg, system=system, start=b, history=clone.events,
                                 y0=y0 if carried else None, last_start="carried" if carried else "undamaged",
                                 settings=settings)
    return with_history(result, history, laws=kept, notes=notes, update_check=check)


def _check_inputs(clone: Clone, measurement: Measurement, widen: float, earlier) -> None:
    """Refuse an update the clone cannot take: another building, an event it has learnt or one
    recorded before its last, a ``widen`` out of range, ``earlier`` records that do not match."""
    src = measurement.source or None
    n = clone.building.n_stories
    if measurement.n_floors != n:
        raise InputError(f"{measurement.n_floors} floor channels, but the clone has {n} stories: the "
                         "measurement is not of this building", source=src)
    check_not_learnt(clone.events, measurement)
    last = clone.events[-1].recorded if clone.events else None
    if last is not None and measurement.recorded is not None and str(measurement.recorded) <= str(last):
        raise InputError(f"recorded {measurement.recorded}, not after the clone's last event ({last})", source=src)
    if not 0 < widen < 100:
        raise InputError(f"widen = {widen}; expected a factor in (0, 100), 1 for none")
    if earlier is not None and len(earlier) != len(clone.events):
        raise InputError(f"earlier: {len(earlier)} records given for the clone's {len(clone.events)} events")


