"""Configuration of hysteresis loop analysis (YAML schema, validated on load).

Defaults were chosen on simulated Table 1 data with 10 % RMS noise over several real
records and seeds (``scripts/study_hla_accuracy.py``; ``tests/test_hla.py::test_hla_accuracy_study``)
and checked on the real shake-table data (``docs/hla.md``), where each choice is explained.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final, Literal

from ..bounds import bounded, check_bounds
from ..errors import InputError

AUTO: Final = "auto"
"""The value of a setting that the record decides (:mod:`hlaid.hla.auto`)."""



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
        noise), below 0.45 of the sampling rate. ``"auto"`` (the identification's default):
        the same where the record's modes are a shear building's, a first-mode band where its
        second mode is not (:func:`hlaid.hla.auto.resolve_hla`).
    highpass_ratio : see ``band_hz``.
    order : Butterworth order (applied forward and backward: effective order doubles).
    displacement : ``"integrate"`` accelerations, use ``"measured"`` floor displacements
        when the data hold them, or ``"auto"`` (measured when present).
    """

    band_hz: tuple[float, float] | Literal["auto"] | None = bounded(None, lo=0.0, hi=50_000.0, unit="Hz")
    highpass_ratio: float = bounded(0.25, lo=1e-3, hi=1.0, hi_open=True)
    order: int = bounded(4, lo=1, hi=10)
    displacement: Literal["auto", "integrate", "measured"] = "auto"

    def __post_init__(self):
        check_bounds(self)
        if self.band_hz is not None and self.band_hz != AUTO:
            lo, hi = self.band_hz
            if not 0 <= lo < hi:
                raise InputError(f"band_hz = {list(self.band_hz)}; expected [low, high] with 0 <= low < high")
            from ..signal import MIN_CORNER_HZ

            if hi < MIN_CORNER_HZ or 0 < lo < MIN_CORNER_HZ:
                raise InputError(f"band_hz = {list(self.band_hz)}; a corner below {MIN_CORNER_HZ:g} Hz cannot be "
                                 f"designed: give 0 (no high-pass) or at least {MIN_CORNER_HZ:g} Hz")


@dataclass(frozen=True, kw_only=True)
class ForceConfig:
    """Story restoring force ``f_i = -sum_{j>=i} m_j a_j`` and its damping share.

    Attributes
    ----------
    damping : ``"none"`` keeps the viscous share in ``f``; ``"rayleigh"`` subtracts an
        assumed Rayleigh damping force (``damping_ratio`` on ``damping_modes`` of the
        identified initial stiffness); ``"regression"`` fits a velocity term per half cycle
        (``f = k x + c dx + f0``) as the published HLA does; ``"auto"`` (the identification's
        default): ``rayleigh`` unless the record says it over-corrects (more half cycles that
        dissipate negative energy than a passive story can have), then ``regression``
        (:func:`hlaid.hla.auto.resolve_hla`).
    damping_ratio, damping_modes : the assumed Rayleigh damping.
    mass_ratios : relative floor masses when absolute masses are unknown (default: equal).
    max_iterations : passes of the ``rayleigh`` correction (its damping matrix depends on
        the k0 it helps to identify; iterate until k0 settles).
    pdelta : add back the P-Delta share ``P x / h`` so that ``f`` is the story spring
        force: ``"auto"`` when the measurement says so (or heights are known).
    """

    damping: Literal["none", "rayleigh", "regression", "auto"] = "rayleigh"
    damping_ratio: float = bounded(0.05, lo=0.0, hi=1.0, hi_open=True)
    damping_modes: tuple[int, int] = bounded((1, 2), lo=1, hi="STORIES")
    mass_ratios: list[float] | None = bounded(None, lo=1e-6, hi=1e6)
    pdelta: Literal["auto", "on", "off"] = "auto"
    max_iterations: int = bounded(6, lo=1, hi=100)

    def __post_init__(self):
        check_bounds(self)


@dataclass(frozen=True, kw_only=True)
class HalfCycleConfig:
    """Splitting the drift history into half cycles at reversals.

    Attributes
    ----------
    min_increment : a reversal counts only when the drift moves back by more than this
        fraction of the story's peak-to-peak drift (smaller wiggles are noise and are
        merged into the half cycle they interrupt).
    """

    min_increment: float = bounded(0.2, lo=1e-4, hi=1.0, hi_open=True)

    def __post_init__(self):
        check_bounds(self)


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
        ``"auto"`` (the identification's default): 0.6, or 0.8 where the band's high corner is
        below 3 x the first mode (the low-pass smooths the tangent at the end of a yielding half
        cycle; :func:`hlaid.hla.auto.resolve_hla`).
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

    ke_force_fraction: float = bounded(0.5, lo=1e-3, hi=1.0)
    ke_min_samples: int = bounded(6, lo=3, hi=100_000)
    k_window: int = bounded(15, lo=3, hi=100_000)
    k0_min_amplitude: float = bounded(0.08, lo=0.0, hi=1.0, hi_open=True)
    yield_ratio: float | Literal["auto"] = bounded(0.6, lo=1e-3, hi=1.0)
    ke_smoothing: Literal["energy", "monotone", "none"] = "energy"
    ke_trend_z: float = bounded(0.0, lo=0.0, hi=1000.0)

    def __post_init__(self):
        check_bounds(self)


@dataclass(frozen=True, kw_only=True)
class HLAConfig:
    """Hysteresis loop analysis settings (``configs/hla.yaml``)."""

    preprocess: PreprocessConfig = field(default_factory=PreprocessConfig)
    force: ForceConfig = field(default_factory=ForceConfig)
    half_cycles: HalfCycleConfig = field(default_factory=HalfCycleConfig)
    stiffness: StiffnessConfig = field(default_factory=StiffnessConfig)

    def unresolved(self) -> list[str]:
        """The settings still ``"auto"`` that the record decides (``preprocess.displacement``'s
        ``auto`` is resolved by the analysis itself and not listed)."""
        out = []
        if self.preprocess.band_hz == AUTO:
            out.append("preprocess.band_hz")
        if self.force.damping == AUTO:
            out.append("force.damping")
        if self.stiffness.yield_ratio == AUTO:
            out.append("stiffness.yield_ratio")
        return out


def auto_hla_config() -> HLAConfig:
    """HLA settings with every record-dependent choice ``"auto"`` (the identification's default,
    :class:`hlaid.identify.IdentifyConfig`); :class:`HLAConfig` itself keeps fixed defaults."""
    return HLAConfig(preprocess=PreprocessConfig(band_hz=AUTO), force=ForceConfig(damping=AUTO),
                     stiffness=StiffnessConfig(yield_ratio=AUTO))
