"""Hysteresis loop analysis of a measurement: ``run_hla(measurement, config) -> HLAResult``.

Steps (docs/DESIGN.md section 5): band-pass and integrate the accelerations to floor motion
relative to the ground; inter-story drift and drift velocity; story restoring force
``f_i = -sum_{j>=i} m_j a_j`` (eq 1-2) less its damping share and plus the P-Delta share;
half cycles between drift reversals; per half cycle the elastic stiffness ``ke`` after the
reversal, along it the tangent stiffness ``k(t)``; the initial stiffness ``k0`` from the
elastic stiffness before degradation sets in.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import cast

import numpy as np
import torch
from scipy import integrate

from ..errors import InputError
from ..measurement import Measurement
from ..model import structure
from ..signal import bandpass, integrate_twice
from ..units import G_MM_S2
from . import preprocess as pp
from .config import AUTO, HLAConfig
from .halfcycles import half_cycle_bounds
from .result import HalfCycleTable, HLAResult, StoryHLA
from .stiffness import degradation_trend, elastic_window, isotonic_decreasing, sliding_slope, slope_with_drift_check


def floor_masses(meas: Measurement, cfg: HLAConfig) -> tuple[np.ndarray, bool]:
    """Floor masses ``(floor,)`` [t] and whether they are normalised: the measurement's masses, or
    ``force.mass_ratios`` (default equal) scaled to sum to 1 when it has none."""
    n = meas.n_floors
    if meas.mass is not None:
        return np.asarray(meas.mass, dtype=float), False
    ratios = cfg.force.mass_ratios
    if ratios is None:
        ratios = [1.0] * n
    if len(ratios) != n:
        raise InputError(f"force.mass_ratios has {len(ratios)} values but there are {n} floors", source=meas.source)
    r = np.asarray(ratios, dtype=float)
    return r / r.sum(), True


def story_force(acc: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """Story restoring force ``f_i = -sum_{j>=i} m_j a_j`` (eq 1-2), ``(time, story)``."""
    return -np.cumsum((acc * mass[None, :])[:, ::-1], axis=1)[:, ::-1]


def _pdelta_active(meas: Measurement, cfg: HLAConfig) -> bool:
    mode = cfg.force.pdelta
    if mode == "off":
        return False
    if meas.height is None:
        if mode == "on":
            raise InputError("force.pdelta is 'on' but the measurement has no story heights", source=meas.source)
        return False
    return True if mode == "on" else meas.pdelta_active


def floor_motion(meas: Measurement, cfg: HLAConfig):
    """Filtered absolute floor accelerations, relative floor velocities and displacements.

    Returns ``(acc, acc_full, vel, disp)``, each ``(time, floor)`` [mm/s^2, mm/s, mm]:
    ``acc`` band-passed like the drift (for stiffness fits, so both carry the same filter),
    ``acc_full`` only low-passed (for the reported force).
    """
    p = cfg.preprocess
    band = resolved_band(meas, cfg)
    pp.check_record_length(meas.n_samples, meas.dt, band, p.order, meas.source or None)
    # force and drift pass through the same zero-phase filter, so whatever the filter takes
    # out of one it takes out of the other and the loops stay consistent
    acc = bandpass(np.asarray(meas.floor_acc), meas.dt, band, p.order)
    ag = bandpass(np.asarray(meas.ground_acc), meas.dt, band, p.order)
    # the reported force keeps its low frequencies (no integration, nothing drifts)
    acc_full = bandpass(np.asarray(meas.floor_acc), meas.dt, (0.0, band[1]), p.order)
    use_measured = p.displacement == "measured" or (p.displacement == "auto" and meas.floor_disp is not None)
    if use_measured:
        if meas.floor_disp is None:
            raise InputError("preprocess.displacement is 'measured' but the data hold no floor displacements",
                             source=meas.source)
        disp = bandpass(np.asarray(meas.floor_disp), meas.dt, band, p.order)
        vel = np.gradient(disp, meas.dt, axis=0)
    else:
        vel, disp = integrate_twice(acc - ag[:, None], meas.dt, band, p.order)
    return acc, acc_full, vel, disp


def resolved_band(meas: Measurement, cfg: HLAConfig) -> tuple[float, float]:
    """The band-pass corners used for ``meas``: the config's, or chosen from the record."""
    p = cfg.preprocess
    if p.band_hz == AUTO:
        raise InputError("preprocess.band_hz is 'auto': the record decides it through hlaid.hla.auto.resolve_hla "
                         "(hlaid.hla.run_hla and the identification resolve it)", source=meas.source or None)
    if p.band_hz is not None:
        return cast("tuple[float, float]", tuple(p.band_hz))
    roof_disp = None if meas.floor_disp is None else np.asarray(meas.floor_disp)[:, -1]
    return pp.auto_band(np.asarray(meas.ground_acc), np.asarray(meas.floor_acc)[:, -1], meas.dt, p.highpass_ratio,
                        roof_disp)


