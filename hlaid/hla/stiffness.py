"""Stiffness identification along half cycles: ke, k(t), k0, and the half-cycle features.

All slopes are least-squares fits of the story force ``f`` against the drift ``x``.
"""

from __future__ import annotations

import numpy as np


def ls_slope(x: np.ndarray, f: np.ndarray, *extra: np.ndarray) -> tuple[float, float]:
    """Slope ``k`` of ``f = k x + b`` (plus ``c_j * extra_j`` terms when given, e.g. the drift
    velocity for a damping term or time for a slowly drifting offset).

    Returns ``(k, var_k)``: the slope and an estimate of its variance (inf when the fit is
    ill-posed).
    """
    n = x.shape[0]
    if not extra:  # closed form, the common case
        if n <= 2:
            return np.nan, np.inf
        xm = x - x.mean()
        sxx = float(xm @ xm)
        if sxx <= 0.0:
            return np.nan, np.inf
        k = float(xm @ (f - f.mean())) / sxx
        r = (f - f.mean()) - k * xm
        return k, float(r @ r) / (n - 2) / sxx
    A = np.stack([x, np.ones(n), *extra], axis=1)
    if n <= A.shape[1]:
        return np.nan, np.inf
    coef, _, rank, _ = np.linalg.lstsq(A, f, rcond=None)
    if rank < A.shape[1]:
        return np.nan, np.inf
    r = f - A @ coef
    s2 = float(r @ r) / (n - A.shape[1])
    try:
        cov = np.linalg.inv(A.T @ A) * s2
    except np.linalg.LinAlgError:
        return np.nan, np.inf
    return float(coef[0]), float(cov[0, 0])


def slope_with_drift_check(x: np.ndarray, f: np.ndarray, t: np.ndarray, z_crit: float) -> tuple[float, float]:
    """Slope of ``f`` on ``x``, with a linear trend in time added only when it is significant.

    The doubly-integrated drift carries slowly varying errors that are locally a linear
    trend (filter smear of plastic drift, integrated noise). Fitting the trend always costs
    precision; it is kept when its coefficient exceeds ``z_crit`` standard errors.
    """
    k, var = ls_slope(x, f)
    if z_crit <= 0 or x.shape[0] < 8:
        return k, var
    n = x.shape[0]
    A = np.stack([x, np.ones(n), t - t[0]], axis=1)
    coef, _, rank, _ = np.linalg.lstsq(A, f, rcond=None)
    if rank < 3:
        return k, var
    r = f - A @ coef
    s2 = float(r @ r) / (n - 3)
    try:
        cov = np.linalg.inv(A.T @ A) * s2
    except np.linalg.LinAlgError:
        return k, var
    if abs(coef[2]) > z_crit * np.sqrt(cov[2, 2]):
        return float(coef[0]), float(cov[0, 0])
    return k, var


def elastic_window(f: np.ndarray, start: int, end: int, fraction: float, min_samples: int) -> int:
    """End index (exclusive) of the elastic branch after the reversal at ``start``.

    The branch runs until the force has changed by ``fraction`` of the half cycle's force
    swing ``|f[end] - f[start]|``, and holds at least ``min_samples`` samples.
    """
    seg = np.abs(f[start:end + 1] - f[start])
    swing = abs(f[end] - f[start])
    hit = np.nonzero(seg >= fraction * swing)[0]
    stop = int(hit[0]) + 1 if hit.size else seg.size
    return start + min(max(stop, min_samples), seg.size)


def sliding_slope(x: np.ndarray, f: np.ndarray, bounds: np.ndarray, window: int) -> np.ndarray:
    """Tangent stiffness ``k(t)``: slope of ``f`` on ``x`` in a centred window of ``window``
    samples that never crosses a half-cycle boundary; NaN outside half cycles and where the
    drift moves by less than 2 % of the half cycle's increment within the window (next to
    a reversal, where the slope is undefined).

    Parameters
    ----------
    x, f : (time,)
    bounds : (n_half_cycles, 2) inclusive start and end index of each half cycle
    """
    n = x.shape[0]
    k = np.full(n, np.nan)
    h = window // 2
    cx = np.concatenate([[0.0], np.cumsum(x)])
    cf = np.concatenate([[0.0], np.cumsum(f)])
    cxx = np.concatenate([[0.0], np.cumsum(x * x)])
    cxf = np.concatenate([[0.0], np.cumsum(x * f)])
    for s, e in bounds:
        i = np.arange(s, e + 1)
        lo = np.maximum(i - h, s)
        hi = np.minimum(i + h, e) + 1
        m = hi - lo
        sx, sf = cx[hi] - cx[lo], cf[hi] - cf[lo]
        sxx, sxf = cxx[hi] - cxx[lo], cxf[hi] - cxf[lo]
        den = m * sxx - sx * sx
        span = np.abs(x[hi - 1] - x[lo])
        ok = (den > 1e-12 * np.maximum(m * sxx, 1e-300)) & (span >= 0.02 * abs(x[e] - x[s]))
        with np.errstate(invalid="ignore", divide="ignore"):
            k[s:e + 1] = np.where(ok, (m * sxf - sx * sf) / den, np.nan)
    return k


