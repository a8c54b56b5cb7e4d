"""Other identifiers, for comparison with the paper's method: least squares through the
differentiable model (:class:`GradientIdentifier`) and the unscented Kalman filter
(:class:`UKFIdentifier`), behind the scikit-learn estimator contract of
:class:`hlaid.estimators.BaseIdentifier`, named in :data:`IDENTIFIERS` with the paper's method
(``hlasvm``). ``scripts/compare_identifiers.py`` and ``docs/comparison.md`` compare them.
Names are imported on first use (PEP 562).
"""

from __future__ import annotations

from .._lazy import lazy_exports

_WHERE = {
    ".gradient": ("GradientIdentifier",),
    ".ukf": ("UKFIdentifier",),
    ".registry": ("IDENTIFIERS", "get_identifier"),
}

__all__ = [name for names in _WHERE.values() for name in names]

__getattr__, __dir__ = lazy_exports(__name__, {name: module for module, names in _WHERE.items() for name in names})