def _story_stiffness(x, f, dx, t, bounds, cfg: HLAConfig, band, regress_damping: bool) -> HalfCycleTable:
    """Half-cycle table of one story: raw ke per half cycle, then the smoothed ke."""
    sc = cfg.stiffness
    work = integrate.cumulative_trapezoid(f * dx, t, initial=0.0)
    corr = max(1.0, 1.0 / (2.0 * band[1] * (t[1] - t[0])))  # samples per independent one
    rows = []
    for s, e in bounds:
        w = elastic_window(f, s, e, sc.ke_force_fraction, sc.ke_min_samples)
        xs, fs = x[s:w], f[s:w]
        c = np.nan
        if regress_damping:
            c = float(np.linalg.lstsq(np.stack([xs, dx[s:w], np.ones(w - s)], axis=1), fs, rcond=None)[0][1])
            fs = fs - c * dx[s:w]
        ke, var = slope_with_drift_check(xs, fs, t[s:w], sc.ke_trend_z)
        b = float(fs[0] - ke * xs[0]) if np.isfinite(ke) else np.nan
        zero = s + int(np.argmin(np.abs(f[s:e + 1])))  # energy where the force crosses zero
        seg = slice(s, e + 1)
        rows.append((s, e, t[s], t[e], np.sign(x[e] - x[s]), abs(x[e] - x[s]), np.max(np.abs(x[seg])), ke,
                     ke, np.sqrt(var * corr), -b / ke if ke else np.nan, np.trapezoid(f[seg], x[seg]),
                     work[zero], c))
    cols = [np.asarray(c) for c in zip(*rows)] if rows else [np.zeros(0)] * 14
    table = HalfCycleTable(*(c.astype(np.int64 if i < 2 else np.float64) for i, c in enumerate(cols)))
    return table


def _ke_weights(table: HalfCycleTable, ptp: float, cfg: HLAConfig) -> np.ndarray:
    """Weight of each half cycle's ke in the pooled fits: 1/variance, 0 for small or failed ones."""
    raw = table.ke_raw
    big = table.drift_increment >= cfg.stiffness.k0_min_amplitude * ptp
    w = np.where(big, 1.0 / np.maximum(table.ke_std, 1e-9 * np.abs(raw)) ** 2, 0.0)
    return np.where(np.isfinite(raw) & (raw > 0), w, 0.0)


def _smooth(table: HalfCycleTable, w: np.ndarray, trend, yielded: bool,
            cfg: HLAConfig) -> tuple[HalfCycleTable, float]:
    """Smoothed ke of every half cycle and k0 (see :class:`StiffnessConfig`), from the weights
    ``w`` (:func:`_ke_weights`) and the energy ``trend`` ``(ke_fit, k0)`` (None without weights)."""
    raw = table.ke_raw
    if len(table) == 0 or trend is None:
        return table, np.nan
    if not yielded:  # an elastic story: one stiffness, k0, pooled over every half cycle
        k0 = float(np.sum(w * np.nan_to_num(raw)) / np.sum(w))
        return table.replace(ke=np.full(len(table), k0)), k0
    ke_fit, k0 = trend
    mode = cfg.stiffness.ke_smoothing
    if mode == "energy":
        ke = ke_fit
    elif mode == "monotone":
        ok = w > 0
        fit = isotonic_decreasing(raw[ok], w[ok])
        ke = np.interp(np.arange(len(raw)), np.flatnonzero(ok), fit)
    else:
        ke = raw.copy()
    return table.replace(ke=ke), k0


