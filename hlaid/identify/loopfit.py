"""Story parameters by least squares on a story's force-drift loop.

The story law is driven along the story's drift path (:func:`hlaid.simulate.path.drive_story`)
and its force compared with the measured story force over the yielding part of the record:
no building, no ground motion, so the ground record's noise (the errors-in-variables limit
of the replay refinement) does not enter. Used for k0 in the outer loop (the regressions for
delta_eta and dy amplify a k0 error). Fitting all five parameters this way to finish the
identification was measured and is worse than the replay refinement (docs/identification.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..simulate.path import drive_story

__all__ = ["LoopFit", "fit_story_loop", "STORY_PARAMS"]

STORY_PARAMS = ("k0", "alpha", "p", "dy", "delta_eta")


@dataclass(frozen=True)
class LoopFit:
    """Result of :func:`fit_story_loop`.

    Attributes
    ----------
    params : the five story parameters after the fit (the fixed ones unchanged)
    rms_initial, rms_final : RMS force residual / RMS force, before and after
    nfev : residual evaluations
    """

    params: dict
    rms_initial: float
    rms_final: float
    nfev: int


def fit_story_loop(drift: np.ndarray, force: np.ndarray, dt: float, mass: float, params: dict, *,
                   free: tuple[str, ...] = ("k0",), bounds: dict | None = None, max_nfev: int = 30,
                   window: slice | None = None) -> LoopFit:
    """Least squares of the story law's force along ``drift`` against ``force``.

    Parameters
    ----------
    drift, force : ``(time,)`` the story's drift path [mm] and measured force [N]
    dt : sample interval [s]; mass : floor mass above the story [t]
    params : start values of ``k0, alpha, p, dy, delta_eta``
    free : which of them are fitted (in log scale)
    bounds : per free parameter ``(low, high)``; default a factor 3 around the start
        (alpha and p within their model ranges)
    window : samples compared (default: all)
    """
    names = list(free)
    start = np.array([float(params[n]) for n in names])
    lims = {n: (v / 3.0, v * 3.0) for n, v in zip(names, start)}
    lims.update({n: b for n, b in (bounds or {}).items() if n in lims})
    if "alpha" in lims:
        lims["alpha"] = (max(lims["alpha"][0], 1e-3), min(lims["alpha"][1], 0.95))
    if "p" in lims:
        lims["p"] = (max(lims["p"][0], 1.0), min(lims["p"][1], 6.0))
    lo = np.log([lims[n][0] for n in names])
    hi = np.log([lims[n][1] for n in names])
    q0 = np.clip(np.log(start), lo + 1e-9, hi - 1e-9)
    w = window or slice(0, drift.shape[0])
    x = np.ascontiguousarray(drift[: w.stop])
    f = force[w]
    scale = float(np.sqrt(np.mean(f**2))) or 1.0

    def forces(Q):
        cols = {n: np.full(Q.shape[0], float(params[n])) for n in STORY_PARAMS}
        for j, n in enumerate(names):
            cols[n] = np.exp(Q[:, j])
        r = drive_story(x, mass=mass, dt=dt, **cols)
        return (r.force[:, w] - f[None, :]) / scale

    last: dict = {}

    def resid(q):
        last["q"], last["r"] = q.tobytes(), forces(q[None, :])[0]
        return last["r"]

    def jac(q):  # the search asks for the residuals at q first: they are not driven again
        h = 1e-5
        R = forces(q[None, :] + h * np.eye(len(q)))
        r0 = last["r"] if last.get("q") == q.tobytes() else resid(q)
        return ((R - r0) / h).T

    r0 = resid(q0)
    sol = least_squares(resid, q0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=max_nfev)
    out = dict(params)
    for j, n in enumerate(names):
        out[n] = float(np.exp(sol.x[j]))
    return LoopFit(params=out, rms_initial=float(np.sqrt(np.mean(r0**2))),
                   rms_final=float(np.sqrt(np.mean(sol.fun**2))), nfev=int(sol.nfev))
