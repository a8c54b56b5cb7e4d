"""HLA settings chosen from the record(s): the ``"auto"`` values of :class:`~hlaid.hla.HLAConfig`.

:func:`resolve_hla` turns every ``"auto"`` into a value and says why (:class:`Choice`); it takes
several records of one building and makes one set of choices for all of them. The rules:

- **Band** (``preprocess.band_hz``). The first mode ``f1`` is the dominant frequency of the roof
  response (:func:`hlaid.hla.preprocess.dominant_frequency`). The story stiffnesses at ``f1``
  (``Re(F/X)``, the cross-spectrum of story force and drift over the drift's auto-spectrum) give
  a shear building whose second mode ``f2_shear`` is where a shear building's second mode would
  be. A *separated* second mode is the most prominent coherent peak of the roof/ground transfer
  function between ``0.6 f2_shear`` and ``2 f2_shear``. A record is not a shear building above
  its first mode (joint rotations couple the stories: a story's force over its drift depends on
  the mode) where both hold:

  1. its separated second mode lies more than :data:`SHEAR_TOLERANCE` away from ``f2_shear``;
  2. HLA's elastic stiffness of a story, one number per half cycle for a shear building, scatters
     at least :data:`CONSISTENCY_GAIN` times more over the half cycles in the record's own band
     than in the first-mode band (each half cycle's elastic window sees another mix of modes).
     A yielding shear building's second mode also sits above ``f2_shear`` (the first mode is
     softened), but its stiffness is no more consistent in a first-mode band.

  Such a record gets the first-mode band, ``highpass_ratio x f1`` to ``sqrt(f1 f2)``; any other
  the band of its own spectrum (``null``: ``highpass_ratio x f1`` to ``max(20 Hz, 4 f1)``).
- **Yield ratio** (``stiffness.yield_ratio``): 0.6, or :data:`SMOOTHED_YIELD_RATIO` where the
  band's high corner is below :data:`HARMONIC` x ``f1``: the low-pass then takes the third
  harmonic of a yielding loop, and smooths the tangent at the end of a yielding half cycle.
- **Damping** (``force.damping``): HLA with the assumed Rayleigh damping; where its half cycles
  dissipate negative energy more often than a passive story can (one-sided sign test over every
  story's half cycles, :data:`DAMPING_P`), the assumed damping over-corrects and ``regression``
  fits the damping per half cycle instead.
- **Displacement** (``preprocess.displacement``): the file's floor displacements where they resolve
  every story's drift (each story's drift from them correlates with the integrated accelerations'
  by at least :data:`DRIFT_AGREEMENT`), else the accelerations integrated (a small drift above an
  isolation layer lies below the displacement sensors' noise, which scales with a floor's whole
  motion); the accelerations where the file has no displacements.
- **First mode** (the band's low corner and ``f1`` above): the dominant frequency of the roof's
  relative acceleration, or the peak of its measured relative displacement where that lies far
  below it (:func:`hlaid.hla.preprocess.first_mode`: an isolation mode).

The thresholds were set on the real records and on simulated shear buildings
(docs/identification.md, "Settings chosen from the data").
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from .. import _progress
from ..measurement import Measurement
from .analysis import floor_masses, floor_motion, story_force
from .analysis import run_hla as _run_hla
from .config import AUTO, HLAConfig, StiffnessConfig
from .preprocess import drift_agreement, first_mode, story_drift
from .result import HLAResult

SHEAR_TOLERANCE = 1.25
"""A separated second mode within this factor of the shear building's (either way) is a shear
building's. The unknown mass ratios alone move it by about 10 % (a simulated shear building with
masses 1 : 1 : 0.52 analysed with equal ratios: 0.90); the steel frame's is 1.40-1.49 x, the mini
shake-table models' 1.07-1.11 x."""
MODE_COHERENCE = 0.6
"""A transfer-function peak counts as a mode where the ground and roof are at least this coherent
(a noise peak of a 10 %-noise record is 0.3-0.45)."""
MODE_PROMINENCE = 0.2
"""... and where it stands out by at least this fraction of the transfer function at the first mode."""
CONSISTENCY_GAIN = 2.0
"""How many times more consistent (robust spread of each half cycle's ke about the story's trend,
averaged over the stories) HLA's stiffness must be in the first-mode band: the steel frame's
2.6-8x, a yielding simulated shear building's 0.5x (Table 1), the mini shake-table models' 0.4-1.2x."""
HARMONIC = 3.0
"""A band whose high corner is below this multiple of ``f1`` cuts a loop's third harmonic."""
SMOOTHED_YIELD_RATIO = 0.8
"""The yield ratio under such a band (with 0.6 a story of the steel frame's s3 record with an
18.7 mm residual drift reads elastic in its first-mode band)."""
DAMPING_P = 0.05
"""The sign test's level: the assumed damping over-corrects where as many or more of the half
cycles dissipate negative energy than a fair coin would give with this probability."""
DRIFT_AGREEMENT = 0.8
"""``preprocess.displacement: auto`` takes the measured floor displacements where every story's
drift from them correlates with the integrated accelerations' by at least this in the band
(:func:`hlaid.hla.preprocess.drift_agreement`): 0.99-1.0 on the steel frame and the hotel,
0.92-0.99 on simulated frames with 10 % noise, -0.2-0.4 above a simulated isolation layer whose
drifts lie below the displacement sensors' noise (their noise scales with a floor's whole motion)."""
SEGMENT_S = 10.0
"""Length of the Welch segments of the modal evidence [s] (0.1 Hz resolution)."""