def _analyse(x, f, dx, t, cfg: HLAConfig, band, regress_damping: bool):
    """Half cycles, stiffness table, k(t), yield flag and k0 of one story."""
    ptp = float(np.ptp(x))
    bounds = half_cycle_bounds(x, cfg.half_cycles.min_increment * ptp)
    table = _story_stiffness(x, f, dx, t, bounds, cfg, band, regress_damping)
    k = sliding_slope(x, f, bounds, cfg.stiffness.k_window)
    w = _ke_weights(table, ptp, cfg)
    trend = degradation_trend(table.ke_raw, table.energy_before, w) if (w > 0).any() else None
    yielded = _yielded(k, table, cfg, np.nan if trend is None else trend[1])
    table, k0 = _smooth(table, w, trend, yielded, cfg)
    return _StoryFit(bounds, table, k, yielded, k0)


@dataclass(frozen=True)
class _StoryFit:
    bounds: np.ndarray
    table: HalfCycleTable
    k: np.ndarray
    yielded: bool
    k0: float


def _rayleigh_damping(results: list, x, f, vel, dx, t, m, cfg: HLAConfig, band, source):
    """Subtract Rayleigh damping forces from the story forces, its coefficients from the k0 of the
    analysis, until k0 settles (``cfg.force.max_iterations``). Returns the analyses, the damped
    forces and the damping forces, each ``(time, story)``."""
    f0, n = f, x.shape[1]
    mv = np.cumsum((vel * m[None, :])[:, ::-1], axis=1)[:, ::-1]
    for _ in range(cfg.force.max_iterations):
        k0 = np.array([r.k0 for r in results])
        if not np.all(np.isfinite(k0) & (k0 > 0)):
            bad = int(np.argmax(~(np.isfinite(k0) & (k0 > 0)))) + 1
            raise InputError(f"story {bad}: no half cycle to estimate k0 from; the record is too short or too "
                             "weak", source=source)
        a0, a1 = structure.rayleigh_coefficients(torch.tensor(k0)[None], torch.tensor(m)[None], "rayleigh",
                                                  cfg.force.damping_ratio, cfg.force.damping_modes)
        damp = float(a0) * mv + float(a1) * k0[None, :] * dx
        f = f0 - damp
        results = [_analyse(x[:, i], f[:, i], dx[:, i], t, cfg, band, False) for i in range(n)]
        k0_new = np.array([r.k0 for r in results])
        if np.all(np.abs(k0_new / k0 - 1) < 1e-3):
            break
    return results, f, damp


def _regression_damping(results: list, x, f, dx, t, share, cfg: HLAConfig, band):
    """Subtract each story's regressed viscous damping (the median over its half cycles) and
    analyse again. Returns the analyses, the forces and the share added to the inertia forces."""
    cs = []
    for i, r in enumerate(results):
        c = np.nanmedian(r.table.damping_coefficient) if len(r.table) else 0.0
        cs.append(c if np.isfinite(c) else 0.0)
        f[:, i] = f[:, i] - cs[-1] * dx[:, i]
        share[:, i] -= cs[-1] * dx[:, i]
    results = [_analyse(x[:, i], f[:, i], dx[:, i], t, cfg, band, False) for i in range(x.shape[1])]
    results = [dataclasses.replace(r, table=r.table.replace(damping_coefficient=np.full(len(r.table), cs[i])))
               for i, r in enumerate(results)]
    return results, f, share


