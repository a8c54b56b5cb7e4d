"""Errors of the reconstructed drift path, simulated (``training.path_errors``).

The measured features of a story are segment slopes along the *reconstructed* drift path
(:mod:`hlaid.identify.drift`), which differs from the story's true drift: HLA's drift is the
doubly integrated, high-passed relative acceleration of noisy sensors, and the replayed
estimate below the crossover is only the estimate's. The measured force, though, is the
story law driven along the *true* drift. A training sample driven along the path itself
lacks that difference (errors in the variables), so its features and the measured ones
differ by more than the story parameters and the force noise.

Here the measurement process is repeated on the current estimate, whose drift is known:
the estimate replayed on the measured ground motion, the measurement's noise level on the
simulated ground and floor accelerations, HLA with the measurement's band, and the same path
(HLA's drift, or the reconstruction with the estimate). ``delta = path - true drift`` of
each such pseudo-measurement is one realistic error history. A training sample is then
driven along ``path - delta_k`` (the true drift that the measured path would have, had it
carried error ``delta_k``) while its features are taken with the operator ``W`` of the path
itself, as the measured ones are (:func:`hlaid.identify.pathtrain.path_training_set`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..hla import HLAConfig, HLAResult, run_hla
from ..measurement import measured_ground
from ..model import Building
from ..motions import GroundMotion
from ..synthetic import simulate_measurement
from .drift import hla_drift, reconstruct_drift

__all__ = ["path_error_bank"]


def path_error_bank(res: HLAResult, ground: GroundMotion, estimate: Building, *, noise_rms: float, n: int,
                    seed: int, reconstruct, crossover_hz: float, hla_config: HLAConfig) -> np.ndarray:
    """``(history, time, story)`` simulated errors ``path - true drift`` of the drift path [mm].

    Parameters
    ----------
    res : HLA of the measurement (its band and length are reused)
    ground : the measured ground motion (low-passed), the excitation of the pseudo-measurements
    estimate : the current building estimate (the pseudo-measurements' truth)
    noise_rms : sensor noise as a fraction of channel RMS (the measurement's level)
    n : number of error histories; seed : seed of the first one's noise (then ``seed + k``)
    reconstruct : bool or ``(story,)`` bools: the story's path is the reconstruction with
        ``estimate`` (else HLA's drift), as the measurement's path of that story is
    crossover_hz : corner of the reconstruction's complementary filters [Hz]
    hla_config : the identification's HLA settings (the band is fixed to ``res.band_hz``)

    Returns
    -------
    ``(k, time, story)`` with ``k <= n``: pseudo-measurements whose simulation or HLA fails
    are left out (``k = 0``: none succeeded).
    """
    lo, hi = (float(f) for f in res.band_hz)
    cfg = dataclasses.replace(hla_config, preprocess=dataclasses.replace(hla_config.preprocess, band_hz=(lo, hi)))
    T, S = res.stories[0].drift.shape[0], res.n_stories
    rec = np.broadcast_to(np.asarray(reconstruct, dtype=bool), (S,))
    out = []
    for k in range(n):
        try:
            meas = simulate_measurement(estimate, ground, rate_hz=None, noise_rms=noise_rms, seed=seed + k)
            r = run_hla(meas, cfg)
        except ValueError:  # InputError, or HLA's fits on an unlucky noise draw: leave it out
            continue
        assert meas.truth is not None  # simulated
        path = hla_drift(r)
        if np.any(rec):
            path = np.where(rec[None, :], reconstruct_drift(r, measured_ground(meas, r.band_hz[1]), estimate,
                                                            crossover_hz=crossover_hz), path)
        delta = np.zeros((T, S))
        m = min(T, path.shape[0])
        delta[:m] = path[:m] - meas.truth.drift[:m]
        out.append(delta)
    return np.stack(out) if out else np.zeros((0, T, S))