@dataclass(frozen=True)
class Choice:
    """One setting chosen from the data.

    Attributes
    ----------
    setting : its key in the identification config (``"hla.preprocess.band_hz"``)
    value : what was chosen (as it would be written in the config)
    reason : the evidence, one sentence
    """

    setting: str
    value: Any
    reason: str

    def line(self) -> str:
        """One line for a terminal."""
        return f"{self.setting} = {show_value(self.value)}: {self.reason}"

    def to_dict(self) -> dict:
        return {"setting": self.setting, "value": self.value, "reason": self.reason}


def show_value(value: Any) -> str:
    """A chosen value as a user would write it."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(show_value(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


@dataclass(frozen=True, eq=False)
class Modes:
    """The modal evidence of one record.

    Attributes
    ----------
    f1 : the dominant frequency of the roof response [Hz] (the effective first mode)
    stiffness : ``(story,)`` ``Re(F/X)`` at ``f1`` (per unit mass where the masses are unknown)
    f2_shear : the second mode of the shear building of those stiffnesses [Hz] (None: one story,
        or a stiffness that is not positive)
    f2 : a separated second mode of the roof/ground transfer function near it [Hz] (None: none)
    """

    f1: float
    stiffness: np.ndarray
    f2_shear: float | None
    f2: float | None

    @property
    def shear(self) -> bool | None:
        """Whether the second mode is a shear building's (None: no separated second mode)."""
        if self.f2 is None or self.f2_shear is None:
            return None
        r = self.f2 / self.f2_shear
        return 1.0 / SHEAR_TOLERANCE <= r <= SHEAR_TOLERANCE

    def describe(self) -> str:
        if self.f2_shear is None:
            return f"first mode {self.f1:.2f} Hz"
        if self.f2 is None:
            return (f"first mode {self.f1:.2f} Hz, no separated second mode near {self.f2_shear:.2f} Hz (where the "
                    "shear building of its story stiffnesses has it)")
        return (f"first mode {self.f1:.2f} Hz, second mode {self.f2:.2f} Hz = {self.f2 / self.f2_shear:.2f} x the "
                f"shear building's {self.f2_shear:.2f} Hz")