def run_hla(measurement: Measurement, config: HLAConfig | None = None) -> HLAResult:
    """Hysteresis loop analysis of every story.

    Parameters
    ----------
    measurement : ground and absolute floor accelerations (masses optional)
    config : analysis settings (defaults: :class:`HLAConfig`)

    Returns
    -------
    HLAResult
    """
    cfg = config or HLAConfig()
    meas = measurement
    if cfg.unresolved():
        raise InputError(f"{', '.join(cfg.unresolved())} 'auto': the record decides through "
                         "hlaid.hla.auto.resolve_hla (hlaid.hla.run_hla resolves it)", source=meas.source or None)
    m, normalised = floor_masses(meas, cfg)
    band = resolved_band(meas, cfg)
    acc, acc_full, vel, disp = floor_motion(meas, cfg)
    x = pp.story_drift(disp)
    dx = pp.story_drift(vel)
    t = meas.time
    f = story_force(acc, m)
    share = np.zeros_like(f)  # what is added to the inertia force: P-Delta, minus damping
    pdelta = _pdelta_active(meas, cfg)
    if pdelta:
        assert meas.height is not None  # _pdelta_active: no P-Delta without story heights
        P = np.cumsum((m * G_MM_S2)[::-1])[::-1]
        share = share + x * (P / meas.height)[None, :]
        f = f + share
    n = meas.n_floors
    damping = cfg.force.damping
    regress = damping == "regression"
    results = [_analyse(x[:, i], f[:, i], dx[:, i], t, cfg, band, regress) for i in range(n)]
    for i, r in enumerate(results):
        if len(r.table) == 0:
            raise InputError(f"story {i + 1}: no complete half cycle; the record is too short or too weak for HLA",
                             source=meas.source)
    if damping == "rayleigh":
        results, f, damp = _rayleigh_damping(results, x, f, vel, dx, t, m, cfg, band, meas.source)
        share = share - damp
    elif regress:
        results, f, share = _regression_damping(results, x, f, dx, t, share, cfg, band)
    f_out = story_force(acc_full, m) + share
    stories = []
    for i, r in enumerate(results):
        if len(r.table) == 0:
            raise InputError(f"story {i + 1}: no complete half cycle; the record is too short or too weak for HLA",
                             source=meas.source)
        ke_t = np.full(meas.n_samples, np.nan)
        for (s, e), ke in zip(r.bounds, r.table.ke):
            ke_t[s:e + 1] = ke
        stories.append(StoryHLA(story=i + 1, force=f_out[:, i], force_fit=f[:, i], drift=x[:, i],
                                drift_velocity=dx[:, i], k=r.k, ke=ke_t, k0=r.k0, yielded=r.yielded,
                                half_cycles=r.table))
    return HLAResult(dt=meas.dt, stories=tuple(stories), mass=m, mass_normalised=normalised, damping=damping,
                     pdelta_corrected=pdelta, config=cfg, band_hz=band, source=meas.source)


def reanalyse_story(story: StoryHLA, drift: np.ndarray, force: np.ndarray, dt: float, config: HLAConfig,
                    band_hz) -> StoryHLA:
    """HLA of one story again along another drift path (e.g. a reconstructed one, see
    :mod:`hlaid.identify.drift`) and a force consistent with it: half cycles, ``ke``,
    ``k(t)``, ``k0`` and the yield test, as :func:`run_hla` does them. The damping and P-Delta
    shares already in ``force`` are kept; the drift velocity is the path's derivative."""
    t = np.arange(drift.shape[0]) * dt
    dx = np.gradient(drift, dt)
    r = _analyse(drift, force, dx, t, config, band_hz, False)
    if len(r.table) == 0:
        return dataclasses.replace(story, drift=drift, drift_velocity=dx, force_fit=force)
    ke_t = np.full(drift.shape[0], np.nan)
    for (s, e), ke in zip(r.bounds, r.table.ke):
        ke_t[s:e + 1] = ke
    return dataclasses.replace(story, drift=drift, drift_velocity=dx, force_fit=force, k=r.k, ke=ke_t, k0=r.k0,
                               yielded=r.yielded, half_cycles=r.table)


def _yielded(k: np.ndarray, table: HalfCycleTable, cfg: HLAConfig, k_ref: float = np.nan, n_largest: int = 5,
             n_below: int = 2) -> bool:
    """Whether the story left the elastic range.

    Of the ``n_largest`` half cycles with the largest drift increments (the best signal to
    noise), at least ``n_below`` must end (last fifth) with a tangent stiffness below
    ``yield_ratio`` times their elastic stiffness: one such half cycle can be noise. The
    elastic stiffness is the larger of the half cycle's own ``ke`` and ``k_ref`` (the story's
    undegraded stiffness from the energy trend): a strongly hardening story (alpha ~0.4) whose
    ``ke`` has degraded towards ``alpha k0`` ends its half cycles close to its *current* ``ke``,
    but far below its initial one.
    """
    order = np.argsort(table.drift_increment)[::-1][:n_largest]
    below = 0
    for j in order:
        s, e, ke = table.start[j], table.end[j], table.ke_raw[j]
        if np.isfinite(k_ref) and k_ref > 0:
            ke = max(ke, k_ref) if np.isfinite(ke) else k_ref
        tail = k[e - max((e - s) // 5, 2): e + 1]
        tail = tail[np.isfinite(tail)]
        if tail.size and np.isfinite(ke) and ke > 0 and np.median(tail) < cfg.stiffness.yield_ratio * ke:
            below += 1
    return below >= min(n_below, len(order))
