"""Did a sequential update forget what the earlier events said?

A sequential update keeps of the earlier events only the clone's Gaussian posterior. Where the
new event pulls the parameters far (a softening the model reads as yielding: the hotel's fifth
event drove ``p`` from 1.9 to 6.3 and ``dy`` from 0.5 to 0.15 mm, and the next prediction fell to
R 0.18), the Gaussian no longer says what the earlier records would: their misfit grows by much
more than the posterior predicts. :func:`check_update` measures that on the records themselves:
the earlier events (read again from their files, checked against the SHA-256 of their ground
record the clone keeps) are replayed by the clone before and after the update, and the change
of their log misfit ``sum_e n_e / 2 log(SS_e(after) / SS_e(before))`` is compared with the
Gaussian's prediction ``1/2 |L^-1 (x_after - x_before)|^2`` (``L`` the posterior's Cholesky
factor in prior units). Where the excess is more than ``max(`` :data:`EXCESS_MIN` ``, the
prediction)``, :func:`hlaid.update_clone` refits jointly from the stored events, warm-started at
the update. Where a file is missing or changed, the update is kept and the clone says so.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from .. import _progress
from ..identify.config import ResolvedSettings
from ..joint.fallback import run_stage
from ..joint.series import at_replay_rate, effective_samples, event_series
from ..joint.vector import GaussianPrior, PriorVector
from ..measurement import Measurement, ground_digest
from ..model import Building
from ..record import EventRecord, UpdateCheck

EXCESS_MIN = 5.0
"""The earlier events' log-misfit change may exceed the Gaussian's prediction by this much (or
by the prediction itself, where larger) before the update is refitted jointly: the hotel's
run-off update exceeded it by 16, its sound updates by 0.4-4.5."""


def load_earlier(events: Sequence[EventRecord], given: Sequence[Measurement] | None = None
                 ) -> tuple[list[Measurement], list[str]]:
    """The earlier events of a clone (its ``events`` records) as measurements: ``given`` (in the
    same order) where passed, else read again from each record's ``source``
    (:func:`hlaid.events.evidence.read_event`); each checked against the SHA-256 of its ground
    record. Returns the events found (all or none: a history with a gap is no history) and a note
    per one missing or changed."""
    from .evidence import read_event

    found, missing = [], []
    for k, e in enumerate(events):
        name = e.label(k)
        if given is not None and k < len(given):
            m: Measurement | None = given[k]
            why = None
            if e.ground_sha256 is not None and ground_digest(given[k]) != e.ground_sha256:
                m, why = None, (f"{name}: the record given is not the event the clone learnt from (SHA-256 of its "
                                "ground record differs)")
        else:
            m, why = read_event(e, name=name)
        if m is None:
            missing.append(str(why))
        else:
            found.append(m)
    return (found, missing) if not missing else ([], missing)


def check_update(before: Building, after: Building, earlier: Sequence[Measurement], prior: GaussianPrior,
                 vector: PriorVector, *, band_hz, compare: str = "acc", y0: np.ndarray | None = None) -> UpdateCheck:
    """The earlier events' log-misfit change against the Gaussian's prediction (see the module)."""
    hi = float(band_hz[1])
    series = event_series(before, [at_replay_rate(m, hi) for m in earlier], band_hz, "ignore", 4, 2, y0, None,
                          compare=compare)
    parts, _, _ = series.run([before, after])  # one batch
    n_eff = np.array([effective_samples(p[0].reshape(-1, ev.channels)) for p, ev in zip(parts, series.events)])
    ss0 = np.array([float(np.sum(p[0] ** 2)) for p in parts])
    ss1 = np.array([float(np.sum(p[1] ** 2)) for p in parts])
    exact = float(np.sum(0.5 * n_eff * np.log(np.maximum(ss1, 1e-300) / np.maximum(ss0, 1e-300))))
    dz = prior.residuals(vector.of(after)) - prior.residuals(vector.of(before))
    gauss = 0.5 * float(np.sum(dz**2))
    excess = exact - gauss
    limit = max(EXCESS_MIN, gauss)
    refit = bool(not np.isfinite(exact) or excess > limit)
    _progress.info(f"[update] the earlier {len(earlier)} event(s)' log misfit changed by {exact:+.1f}, the posterior "
                   f"predicted {gauss:.1f}" + (": it forgot them, refitted jointly" if refit else ""))
    return UpdateCheck(events=len(earlier), misfit_change=exact if np.isfinite(exact) else None, gaussian=gauss,
                       excess=excess if np.isfinite(excess) else None, limit=limit, refit=refit)


def check_against_earlier(events: Sequence[EventRecord], before: Building, after: Building, prior,
                          vector: PriorVector, settings: ResolvedSettings, earlier: Sequence[Measurement] | None,
                          notes: list[dict]) -> tuple[UpdateCheck, list[Measurement] | None]:
    """The check of an update from ``before`` to ``after`` against the clone's earlier ``events``
    (:func:`check_update`; their records ``earlier``, None: read again from their files) and those
    records where it calls for a joint refit (else None). A stage that fails numerically is noted
    in ``notes``."""
    n = len(events)
    if not events:
        return UpdateCheck(events=0, note="the clone has no earlier events"), None
    if not isinstance(prior, GaussianPrior):
        return UpdateCheck(events=n, note="the clone keeps no posterior: the update is a fit from the structural "
                                          "system's prior, nothing to forget"), None
    stored, missing = load_earlier(events, earlier)
    if missing:
        _progress.warn("the update is not checked against the earlier events: " + "; ".join(missing[:3]))
        return UpdateCheck(events=n, missing=tuple(missing),
                           note="the earlier events' records are not all at hand: the update is kept unchecked"), None
    check = run_stage("the check of the update against the earlier events", functools.partial(
        check_update, before, after, stored, prior, vector, band_hz=settings.band_hz, compare=settings.compare), None,
        notes, used="the update is kept unchecked")
    if check is None:
        return UpdateCheck(events=n, note="the check failed numerically: the update is kept"), None
    return check, (stored if check.refit else None)


__all__ = ["EXCESS_MIN", "load_earlier", "check_update", "check_against_earlier"]