def segment_index(x: np.ndarray, start: int, end: int, n_segments: int) -> np.ndarray:
    """Segment (0..n-1) of every sample of a half cycle, by equal drift increments from its
    reversal; ``(end - start + 1,)``."""
    xs = x[start:end + 1]
    d = xs[-1] - xs[0]
    pos = np.clip((xs - xs[0]) / d, 0.0, 1.0 - 1e-12) if d != 0 else np.zeros_like(xs)
    return (pos * n_segments).astype(int)


def segment_slopes(x: np.ndarray, f: np.ndarray, start: int, end: int, n_segments: int) -> np.ndarray:
    """Slopes of ``f`` on ``x`` over ``n_segments`` equal drift increments of one half cycle.

    Segment ``j`` holds the samples whose drift lies between ``j/n`` and ``(j+1)/n`` of the
    way from ``x[start]`` to ``x[end]``; each slope is a least-squares fit over its samples
    widened by one neighbour on each side (so a segment always has at least 3 points).
    Returns ``(n_segments,)``.
    """
    xs, fs = x[start:end + 1], f[start:end + 1]
    seg = segment_index(x, start, end, n_segments)
    # the drift is monotonic in a half cycle up to noise: take each segment's sample span
    first = np.searchsorted(np.maximum.accumulate(seg), np.arange(n_segments), side="left")
    last = np.searchsorted(np.maximum.accumulate(seg), np.arange(n_segments), side="right")
    out = np.full(n_segments, np.nan)
    for j in range(n_segments):
        lo, hi = max(first[j] - 1, 0), min(last[j] + 1, xs.size)
        if hi - lo >= 3:
            xx, ff = xs[lo:hi], fs[lo:hi]
            xm = xx - xx.mean()
            den = float(xm @ xm)
            if den > 0:
                out[j] = float(xm @ (ff - ff.mean())) / den
    if np.isnan(out).any() and (~np.isnan(out)).sum() >= 2:
        seg_idx = np.arange(n_segments)
        ok = ~np.isnan(out)
        out = np.interp(seg_idx, seg_idx[ok], out[ok])
    return out


def isotonic_decreasing(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted least-squares non-increasing fit of ``y`` (pool adjacent violators)."""
    vals, wts, sizes = [], [], []
    for yi, wi in zip(y, w):
        vals.append(yi)
        wts.append(wi)
        sizes.append(1)
        while len(vals) > 1 and vals[-2] < vals[-1]:
            wsum = wts[-2] + wts[-1]
            v = (vals[-2] * wts[-2] + vals[-1] * wts[-1]) / wsum
            s = sizes[-2] + sizes[-1]
            vals[-2:], wts[-2:], sizes[-2:] = [v], [wsum], [s]
    return np.repeat(vals, sizes)


def degradation_trend(ke: np.ndarray, energy: np.ndarray, weights: np.ndarray,
                      max_rate: float = 20.0) -> tuple[np.ndarray, float]:
    """Smooth ``ke`` against the energy dissipated before each half cycle.

    Fits ``ke(E) = k0 (r + (1 - r) / (1 + c E / E_max))`` with ``0 <= r <= 1`` and
    ``0 <= c <= max_rate`` (the form of eq 7-11: the elastic stiffness falls with dissipated
    energy only) by weighted robust least squares, so that noisy single half cycles are
    pooled with all the others. Returns the fitted ``ke`` of each half cycle and
    ``k0 = ke(0)``.
    """
    from scipy.optimize import least_squares

    ok = np.isfinite(ke) & (ke > 0) & np.isfinite(weights) & (weights > 0) & np.isfinite(energy)
    if ok.sum() < 4:
        k0 = float(np.sum(weights[ok] * ke[ok]) / np.sum(weights[ok])) if ok.any() else np.nan
        return np.full(ke.shape, k0), k0
    scale = float(np.median(ke[ok]))
    e_max = max(float(np.max(energy[ok])), 1e-12)
    E_all = np.clip(energy, 0.0, None) / e_max
    y, E = ke[ok] / scale, E_all[ok]
    w = np.sqrt(weights[ok] / weights[ok].sum())

    def model(q, E):
        k0, r, c = q
        return k0 * (r + (1.0 - r) / (1.0 + c * E))

    def jac(q):
        k0, r, c = q
        d = 1.0 / (1.0 + c * E)
        return w[:, None] * np.stack([r + (1.0 - r) * d, k0 * (1.0 - d), -k0 * (1.0 - r) * E * d * d], axis=1)

    iso = isotonic_decreasing(y, weights[ok])
    k_first = min(max(float(iso[0]), 1e-3), 20.0)  # inside the bounds below (an outlier can start above)
    q0 = [k_first, min(max(float(iso[-1]) / k_first, 0.0), 1.0), 1.0]
    sol = least_squares(lambda q: w * (model(q, E) - y), q0, jac=jac,
                        bounds=([1e-3, 0.0, 0.0], [20.0, 1.0, max_rate]), loss="soft_l1", f_scale=0.05)
    return model(sol.x, E_all) * scale, float(sol.x[0] * scale)