def _segment(meas: Measurement) -> int:
    n = int(2 ** round(np.log2(SEGMENT_S / meas.dt)))
    return int(max(16, min(n, meas.n_samples // 4)))


def shear_frequencies(k: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """Natural frequencies [Hz] of the shear building of story stiffnesses ``k`` and floor masses."""
    from scipy import linalg

    n = len(k)
    K = np.diag(k + np.append(k[1:], 0.0))
    for i in range(n - 1):
        K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    w2 = linalg.eigh(K, np.diag(mass), eigvals_only=True)
    return np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi)


def modes(meas: Measurement, cfg: HLAConfig) -> Modes:
    """The modal evidence of ``meas`` (see the module's rules); ``cfg`` gives the displacement
    source, the mass ratios and the high-pass ratio."""
    from scipy import signal

    from ..signal import max_corner

    dt = meas.dt
    ground, roof = np.asarray(meas.ground_acc, float), np.asarray(meas.floor_acc, float)[:, -1]
    f1 = first_mode(ground, roof, dt, None if meas.floor_disp is None else np.asarray(meas.floor_disp)[:, -1])
    nper = _segment(meas)
    wide = dataclasses.replace(cfg, preprocess=dataclasses.replace(
        cfg.preprocess, band_hz=(cfg.preprocess.highpass_ratio * f1, max_corner(dt))))
    acc, _, _, disp = floor_motion(meas, wide)
    m, _ = floor_masses(meas, cfg)
    x, force = story_drift(disp), story_force(acc, m)
    fs = 1.0 / dt
    f, pxx = signal.welch(x, fs=fs, nperseg=nper, axis=0)
    _, pxf = signal.csd(x, force, fs=fs, nperseg=nper, axis=0)
    k = (pxf[int(np.argmin(np.abs(f - f1)))] / np.maximum(pxx[int(np.argmin(np.abs(f - f1)))], 1e-300)).real
    if meas.n_floors < 2 or not np.all(np.isfinite(k) & (k > 0)):
        return Modes(f1=f1, stiffness=k, f2_shear=None, f2=None)
    f2s = float(shear_frequencies(k, m)[1])
    _, pgg = signal.welch(ground, fs=fs, nperseg=nper)
    _, pgr = signal.csd(ground, roof, fs=fs, nperseg=nper)
    _, coh = signal.coherence(ground, roof, fs=fs, nperseg=nper)
    h = np.abs(pgr) / np.maximum(pgg, 1e-300)
    near_f1 = (f >= 0.5 * f1) & (f <= 1.5 * f1)
    h1 = float(np.max(h[near_f1])) if near_f1.any() else float(h[int(np.argmin(np.abs(f - f1)))])
    window = np.flatnonzero((f >= max(0.6 * f2s, 1.5 * f1)) & (f <= min(2.0 * f2s, 0.4 * fs)))
    f2 = None
    if window.size >= 3:
        peaks, props = signal.find_peaks(h[window], prominence=MODE_PROMINENCE * h1)
        good = [j for j in range(peaks.size) if coh[window[peaks[j]]] >= MODE_COHERENCE]
        if good:
            best = max(good, key=lambda j: props["prominences"][j])
            f2 = float(f[window[peaks[best]]])
    return Modes(f1=f1, stiffness=k, f2_shear=f2s, f2=f2)


def dissipation_signs(res: HLAResult) -> tuple[int, int]:
    """Of all half cycles of every story, how many dissipate negative energy, and how many there
    are: the work of the story force along the half cycle less the change of its elastic energy
    ``f x / 2``."""
    neg = total = 0
    for s in res.stories:
        f, x = np.asarray(s.force_fit), np.asarray(s.drift)
        work = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(x))]) - 0.5 * f * x
        hc = s.half_cycles
        d = work[np.asarray(hc.end)] - work[np.asarray(hc.start)]
        neg += int(np.sum(d < 0))
        total += int(d.size)
    return neg, total


def sign_test(negative: int, total: int) -> float:
    """One-sided p-value of at least ``negative`` of ``total`` under a fair coin."""
    from scipy import stats

    return float(stats.binom.sf(negative - 1, total, 0.5)) if total else 1.0


@dataclass(frozen=True, eq=False)
class HLAResolution:
    """The HLA settings chosen: ``config`` (no ``"auto"`` left), ``choices`` (one per setting
    that was ``"auto"``), ``modes`` (the modal evidence per record, None where the band was given)."""

    config: HLAConfig
    choices: tuple[Choice, ...]
    modes: tuple[Modes, ...] | None = None

    @property
    def first_mode_band(self) -> bool:
        """Whether the band was chosen as a first-mode band (the records are not a shear building
        above their first mode)."""
        return any(c.setting.endswith("preprocess.band_hz") and c.value is not None for c in self.choices)


