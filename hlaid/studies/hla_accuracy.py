"""Accuracy of hysteresis loop analysis against the truth of simulated measurements.

``scripts/study_hla_accuracy.py`` runs the study and prints its table (``docs/hla.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hla import HLAResult
from ..measurement import Truth


@dataclass(frozen=True)
class HLAErrors:
    """Errors of HLA against the simulated truth, each ``(story,)``.

    Attributes
    ----------
    k0 : relative error of k0 (signed)
    ke_median : median over half cycles of ``|ke / ke_true - 1|`` with
        ``ke_true = alpha k0 + (1-alpha) k0 / eta(t_start)`` (eq 11)
    force_nrmse : RMS of (force - true spring force) over the RMS of the true force
    force_nrmse_range : the same RMS error over the range (max - min) of the true force
    """

    k0: np.ndarray
    ke_median: np.ndarray
    force_nrmse: np.ndarray
    force_nrmse_range: np.ndarray


def hla_errors(result: HLAResult, truth: Truth) -> HLAErrors:
    """Compare an :class:`HLAResult` with the :class:`~hlaid.measurement.Truth` it came from."""
    b = truth.building
    k0, ke, nr, nrr = [], [], [], []
    for i, s in enumerate(result.stories):
        k0.append(s.k0 / b.k0[i] - 1.0)
        hc = s.half_cycles
        ke_true = b.alpha[i] * b.k0[i] + (1 - b.alpha[i]) * b.k0[i] / truth.eta[hc.start, i]
        ke.append(float(np.median(np.abs(hc.ke / ke_true - 1.0))) if len(hc) else np.nan)
        err = np.sqrt(np.mean((s.force - truth.force[:, i]) ** 2))
        nr.append(err / np.sqrt(np.mean(truth.force[:, i] ** 2)))
        nrr.append(err / np.ptp(truth.force[:, i]))
    return HLAErrors(*(np.asarray(v) for v in (k0, ke, nr, nrr)))


def accuracy_study(building, motions, seeds, *, noise_rms: float = 0.10, config=None, pga_g: float | None = 0.62,
                   rate_hz: float = 200.0) -> dict[tuple[str, int], HLAErrors]:
    """HLA errors on simulated measurements of ``building`` for every motion x noise seed."""
    from ..hla import run_hla
    from ..synthetic import simulate_measurement

    out = {}
    for gm in motions:
        g = gm.scaled_to_pga(pga_g) if pga_g else gm
        for seed in seeds:
            meas = simulate_measurement(building, g, rate_hz=rate_hz, noise_rms=noise_rms, seed=seed)
            assert meas.truth is not None  # a simulated measurement carries its truth
            out[(gm.name, seed)] = hla_errors(run_hla(meas, config), meas.truth)
    return out


def summarise(errors: dict[tuple[str, int], HLAErrors]) -> dict[str, dict[str, float]]:
    """Mean and worst (over runs and stories) of each error in absolute value."""
    out = {}
    for field in ("k0", "ke_median", "force_nrmse", "force_nrmse_range"):
        a = np.abs(np.stack([getattr(e, field) for e in errors.values()]))
        out[field] = {"mean": float(np.nanmean(a)), "worst": float(np.nanmax(a)),
                      "mean_per_story": np.nanmean(a, axis=0).tolist()}
    return out
