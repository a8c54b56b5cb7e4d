"""What a joint fit compares: floor accelerations, and story drifts where the records resolve them.

The quantity a clone is judged on is the story drift (damage, collapse and losses rest on it).
Absolute floor accelerations, each normalised by its RMS, weigh a stiff first story's small
relative motion little (its absolute acceleration is mostly the ground's), so a fit of
accelerations alone can put the drift in the wrong story while the floor motion's correlation
stays high. Where a record's floor displacements resolve its story drifts, the fit compares them
too (``refine.compare``, :data:`COMPARES`):

- ``acc``: absolute floor accelerations (the paper's criterion);
- ``acc+drift``: accelerations and story drifts (the measured floor displacements' differences);
- ``disp+drift``: floor displacements relative to the ground and story drifts.

Every channel is band-passed like the replay's and normalised by its RMS (the joint fit's
weighting, :func:`hlaid.joint.series.effective_samples`, counts channels that move as one once).

Whether the measured drifts are usable (:func:`hlaid.hla.preprocess.drift_agreement`):
displacement sensors whose noise scales with a floor's whole motion bury a small story drift (a
superstructure above an isolation layer drifts a few millimetres while its floors move by a
hundred). A story's measured drift is usable where it correlates with the drift of the integrated
accelerations in the band by at least :data:`hlaid.hla.auto.DRIFT_AGREEMENT`; where one story's
does not, the accelerations are integrated for every story (HLA's ``preprocess.displacement``)
and the fit compares accelerations only.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..identify.config import COMPARES
from ..measurement import Measurement, measured_ground
from ..model import Building
from ..signal import bandpass, cap_corner
from ..simulate import simulate_response


def parts(compare: str) -> tuple[str, ...]:
    """The channel groups of ``compare`` (``"acc"``, ``"disp"``, ``"drift"``)."""
    if compare not in COMPARES:
        raise InputError(f"refine.compare = {compare!r}; expected one of {', '.join(map(repr, COMPARES + ('auto',)))}")
    return tuple(compare.split("+"))


class StoryResiduals:
    """Normalised residuals of replays against one measurement's floor accelerations and/or
    floor displacements and story drifts (``compare``, :data:`COMPARES`): the residual unit of an
    :class:`~hlaid.joint.series.EventSeries` with the interface of
    :class:`~hlaid.identify.residuals.ReplayResiduals` (least squares, no ground-noise weighting).

    Parameters
    ----------
    measurement : the record (floor displacements needed for ``disp`` and ``drift``)
    compare : a name in :data:`COMPARES`
    band_hz : band of the compared channels [Hz] (its upper corner capped by the Nyquist rule)
    substeps : RK4 sub-steps per sample of the replays
    """

    def __init__(self, measurement: Measurement, *, compare: str, band_hz=(0.1, 20.0), substeps: int = 4):
        self.what = parts(compare)
        dt = measurement.dt
        self.dt, self.substeps, self.criterion = dt, int(substeps), "ignore"
        self.hi = hi = cap_corner(band_hz[1], dt)
        self.lo = float(band_hz[0])
        self.ground = measured_ground(measurement, hi)
        if measurement.floor_disp is None and ("disp" in self.what or "drift" in self.what):
            raise InputError(f"refine.compare = {compare!r} needs floor displacements; the record has none",
                             source=measurement.source or None)
        targets = []
        if "acc" in self.what:
            targets.append(bandpass(np.asarray(measurement.floor_acc), dt, (self.lo, hi)))
        if "disp" in self.what or "drift" in self.what:
            d = bandpass(np.asarray(measurement.floor_disp), dt, (self.lo, hi))
            if "disp" in self.what:
                targets.append(d)
            if "drift" in self.what:
                targets.append(np.diff(d, axis=1, prepend=0.0))
        self.target = np.concatenate(targets, axis=1)
        rms = np.sqrt(np.mean(self.target**2, axis=0))
        self.scale = np.maximum(rms, 1e-9 * max(float(rms.max()), 1e-300))
        self.stride = 1
        self.whitener = None
        self.channels = self.target.shape[1]
        self.n_residuals = self.target.size

    def _outputs(self, r) -> np.ndarray:
        out = []
        if "acc" in self.what:
            out.append(np.asarray(r.acc))
        if "disp" in self.what:
            out.append(np.asarray(r.disp))
        if "drift" in self.what:
            out.append(np.diff(np.asarray(r.disp), axis=2, prepend=0.0))
        return np.nan_to_num(np.concatenate(out, axis=2))

    def __call__(self, buildings: Sequence[Building], substeps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        res, plain, _ = self.run(buildings, substeps)
        return res, plain

    def run(self, buildings: Sequence[Building], substeps: int | None = None, *, y0: np.ndarray | None = None,
            tail_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`hlaid.identify.residuals.ReplayResiduals.run`: residuals ``(batch, n)``,
        plain costs ``(batch,)`` and the final states ``(batch, 4*story)`` (NaN where a replay
        diverged)."""
        r = simulate_response(list(buildings), self.ground, substeps=self.substeps if substeps is None else substeps,
                              outputs="full", y0=y0, free_vibration=tail_s)
        n_time = self.target.shape[0]
        out = self._outputs(r)[:, :n_time]
        part = bandpass(out, self.dt, (self.lo, self.hi), axis=1)
        part -= self.target[None]
        part /= self.scale
        res = part.reshape(len(part), -1)
        plain = 0.5 * np.sum(res**2, axis=1)
        bad = np.asarray(r.status) != 0
        res[bad] = 1e3
        plain[bad] = np.inf
        final = np.array(r.final_state, dtype=float)
        final[bad] = np.nan
        return res, plain, final


__all__ = ["COMPARES", "StoryResiduals", "parts"]