def resolve_hla(measurements: Measurement | Sequence[Measurement], cfg: HLAConfig, *,
                prefix: str = "hla.") -> HLAResolution:
    """Every ``"auto"`` of ``cfg`` chosen from ``measurements`` (records of one building: one set
    of choices for all), with the evidence. ``prefix`` is put before each setting's key in the
    choices (the identification config's ``"hla."``)."""
    meas = [measurements] if isinstance(measurements, Measurement) else list(measurements)
    p, choices = cfg.preprocess, []
    evidence = None
    if p.band_hz == AUTO:
        evidence = tuple(modes(m, cfg) for m in meas)
        band, reason = _band(evidence, meas, cfg)
        cfg = dataclasses.replace(cfg, preprocess=dataclasses.replace(cfg.preprocess, band_hz=band))
        choices.append(Choice(prefix + "preprocess.band_hz", None if band is None else list(band), reason))
    if cfg.preprocess.displacement == AUTO:
        source, reason = _displacement(meas, cfg)
        cfg = dataclasses.replace(cfg, preprocess=dataclasses.replace(cfg.preprocess, displacement=source))
        choices.append(Choice(prefix + "preprocess.displacement", source, reason))
    if cfg.stiffness.yield_ratio == AUTO:
        if evidence is None:
            evidence = tuple(modes(m, cfg) for m in meas)
        value, reason = _yield_ratio(cfg, evidence, meas)
        cfg = dataclasses.replace(cfg, stiffness=dataclasses.replace(cfg.stiffness, yield_ratio=value))
        choices.append(Choice(prefix + "stiffness.yield_ratio", value, reason))
    if cfg.force.damping == AUTO:
        trial = dataclasses.replace(cfg, force=dataclasses.replace(cfg.force, damping="rayleigh"))
        neg = total = 0
        for m in meas:
            a, b = dissipation_signs(_run_hla(m, trial))
            neg, total = neg + a, total + b
        pval = sign_test(neg, total)
        zeta = f"{100 * cfg.force.damping_ratio:g} %"
        damping: Literal["rayleigh", "regression"]
        if pval < DAMPING_P:
            damping = "regression"
            reason = (f"the assumed {zeta} Rayleigh damping over-corrects: {neg} of {total} half cycles dissipate "
                      f"negative energy, which a passive story cannot (sign test p = {pval:.2g})")
        else:
            damping = "rayleigh"
            reason = (f"the assumed {zeta} Rayleigh damping leaves {neg} of {total} half cycles with negative "
                      f"dissipated energy, as many as noise gives (sign test p = {pval:.2g})")
        cfg = dataclasses.replace(cfg, force=dataclasses.replace(cfg.force, damping=damping))
        choices.append(Choice(prefix + "force.damping", damping, reason))
    return HLAResolution(config=cfg, choices=tuple(choices), modes=evidence)


def _displacement(meas: Sequence[Measurement], cfg: HLAConfig) -> tuple[Literal["measured", "integrate", "auto"], str]:
    """The displacement rule: ``(source, reason)``."""
    from .analysis import resolved_band

    have = [m.floor_disp is not None for m in meas]
    if not any(have):
        return "integrate", "no floor displacements in the file: the accelerations are integrated"
    if not all(have):
        return "auto", "each record's own: measured where it has floor displacements"
    worst, where = np.inf, ""
    for k, m in enumerate(meas):
        assert m.floor_disp is not None
        agree = drift_agreement(m.floor_disp, m.floor_acc, m.ground_acc, m.dt, resolved_band(m, cfg),
                                cfg.preprocess.order)
        i = int(np.argmin(agree))
        if agree[i] < worst:
            worst, where = float(agree[i]), f"story {i + 1}" + (f" of {m.name or f'record {k + 1}'}" if len(meas) > 1
                                                                  else "")
    if worst < DRIFT_AGREEMENT:
        return "integrate", (f"the measured displacements do not resolve every story's drift ({where}: correlation "
                             f"{worst:.2f} with the integrated accelerations', under {DRIFT_AGREEMENT:g}; the drift "
                             "lies below the displacement sensors' noise): the accelerations are integrated")
    return "measured", (f"the file has floor displacements and they resolve every story's drift (correlation >= "
                        f"{worst:.2f} with the integrated accelerations')")


def stiffness_scatter(res: HLAResult) -> float:
    """How much HLA's elastic stiffness scatters over the half cycles: per story the robust
    spread (1.4826 x median absolute log) of each large half cycle's ke about the story's smoothed
    ke, averaged over the stories."""
    spread = []
    for s in res.stories:
        t = s.half_cycles
        ok = np.isfinite(t.ke_raw) & (t.ke_raw > 0) & np.isfinite(t.ke) & (t.ke > 0)
        ok &= t.drift_increment >= res.config.stiffness.k0_min_amplitude * np.ptp(s.drift)
        if ok.any():
            spread.append(1.4826 * float(np.median(np.abs(np.log(t.ke_raw[ok] / t.ke[ok])))))
    return float(np.mean(spread)) if spread else float("nan")


