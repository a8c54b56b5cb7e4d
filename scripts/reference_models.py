"""Reference structures of the benchmark and study scripts (imported as a sibling module: run the
scripts as ``python scripts/NAME.py``, which puts ``scripts/`` on ``sys.path``).

- :func:`table1_stories`: the paper's proof-of-concept structure (Table 1, docs/DESIGN.md section 4).
- The SDOF of Vamvatsikos & Cornell (2002), Fig. 4a, and :func:`bilinear_peak`, an independent
  bilinear oscillator (Newmark average acceleration, Newton iterations, elastic-perfectly-plastic
  return map with kinematic hardening).

The tests keep their own copies (``tests/reference_systems.py``, ``tests/test_ida_verification.py``)
so that they stay independent of the scripts.
"""

from __future__ import annotations

import numba as nb
import numpy as np

TABLE1 = {
    "weight_kN": (171.85, 171.85, 90.0),
    "k0": (1.94e4, 1.65e4, 1.37e4),
    "alpha": (0.23, 0.17, 0.12),
    "p": (2.5, 1.5, 1.9),
    "dy": (7.0, 6.0, 3.0),
    "delta_eta": (0.7, 0.66, 1.54),
}
"""Table 1 of the paper, bottom to top: weights [kN], k0 [N/mm], alpha, p, dy [mm], delta_eta [s^2/m^2]."""


class VC2002:
    """The SDOF of Vamvatsikos & Cornell (2002), Fig. 4a: period ``T`` [s], damping ratio ``XI``,
    hardening ratio ``ALPHA``, yield displacement ``UY`` [mm], mass ``M`` [t], stiffness ``K`` [N/mm]."""

    T, XI, ALPHA, UY, M = 1.0, 0.05, 0.01, 250.0, 1.0
    K = (2 * np.pi / T) ** 2 * M


def table1_stories() -> list[dict]:
    """Table 1 as per-story mappings (bottom to top) for ``Building.from_stories``."""
    n = len(TABLE1["k0"])
    return [{k: v[i] for k, v in TABLE1.items()} for i in range(n)]


@nb.njit(cache=True)
def bilinear_peak(ag, dt, nsub, m, k, alpha, uy, c):
    """Peak |u| [mm] over every step of a bilinear (kinematic hardening) SDOF.

    Parameters
    ----------
    ag : (time,) ground acceleration [mm/s^2], sampled at ``dt`` [s]
    nsub : integration steps per sample
    m, k, alpha, uy, c : mass [t], stiffness [N/mm], hardening ratio, yield displacement [mm],
        damping coefficient [N s/mm]
    """
    h = dt / nsub
    u, v, zp = 0.0, 0.0, 0.0
    a = -ag[0]
    peak = 0.0
    for i in range(ag.size - 1):
        for s in range(nsub):
            p1 = -m * (ag[i] + (ag[i + 1] - ag[i]) * (s + 1) / nsub)
            u1 = u
            for _ in range(50):
                z1 = zp + (u1 - u)
                kt = k
                if abs(z1) > uy:
                    z1 = uy * np.sign(z1)
                    kt = alpha * k
                fs1 = alpha * k * u1 + (1 - alpha) * k * z1
                a1 = 4.0 / (h * h) * (u1 - u) - 4.0 / h * v - a
                v1 = v + 0.5 * h * (a + a1)
                du = (p1 - m * a1 - c * v1 - fs1) / (kt + 2.0 * c / h + 4.0 * m / (h * h))
                u1 += du
                if abs(du) < 1e-12 * (1.0 + abs(u1)):
                    break
            z1 = zp + (u1 - u)
            if abs(z1) > uy:
                z1 = uy * np.sign(z1)
            a1 = 4.0 / (h * h) * (u1 - u) - 4.0 / h * v - a
            v = v + 0.5 * h * (a + a1)
            u, a, zp = u1, a1, z1
            peak = max(peak, abs(u))
    return peak
