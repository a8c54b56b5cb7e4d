"""Independent reference implementations for the verification tests.

Nothing here imports hlaid: the shear building, its Rayleigh damping and the degrading
Bouc-Wen story law are written again from docs/DESIGN.md section 3 (units N, mm, t, s) so that the
tests compare hlaid against a second, separately written model, integrated by scipy.

State layout (same as hlaid, so histories can be compared directly)::

    y = [u (n), v (n), z (n), e (n)]

``u`` floor displacement relative to the ground [mm], ``v`` its velocity [mm/s], ``z`` the
hysteretic displacement of each story [mm], ``e`` the signed work integral(z dx) [mm^2].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate, linalg, signal

G_MM_S2 = 9806.65

# The proof-of-concept structure of the paper (Table 1 and section 3.1), from docs/DESIGN.md section 4.
TABLE1 = {
    "weight_kN": (171.85, 171.85, 90.0),
    "k0": (1.94e4, 1.65e4, 1.37e4),
    "alpha": (0.23, 0.17, 0.12),
    "p": (2.5, 1.5, 1.9),
    "dy": (7.0, 6.0, 3.0),
    "delta_eta": (0.7, 0.66, 1.54),
}


def table1_stories() -> list[dict]:
    """Table 1 as per-story mappings (bottom to top) for ``Building.from_stories``."""
    n = len(TABLE1["k0"])
    return [{k: v[i] for k, v in TABLE1.items()} for i in range(n)]


def table1_masses() -> np.ndarray:
    """Floor masses [t] from the Table 1 weights: W / g."""
    return np.asarray(TABLE1["weight_kN"]) * 1000.0 / G_MM_S2


@dataclass
class ShearBuildingRef:
    """A shear building with one degrading Bouc-Wen spring per story (docs/DESIGN.md section 3).

    Parameters are ``(story,)`` arrays, stories bottom to top; ``kg`` is the P-Delta
    stiffness P/h of each story [N/mm] (zeros: no P-Delta); ``ratio`` the Rayleigh damping
    ratio on modes 1 and 2 of the initial stiffness (both modes set to the same mode for a
    one-story building).
    """

    mass: np.ndarray
    k0: np.ndarray
    alpha: np.ndarray
    p: np.ndarray
    dy: np.ndarray
    delta_eta: np.ndarray
    ratio: float = 0.05
    kg: np.ndarray | None = None

    def __post_init__(self):
        for name in ("mass", "k0", "alpha", "p", "dy", "delta_eta"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        self.n = self.mass.size
        self.kg = np.zeros(self.n) if self.kg is None else np.asarray(self.kg, dtype=float)
        self.M = np.diag(self.mass)
        self.K = self.stiffness_matrix(self.k0)
        w = self.frequencies()
        w1, w2 = w[0], w[min(1, self.n - 1)]
        if self.n == 1 or w1 == w2:
            a0, a1 = self.ratio * w1, self.ratio / w1
        else:
            # zeta_i = a0 / (2 w_i) + a1 w_i / 2 for i = 1, 2
            a0, a1 = np.linalg.solve([[0.5 / w1, 0.5 * w1], [0.5 / w2, 0.5 * w2]], [self.ratio, self.ratio])
        self.C = a0 * self.M + a1 * self.K

    @staticmethod
    def stiffness_matrix(k: np.ndarray) -> np.ndarray:
        n = k.size
        K = np.zeros((n, n))
        for i in range(n):  # story i joins floor i-1 (ground for i = 0) to floor i
            K[i, i] += k[i]
            if i > 0:
                K[i - 1, i - 1] += k[i]
                K[i, i - 1] -= k[i]
                K[i - 1, i] -= k[i]
        return K

    def frequencies(self) -> np.ndarray:
        """Circular natural frequencies [rad/s], ascending (generalised eigenproblem)."""
        return np.sqrt(linalg.eigh(self.K, self.M, eigvals_only=True))

    # ------------------------------------------------------------------ nonlinear model
    def story_drift(self, u):
        return u - np.concatenate([[0.0], u[:-1]])

    def rhs(self, y: np.ndarray, ag: float) -> np.ndarray:
        n = self.n
        u, v, z, e = y[:n], y[n:2 * n], y[2 * n:3 * n], y[3 * n:]
        x = self.story_drift(u)
        dx = self.story_drift(v)
        # eta = 1 + delta_eta * eps, eps = (1-alpha) (k0/m) integral(z dx) in SI (m^2 = 1e6 mm^2)
        eps = (1.0 - self.alpha) * (self.k0 / self.mass) * (e * 1e-6)
        eta = 1.0 + self.delta_eta * eps
        zdot = dx * (1.0 - 0.5 * (np.sign(dx * z) + 1.0) * np.abs(z / self.dy) ** self.p) / eta
        shear = self.alpha * self.k0 * x + (1.0 - self.alpha) * self.k0 * z - self.kg * x
        restoring = shear - np.concatenate([shear[1:], [0.0]])
        a = (-restoring - self.C @ v) / self.mass - ag
        return np.concatenate([v, a, zdot, z * dx])

    def solve(self, ag: np.ndarray, dt: float, *, rtol: float = 1e-10, atol: float = 1e-10,
              method: str = "DOP853", y0: np.ndarray | None = None) -> np.ndarray:
        """States at the sample times, ``(time, 4*story)``, by ``solve_ivp`` restarted at every
        sample: the ground acceleration is linear inside each interval, so its kinks never fall
        inside a step. ``y0``: the state at the first sample ``[u, v, z, e]`` (default rest)."""
        y = np.zeros(4 * self.n) if y0 is None else np.array(y0, dtype=float)
        out = np.empty((ag.size, y.size))
        out[0] = y
        for k in range(ag.size - 1):
            a0, slope = ag[k], (ag[k + 1] - ag[k]) / dt
            sol = integrate.solve_ivp(lambda t, s, a0=a0, slope=slope: self.rhs(s, a0 + slope * t), (0.0, dt), y,
                                      method=method, rtol=rtol, atol=atol)
            y = sol.y[:, -1]
            out[k + 1] = y
        return out

    # ------------------------------------------------------------------ linear model (alpha = 1)
    def linear_state_space(self):
        """``(A, B)`` of ``d/dt [u, v] = A [u, v] + B ag`` with stiffness ``K0 - Kg``."""
        n = self.n
        Kg = self.stiffness_matrix(self.kg)
        Minv = np.diag(1.0 / self.mass)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ (self.K - Kg), -Minv @ self.C]])
        B = np.concatenate([np.zeros(n), -np.ones(n)])[:, None]
        return A, B

    def linear_response(self, ag: np.ndarray, dt: float) -> np.ndarray:
        """Floor displacements ``(time, story)`` of the linear system, exact for a piecewise-linear
        ground acceleration (``scipy.signal.lsim`` with ``interp=True``)."""
        A, B = self.linear_state_space()
        Cout = np.hstack([np.eye(self.n), np.zeros((self.n, self.n))])
        sys = signal.StateSpace(A, B, Cout, np.zeros((self.n, 1)))
        t = np.arange(ag.size) * dt
        _, yout, _ = signal.lsim(sys, ag, t, interp=True)
        return yout.reshape(ag.size, self.n)


def energy_terms(*, dt, mass, C, alpha, k0, kg, ag, drift, vel, z) -> dict[str, np.ndarray]:
    """Energy balance terms [N mm] of a response history, each ``(time,)``.

    Arguments are histories ``(time, story)`` on a uniform grid (``ag`` is ``(time,)``); the
    time integrals are cumulative trapezoids, ``integral(z dx)`` uses the drift velocity.
    """
    def cumtrapz(y):
        return integrate.cumulative_trapezoid(y, dx=dt, axis=0, initial=0.0)

    dx = vel - np.concatenate([np.zeros((vel.shape[0], 1)), vel[:, :-1]], axis=1)
    return {
        "input": cumtrapz(-(vel @ mass) * ag),
        "kinetic": 0.5 * np.einsum("ti,i,ti->t", vel, mass, vel),
        "damping": cumtrapz(np.einsum("ti,ij,tj->t", vel, C, vel)),
        "elastic": (0.5 * alpha * k0 * drift**2).sum(axis=1),
        "hysteretic": (((1.0 - alpha) * k0) * cumtrapz(z * dx)).sum(axis=1),
        "pdelta": (-0.5 * kg * drift**2).sum(axis=1),
    }