def _consistency(meas: Measurement, cfg: HLAConfig, band: tuple[float, float]) -> tuple[float, float]:
    """The stiffness scatter of ``meas`` in its own band and in ``band`` (NaN where HLA fails)."""
    from ..errors import InputError

    trial = dataclasses.replace(cfg, force=dataclasses.replace(
        cfg.force, damping="rayleigh" if cfg.force.damping == AUTO else cfg.force.damping),
        stiffness=dataclasses.replace(cfg.stiffness, yield_ratio=StiffnessConfig().yield_ratio))
    out = []
    for b in (None, band):
        try:
            out.append(stiffness_scatter(_run_hla(meas, dataclasses.replace(
                trial, preprocess=dataclasses.replace(trial.preprocess, band_hz=b)))))
        except InputError:
            out.append(float("nan"))
    return out[0], out[1]


def _band(evidence: Sequence[Modes], meas: Sequence[Measurement], cfg: HLAConfig):
    """The band rule: ``(band or None, reason)``."""
    from ..signal import max_corner

    ratio = cfg.preprocess.highpass_ratio
    names = [m.name or f"record {k + 1}" for k, m in enumerate(meas)]
    what = "; ".join(f"{n}: {e.describe()}" for n, e in zip(names, evidence)) if len(meas) > 1 \
        else evidence[0].describe()
    votes, gains = [], []
    for m, e in zip(meas, evidence):
        if e.shear is None:
            continue
        if e.shear:
            votes.append(True)
            continue
        assert e.f2 is not None  # shear is False only with a separated second mode
        wide, first = _consistency(m, cfg, (ratio * e.f1, min(float(np.sqrt(e.f1 * e.f2)), max_corner(m.dt))))
        gain = wide / first if np.isfinite(wide) and np.isfinite(first) and first > 0 else float("nan")
        gains.append(gain)
        votes.append(not gain >= CONSISTENCY_GAIN)
    gain_txt = ", ".join(f"{g:.1f}x" for g in gains)
    if not votes:
        return None, f"each record's band from its spectrum ({what})"
    if 2 * sum(not v for v in votes) < len(votes):
        if gains:
            return None, (f"each record's band from its spectrum: HLA's stiffness is not more consistent in a "
                          f"first-mode band ({gain_txt}, under {CONSISTENCY_GAIN:g}x: {what})")
        return None, f"each record's band from its spectrum: its second mode is a shear building's ({what})"
    f1 = min(e.f1 for e in evidence)
    hi = min(np.sqrt(e.f1 * e.f2) for e in evidence if e.shear is False and e.f2 is not None)
    hi = min(hi, min(max_corner(m.dt) for m in meas))
    band = (round(float(ratio * f1), 2), round(float(hi), 2))
    return band, (f"first-mode band, {ratio:g} x f1 to sqrt(f1 f2): not a shear building above its first mode "
                  f"({what}; HLA's stiffness {gain_txt} more consistent over the half cycles in it)")


def _yield_ratio(cfg: HLAConfig, evidence: Sequence[Modes], meas: Sequence[Measurement]):
    f1 = float(np.median([e.f1 for e in evidence]))
    band = cfg.preprocess.band_hz
    default = StiffnessConfig().yield_ratio
    if band is None:
        return default, f"the band's high corner (max(20 Hz, 4 x f1)) keeps a loop's harmonics (f1 {f1:.2f} Hz)"
    hi = float(band[1])
    if hi < HARMONIC * f1:
        return SMOOTHED_YIELD_RATIO, (f"the band's high corner {hi:.3g} Hz is below {HARMONIC:g} x f1 ({f1:.2f} Hz): "
                                      "it smooths the tangent at the end of a yielding half cycle")
    return default, f"the band's high corner {hi:.3g} Hz keeps a loop's third harmonic ({HARMONIC:g} x f1 {f1:.2f} Hz)"


def run_hla(measurement: Measurement, config: HLAConfig | None = None) -> HLAResult:
    """Hysteresis loop analysis (:func:`hlaid.hla.analysis.run_hla`), its ``"auto"`` settings
    chosen from the record first (:func:`resolve_hla`, each choice said on the terminal)."""
    cfg = config or HLAConfig()
    if cfg.unresolved():
        r = resolve_hla(measurement, cfg, prefix="")
        for c in r.choices:
            _progress.info(f"[hla] {c.line()}")
        cfg = r.config
    return _run_hla(measurement, cfg)
