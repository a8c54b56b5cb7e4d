"""The collapse law's capping drift as a random variable, conditioned on the drifts a building survived.

A collapse law (:class:`~hlaid.model.collapse.CollapseModel`) gives every story a capping drift
``xc_i = dy_i + theta_p h_i`` beyond which it loses strength. The law's ``theta_p`` is a
literature median over tested members, with a scatter ``beta_p``; the building at hand is one
draw of it. Every event the building came through, with its records fitted by a story law that
loses no strength, says that each story's capping drift lies beyond the drift it was measured to
reach. So, with ``s_ei`` the measured peak drift of story ``i`` in event ``e`` [mm]:

* prior: ``ln theta_p ~ N(ln m, beta^2)`` (``m = law.theta_p``, ``beta = law.beta_p``);
* evidence: ``dy_i + theta_p h_i > s_ei`` for every event and story, i.e. ``theta_p > t`` with
  ``t = max_ei (s_ei - dy_i) / h_i`` (the largest plastic drift ratio survived);
* posterior: the prior truncated below ``t``: with ``u = (ln t - ln m) / beta`` and ``Phi`` the
  standard normal distribution, ``P(theta_p <= x | survived) = (Phi((ln x - ln m)/beta) - Phi(u))
  / (1 - Phi(u))`` for ``x > t``; its quantile ``q`` is ``m exp(beta Phi^-1(Phi(u) + q (1 -
  Phi(u))))``, and ``1 - Phi(u)`` is the prior probability that a building of this law survives
  what this one did (:attr:`CapacityPosterior.p_consistent`).

The law in force is the posterior median (``theta_u`` moved by as much, so the post-capping branch
and the residual plateau keep their extent); its 90 % interval is kept beside it. With no plastic
drift survived (``t <= 0``: no story went beyond its yield drift) the evidence says nothing and
the law is the literature's, unchanged. Where ``1 - Phi(u)`` is below :data:`P_CONSISTENT_MIN`
the law and the records contradict each other (no building of that law would have survived
them): the posterior is still given, flagged, and the decision figures that rest on it are "not
assessed".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from .collapse import CollapseModel

P_CONSISTENT_MIN = 1e-4
"""Below this prior probability of surviving the recorded drifts the law is taken as contradicted
by the records (the drifts lie more than 3.7 ``beta_p`` beyond the law's median cap)."""

P_CONSISTENT_FLAG = 0.05
"""Below this prior probability the recorded drifts lie in the law's tail: said in a flag."""


def _phi(x: float) -> float:
    from scipy.special import ndtr

    return float(ndtr(x))


def _phi_inv(p: float) -> float:
    from scipy.special import ndtri

    return float(ndtri(p))


@dataclass(frozen=True)
class CapacityPosterior:
    """The law's ``theta_p`` given the drifts the building survived (see the module doc).

    Attributes
    ----------
    law : the literature law (the prior's median ``theta_p`` and its ``beta_p``)
    threshold : ``t``, the largest plastic drift ratio survived (``-inf``: no drift recorded)
    story : the story (0-based) that sets ``t`` (-1: none)
    survived_mm : ``(story,)`` the largest measured drift of each story over the events [mm]
        (None: none recorded)
    """

    law: CollapseModel
    threshold: float
    story: int = -1
    survived_mm: tuple[float, ...] | None = None

    @property
    def informative(self) -> bool:
        """Whether a story went beyond its yield drift (else the evidence leaves the law as it is)."""
        return self.threshold > 0.0

    @property
    def _u(self) -> float:
        return (math.log(self.threshold) - math.log(self.law.theta_p)) / self.law.beta_p

    @property
    def p_consistent(self) -> float:
        """The prior probability that a building of this law survives the recorded drifts, ``1 - Phi(u)``."""
        if not self.informative:
            return 1.0
        if self.law.beta_p == 0.0:
            return 1.0 if self.threshold < self.law.theta_p else 0.0
        return _phi(-self._u)

    @property
    def consistent(self) -> bool:
        """Whether the law and the records can both hold (:data:`P_CONSISTENT_MIN`)."""
        return self.p_consistent >= P_CONSISTENT_MIN

    def quantile(self, q: float) -> float:
        """The posterior's ``q`` quantile of ``theta_p``."""
        m, beta = self.law.theta_p, self.law.beta_p
        if not self.informative:
            return m if beta == 0.0 else m * math.exp(beta * _phi_inv(q))
        if beta == 0.0 or not self.consistent:
            return max(m, self.threshold)
        # Phi^-1(Phi(u) + q (1 - Phi(u))) = -Phi^-1((1 - q) (1 - Phi(u))), exact in the far tail too
        return max(self.threshold, m * math.exp(-beta * _phi_inv((1.0 - q) * self.p_consistent)))

    def interval(self, level: float = 0.9) -> tuple[float, float]:
        """The central ``level`` interval of ``theta_p``."""
        return self.quantile(0.5 - level / 2), self.quantile(0.5 + level / 2)

    def conditioned(self) -> CollapseModel:
        """The law in force: ``theta_p`` at the posterior median, ``theta_u`` moved by as much, and
        ``beta_p`` 0 (a point value: conditioning it again on the same drifts leaves it as it is);
        the literature law itself where the evidence is not informative."""
        if not self.informative:
            return self.law
        tp = self.quantile(0.5)
        return replace(self.law, theta_p=tp, theta_u=self.law.theta_u + (tp - self.law.theta_p), beta_p=0.0)

    def note(self) -> str:
        """In words: what the evidence did to the law."""
        law = self.law
        if law.beta_p == 0.0 and self.informative and self.consistent:
            return (f"collapse law {law.name!r}: capping drift dy/h + {law.theta_p:.4g}, beyond every drift the "
                    "building survived (a point value, already conditioned on them)")
        if not self.informative:
            return (f"collapse law {law.name!r}: no story went beyond its yield drift in the recorded events, so "
                    f"the capping drift dy/h + {law.theta_p:g} is the literature's")
        lo, hi = self.interval()
        s = "" if self.survived_mm is None else " (measured peaks " + ", ".join(f"{v:.1f}" for v in
                                                                            self.survived_mm) + " mm)"
        head = (f"collapse law {law.name!r}: every story survived its recorded drifts{s} without losing strength, "
                f"so theta_p > {self.threshold:.4g} (story {self.story + 1}); the prior lognormal(median "
                f"{law.theta_p:g}, beta {law.beta_p:g}) conditioned on it: median {self.quantile(0.5):.4g}, 90 % "
                f"{lo:.4g}-{hi:.4g}; a building of this law survives such drifts with prior probability "
                f"{self.p_consistent:.2g}")
        if not self.consistent:
            return head + ": the law contradicts the records, collapse figures resting on it are not assessed"
        return head

    def to_dict(self) -> dict:
        lo, hi = self.interval()
        return {"law": self.law.name, "theta_p_prior": self.law.theta_p, "beta_p": self.law.beta_p,
                "threshold": self.threshold if math.isfinite(self.threshold) else None,
                "story": self.story + 1 if self.story >= 0 else None,
                "survived_drift_mm": None if self.survived_mm is None else list(self.survived_mm),
                "theta_p_median": self.quantile(0.5), "theta_p_90": [lo, hi],
                "p_consistent": self.p_consistent, "consistent": self.consistent,
                "informative": self.informative}


def capacity_posterior(law: CollapseModel, *, dy, height, survived=None) -> CapacityPosterior:
    """The posterior of ``law``'s ``theta_p`` given the measured drifts ``survived`` ``(story,)`` [mm]
    (None: none recorded) of stories of yield drift ``dy`` and height ``height`` ``(story,)`` [mm].
    A survived drift at or beyond its story's height is an InputError (check the heights)."""
    dy, h = np.asarray(dy, dtype=float), np.asarray(height, dtype=float)
    if survived is None:
        return CapacityPosterior(law=law, threshold=-math.inf)
    s = np.asarray(survived, dtype=float)
    bad = np.flatnonzero(s >= h)
    if bad.size:
        i = int(bad[0])
        raise InputError(f"story {i + 1} survived a drift of {s[i]:.4g} mm, beyond its height {h[i]:g} mm: "
                         "check the story heights (heights_mm, --heights)")
    need = (s - dy) / h
    i = int(np.argmax(need))
    return CapacityPosterior(law=law, threshold=float(need[i]), story=i, survived_mm=tuple(float(v) for v in s))


__all__ = ["CapacityPosterior", "P_CONSISTENT_FLAG", "P_CONSISTENT_MIN", "capacity_posterior"]
