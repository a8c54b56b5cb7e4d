"""Configuration of hysteresis loop analysis (YAML schema, validated on load).

Defaults were chosen on simulated Table 1 data with 10 % RMS noise over several real
records and seeds (``scripts/study_hla_accuracy.py``; ``tests/test_hla.py::test_hla_accuracy_study``)
and checked on the real shake-table data (``docs/hla.md``), where each choice is explained.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ..errors import InputError


@dataclass(frozen=True, kw_only=True)
class PreprocessConfig:
    """Filtering and integration.

    Attributes
    ----------
    band_hz : zero-phase Butterworth band-pass corners [Hz] applied to the accelerations
        (force and drift alike), and (high-pass) again after each integration. ``null``
        (default) sets them from the record: the low corner at ``highpass_ratio`` times the
        dominant frequency of the roof response (well below the lowest, damaged mode, high
        enough to keep doubly-integrated sensor noise out of the drift), the high corner at
        ``max(20 Hz, 4 x dominant)`` (above the modes of interest, cutting most broadband
        noise), below 0.45 of the sampling rate.
    highpass_ratio : see ``band_hz``.
    order : Butterworth order (applied forward and backward: effective order doubles).
    displacement : ``"integrate"`` accelerations, use ``"measured"`` floor displacements
        when the data hold them, or ``"auto"`` (measured when present).
    """

    band_hz: tuple[float, float] | None = None
    highpass_ratio: float = 0.25
    order: int = 4
    displacement: Literal["auto", "integrate", "measured"] = "auto"

    def __post_init__(self):
        if self.band_hz is not None:
            lo, hi = self.band_hz
            if not 0 <= lo < hi:
                raise InputError(f"band_hz = {list(self.band_hz)}; expected [low, high] with 0 <= low < high")
        if not 0 < self.highpass_ratio < 1:
            raise InputError(f"highpass_ratio = {self.highpass_ratio}; expected a fraction in (0, 1)")
        if not 1 <= self.order <= 10:
            raise InputError(f"order = {self.order}; expected 1..10")


@dataclass(frozen=True, kw_only=True)
class ForceConfig:
    """Story restoring force ``f_i = -sum_{j>=i} m_j a_j`` and its damping share.

    Attributes
    ----------
    damping : ``"none"`` keeps the viscous share in ``f``; ``"rayleigh"`` subtracts an
        assumed Rayleigh damping force (``damping_ratio`` on ``damping_modes`` of the
        identified initial stiffness); ``"regression"`` fits a velocity term per half cycle
        (``f = k x + c dx + f0``) as the published HLA does.
    damping_ratio, damping_modes : the assumed Rayleigh damping.
    mass_ratios : relative floor masses when absolute masses are unknown (default: equal).
    max_iterations : passes of the ``rayleigh`` correction (its damping matrix depends on
        the k0 it helps to identify; iterate until k0 settles).
    pdelta : add back the P-Delta share ``P x / h`` so that ``f`` is the story spring
        force: ``"auto"`` when the measurement says so (or heights are known).
    """

    damping: Literal["none", "rayleigh", "regression"] = "rayleigh"
    damping_ratio: float = 0.05
    damping_modes: tuple[int, int] = (1, 2)
    mass_ratios: list[float] | None = None
    pdelta: Literal["auto", "on", "off"] = "auto"
    max_iterations: int = 6

    def __post_init__(self):
        if not 0 <= self.damping_ratio < 1:
            raise InputError(f"damping_ratio = {self.damping_ratio}; expected 0 <= ratio < 1")
        if self.mass_ratios is not None and not all(m > 0 for m in self.mass_ratios):
            raise InputError("mass_ratios must be positive numbers")
        if not all(m >= 1 for m in self.damping_modes):
            raise InputError(f"damping_modes = {list(self.damping_modes)}; expected mode numbers >= 1")
        if self.max_iterations < 1:
            raise InputError(f"max_iterations = {self.max_iterations}; expected >= 1")


@dataclass(frozen=True, kw_only=True)
class HalfCycleConfig:
    """Splitting the drift history into half cycles at reversals.

    Attributes
    ----------
    min_increment : a reversal counts only when the drift moves back by more than this
        fraction of the story's peak-to-peak drift (smaller wiggles are noise and are
        merged into the half cycle they interrupt).
    """

    min_increment: float = 0.2

    def __post_init__(self):
        if not 0 < self.min_increment < 1:
            raise InputError(f"min_increment = {self.min_increment}; expected a fraction in (0, 1)")


@dataclass(frozen=True, kw_only=True)
class StiffnessConfig:
    """Stiffness identification.

    Attributes
    ----------
    ke_force_fraction : ``ke`` is the least-squares slope of ``f`` against ``x`` from the
        reversal until the force has changed by this fraction of the half cycle's force
        swing (the elastic unloading branch).
    ke_min_samples : fewest samples in that window.
    k_window : samples in the sliding least-squares window of the tangent stiffness k(t).
    k0_min_amplitude : half cycles whose drift increment is below this fraction of the
        story's peak-to-peak drift are too noisy to set k0.
    yield_ratio : a story has yielded when, of its five largest half cycles, at least two end
        with a tangent stiffness below this fraction of their ke (elastic stories stay above
        ~0.75 at 10 % noise; a yielding story with strong hardening, alpha ~0.35, reaches ~0.5).
    ke_smoothing : how single-half-cycle slopes (noisy: several % at 10 % noise) are pooled:
        ``"energy"`` fits ke against the energy dissipated so far
        (``k_inf + (k0 - k_inf)/(1 + c E)``, the form of eq 7-11); ``"monotone"`` a
        non-increasing fit in time; ``"none"`` keeps the raw slopes. k0 is always the energy
        fit at zero dissipated energy.
    ke_trend_z : fit ``f = ke x + b + c t`` on the elastic branch and keep the trend term
        when it exceeds this many standard errors (0: never). The drift from doubly
        integrated accelerations carries slowly varying errors (what the high-pass filter
        leaves of noise and takes away of plastic drift) that are locally a linear trend.
    """

    ke_force_fraction: float = 0.5
    ke_min_samples: int = 6
    k_window: int = 15
    k0_min_amplitude: float = 0.08
    yield_ratio: float = 0.6
    ke_smoothing: Literal["energy", "monotone", "none"] = "energy"
    ke_trend_z: float = 0.0

    def __post_init__(self):
        if not 0 < self.ke_force_fraction <= 1:
            raise InputError(f"ke_force_fraction = {self.ke_force_fraction}; expected (0, 1]")
        if self.ke_min_samples < 3 or self.k_window < 3:
            raise InputError("ke_min_samples and k_window must be >= 3")
        if not 0 <= self.k0_min_amplitude < 1:
            raise InputError(f"k0_min_amplitude = {self.k0_min_amplitude}; expected a fraction in [0, 1)")
        if not 0 < self.yield_ratio <= 1:
            raise InputError(f"yield_ratio = {self.yield_ratio}; expected a fraction in (0, 1]")
        if self.ke_trend_z < 0:
            raise InputError(f"ke_trend_z = {self.ke_trend_z}; expected >= 0 (0: never fit the trend)")


@dataclass(frozen=True, kw_only=True)
class HLAConfig:
    """Hysteresis loop analysis settings (``configs/hla.yaml``)."""

    preprocess: PreprocessConfig = field(default_factory=PreprocessConfig)
    force: ForceConfig = field(default_factory=ForceConfig)
    half_cycles: HalfCycleConfig = field(default_factory=HalfCycleConfig)
    stiffness: StiffnessConfig = field(default_factory=StiffnessConfig)
