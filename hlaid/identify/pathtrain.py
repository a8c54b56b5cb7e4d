"""Path-driven training sets: simulated half cycles along the measured drift path.

The story law is driven along the story's own (reconstructed) drift history with alpha and
p drawn from the class ranges and k0, dy, delta_eta around their estimates
(:func:`hlaid.simulate.path.drive_story`). Every simulated sample then has the measured
half cycles' own paths and differs from the measurement only in the story parameters and
the noise, which is what makes the classes separable (docs/identification.md, Fig. 2).

Features (eq 18, one vector per story): the least-squares slopes of the force on the drift
over ``n_segments`` equal drift increments of every yielding half cycle, divided by ``k0``.
A slope over fixed samples of a fixed path is linear in the force, so all slopes of a story
are one sparse operator ``W`` ``(feature, time)`` built once from the path
(:func:`segment_operator`); measured and simulated features are both ``W @ force / k0``
(:func:`story_features`). Noise enters the simulated features the way it enters the
measured force: white noise on every floor accelerometer, summed over the floors above the
story with their masses (eq 1-2), low-passed like the force.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sps

from .. import _progress
from ..hla.stiffness import segment_index
from ..signal import bandpass
from ..simulate.path import drive_story
from .training import TrainingSet

__all__ = ["StoryPath", "story_paths", "segment_operator", "story_features", "noise_bank", "path_training_set"]


def segment_operator(drift: np.ndarray, bounds: np.ndarray, n_segments: int) -> sps.csr_matrix:
    """Sparse ``(half_cycle * n_segments, time)`` operator of the segment slopes.

    Row ``j * n_segments + q`` applied to a force history gives the least-squares slope of
    that force on ``drift`` over segment ``q`` of half cycle ``j`` (``bounds[j]`` inclusive
    sample indices), exactly as :func:`hlaid.hla.stiffness.segment_slopes`: the samples
    whose drift lies in the segment's share of the half cycle's increment, widened by one
    neighbour on each side. A segment with fewer than three samples gives a zero row.
    """
    rows, cols, vals = [], [], []
    for j, (s, e) in enumerate(np.asarray(bounds, dtype=int)):
        acc = np.maximum.accumulate(segment_index(drift, s, e, n_segments))
        first = np.searchsorted(acc, np.arange(n_segments), side="left")
        last = np.searchsorted(acc, np.arange(n_segments), side="right")
        for q in range(n_segments):
            lo, hi = max(first[q] - 1, 0), min(last[q] + 1, e - s + 1)
            if hi - lo < 3:
                continue
            xs = drift[s + lo:s + hi]
            xm = xs - xs.mean()
            den = float(xm @ xm)
            if den <= 0:
                continue
            rows.append(np.full(hi - lo, j * n_segments + q))
            cols.append(np.arange(s + lo, s + hi))
            vals.append(xm / den)
    n_rows = len(bounds) * n_segments
    if not rows:
        return sps.csr_matrix((n_rows, drift.shape[0]))
    return sps.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(n_rows, drift.shape[0]))


def story_features(operator: sps.csr_matrix, force: np.ndarray, k0: float) -> np.ndarray:
    """Features ``W @ f / k0`` of force histories ``(time,)`` or ``(time, batch)``:
    ``(feature,)`` or ``(batch, feature)``. The one function for measured and simulated data."""
    out = operator @ np.asarray(force, dtype=float) / k0
    return out if out.ndim == 1 else out.T


@dataclass(frozen=True, eq=False)
class StoryPath:
    """What the path-driven training of one story needs.

    Attributes
    ----------
    drift : (time,) the drift path [mm] (reconstructed, see :mod:`hlaid.identify.drift`)
    force : (time,) the measured story force, low-passed only [N]
    bounds : (half_cycle, 2) inclusive sample bounds of the yielding half cycles
    k0 : the story's initial stiffness estimate [N/mm] (feature scale)
    mass : floor mass above the story [t]
    noise_std : std of the white noise on the story force [N] (before low-pass)
    dt : sample interval [s]; cutoff_hz : low-pass corner of the force [Hz]
    n_segments : segments per half cycle
    """

    drift: np.ndarray
    force: np.ndarray
    bounds: np.ndarray
    k0: float
    mass: float
    noise_std: float
    dt: float
    cutoff_hz: float
    n_segments: int = 10

    @property
    def end(self) -> int:
        """One past the last sample any feature uses: the path is driven up to here."""
        return int(np.max(self.bounds[:, 1])) + 2 if len(self.bounds) else 0

    @cached_property
    def operator(self) -> sps.csr_matrix:
        """The segment operator ``W`` of this path (built once)."""
        return segment_operator(self.drift[: self.end], self.bounds, self.n_segments)

    def measured_features(self) -> np.ndarray:
        """``(feature,)`` features of the measured force."""
        return story_features(self.operator, self.force[: self.end], self.k0)


def story_paths(stories, selected, *, mass: np.ndarray, k0: np.ndarray, floor_acc: np.ndarray, noise_rms: float,
                dt: float, cutoff_hz: float, n_segments: int, identifiable: np.ndarray | None = None) -> list:
    """The :class:`StoryPath` of every story (None where not ``identifiable``).

    Parameters
    ----------
    stories : per story a :class:`~hlaid.hla.StoryHLA` whose ``drift`` is the path
    selected : per story the yielding half cycles (:class:`~hlaid.hla.features.HalfCycleFeatures`)
    mass, k0 : (story,) floor masses [t] and initial stiffness estimates [N/mm]
    floor_acc : (time, floor) the measured floor accelerations: the story force noise is
        ``noise_rms`` x each floor's RMS, summed over the floors above with their masses (eq 1-2)
    """
    acc = np.asarray(floor_acc)
    rms = np.sqrt(np.mean((acc - acc.mean(axis=0)) ** 2, axis=0))
    out: list[StoryPath | None] = []
    for i, (s, F) in enumerate(zip(stories, selected)):
        if identifiable is not None and not identifiable[i]:
            out.append(None)
            continue
        hc = s.half_cycles
        out.append(StoryPath(drift=s.drift, force=s.force,
                             bounds=np.stack([hc.start[F.index], hc.end[F.index]], axis=1),
                             k0=float(k0[i]), mass=float(mass[i]),
                             noise_std=noise_rms * float(np.sqrt(np.sum((mass[i:] * rms[i:]) ** 2))), dt=dt,
                             cutoff_hz=cutoff_hz, n_segments=n_segments))
    return out


def noise_bank(n_time: int, dt: float, cutoff_hz: float, *, size: int = 256, seed: int = 0) -> np.ndarray:
    """``(n_time, size)`` unit-variance white-noise histories low-passed at ``cutoff_hz``, as
    the measured force is. One bank serves every story and pass of a run
    (:func:`path_training_set` takes the first ``end`` samples and scales them by the story's
    noise std): filtering it once instead of per story and pass saves ~0.6 s per identification."""
    white = np.random.default_rng(seed).standard_normal((int(n_time), int(size)))
    return bandpass(white, dt, (0.0, cutoff_hz))


def _noise_features(sp: StoryPath, op, n: int, rng: np.random.Generator, bank: np.ndarray | None = None) -> np.ndarray:
    """``(n, feature)`` Gaussian noise features with the covariance of ``W @ lowpass(white) / k0``.

    The histories of ``bank`` (:func:`noise_bank`; None: 256 drawn here from ``rng``) go through
    the operator once; each sample is a random unit-variance combination of them (Gaussian,
    same covariance as one history).
    """
    if sp.noise_std <= 0:
        return np.zeros((n, op.shape[0]))
    if bank is None:
        bank = noise_bank(op.shape[1], sp.dt, sp.cutoff_hz, seed=int(rng.integers(2**32)))
    elif bank.shape[0] < op.shape[1]:
        raise ValueError(f"noise bank of {bank.shape[0]} samples for a path of {op.shape[1]}")
    feats = story_features(op, bank[: op.shape[1]] * sp.noise_std, sp.k0)  # (size, feature)
    w = rng.standard_normal((n, bank.shape[1])) / np.sqrt(bank.shape[1])
    return w @ feats


def path_training_set(sp: StoryPath, *, k0: float, dy: float, delta_eta: float, alpha_range, p_range,
                      n_samples: int, spread: float, seed: int, substeps: int = 4,
                      wide: float | None = None, noise: np.ndarray | None = None) -> TrainingSet:
    """``n_samples`` simulated feature vectors of one story along its path.

    alpha and p are drawn uniformly from their ranges (the class targets); k0, dy and
    delta_eta uniformly within ``+-spread`` (relative) of the given estimates, or, with
    ``wide``, dy and delta_eta log-uniformly within a factor ``wide`` of them (a first pass,
    whose estimates of dy and delta_eta are still rough).

    ``noise``: a :func:`noise_bank` at least ``sp.end`` long, shared by the passes of a run
    (None: one is drawn for this set).
    """
    rng = np.random.default_rng(seed)
    a = rng.uniform(alpha_range[0], alpha_range[1], n_samples)
    p = rng.uniform(p_range[0], p_range[1], n_samples)

    def jitter(v):
        return v * rng.uniform(1.0 - spread, 1.0 + spread, n_samples)

    def draw(v):
        if wide is None:
            return jitter(v)
        return max(v, 1e-3) * np.exp(rng.uniform(-np.log(wide), np.log(wide), n_samples))

    x = sp.drift[: sp.end]
    resp = drive_story(x, k0=jitter(k0), alpha=a, p=p, dy=draw(dy), delta_eta=draw(max(delta_eta, 0.1)), mass=sp.mass,
                       dt=sp.dt, substeps=substeps, state=False)
    op = sp.operator
    X = story_features(op, resp.force.T, sp.k0) + _noise_features(sp, op, n_samples, rng, noise)
    # a draw whose story law blows up along this path (a dy far below the path's sample-to-sample
    # increments overshoots the yield surface in one step) is no sample of the class: left out
    ok = np.isfinite(X).all(axis=1)
    if not ok.all():
        _progress.debug(f"  path-driven training: {int(np.sum(~ok))} of {n_samples} samples diverged along the "
                        "path and are left out")
    return TrainingSet(X=X[ok], alpha=a[ok], p=p[ok], sim=np.flatnonzero(ok))

