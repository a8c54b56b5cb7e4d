"""The identification's settings chosen from the data: every ``"auto"`` of an
:class:`~hlaid.identify.IdentifyConfig`, resolved in one place.

:func:`resolve_settings` takes the record(s) of one building and the config and returns the
concrete config and one :class:`~hlaid.hla.Choice` per setting it chose, with the evidence
(printed by ``hlaid identify``, kept in the clone as ``clone.settings``). A value given in
the config is kept as it is. Several records get one set of choices (the evidence of all of them).

- ``hla.*``: the band, the displacement source, the damping handling and the yield ratio
  (:func:`hlaid.hla.auto.resolve_hla`);
- ``refine.method``: ``least_squares`` where HLA chose a first-mode band: the records are not a
  shear building's above their first mode, so a clone's misfit is model error, which the
  errors-in-variables weighting (sensor noise only) does not model; else ``eiv`` (which still
  falls back to least squares where its fit misses the data by more than the noise);
- ``refine.band_hz``: the band the records hold (:func:`records_band`: 0.1 Hz up to where the
  floor records' spectra stay above their noise floor) where HLA chose a first-mode band (the
  clone is used under the whole ground motion, so it is fitted on every frequency its records
  hold, not only its first mode's); HLA's band where one is given; else 0.1-20 Hz (the replay
  of a shear building follows every mode);
- ``refine.parameters``: all five, without ``k0`` where the floor masses are unknown and no mass
  ratios are given (with assumed ratios the replay fit of k0 is ill-conditioned; k0 stays HLA's);
- ``refine.damping``: fitted where HLA found the assumed damping over-corrects, else held;
- ``refine.compare``: where the records' floor displacements resolve every story's drift (HLA's
  ``preprocess.displacement`` chosen ``measured``), ``disp+drift`` in the records' band of a
  first-mode-band building (the accelerations' higher-mode content is not a shear building's:
  on the steel frame s4's prediction R 0.915 -> 0.964 and mean |peak-drift error| 14 -> 10 %
  against ``acc+drift``), else ``acc+drift``; ``acc`` where they do not.

On a simulated shear building with known masses and its true Rayleigh damping (Table 1) this
gives the settings the identification used before they were chosen from the data.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from ..hla.auto import Choice, HLAResolution, resolve_hla
from ..hla.config import AUTO
from ..measurement import Measurement
from ..record import SettingChoice, Settings
from .config import PARAMETERS, IdentifyConfig

BROAD_BAND_HZ = (0.1, 20.0)
"""``refine.band_hz`` where each record has its own HLA band (a shear building)."""


def records_band(measurements: Measurement | Sequence[Measurement], lo_hz: float = BROAD_BAND_HZ[0]
                 ) -> tuple[float, float]:
    """The band the records hold: ``lo_hz`` (raised to two periods of the shortest record, so
    that its high-pass holds) up to the highest frequency at which some record's floor
    accelerations stay above their noise floor (:func:`hlaid.signal.content_corner`, below the
    Nyquist rule of each record); ``BROAD_BAND_HZ`` where no record has content."""
    from ..signal import cap_corner, content_corner

    meas = [measurements] if isinstance(measurements, Measurement) else list(measurements)
    his = [min(content_corner(np.asarray(m.floor_acc), m.dt), cap_corner(BROAD_BAND_HZ[1] * 4, m.dt)) for m in meas]
    hi = max(his) if his else 0.0
    if meas:
        lo_hz = max(float(lo_hz), float(np.ceil(100.0 * 2.0 / min(m.n_samples * m.dt for m in meas)) / 100.0))
    if not hi > lo_hz:
        return BROAD_BAND_HZ
    return (float(lo_hz), round(float(hi), 2))


@dataclass(frozen=True, eq=False)
class Resolution:
    """The settings chosen: ``config`` (no ``"auto"`` left), ``choices`` (one per setting that
    was ``"auto"``, in the order of the config file) and the config as ``given`` (None: not said)."""

    config: IdentifyConfig
    choices: tuple[Choice, ...]
    given: IdentifyConfig | None = None

    def lines(self) -> list[str]:
        return [c.line() for c in self.choices]

    def to_list(self) -> list[dict]:
        """The choices as mappings (those of :meth:`record`)."""
        return [c.to_dict() for c in self.choices]

    def record(self) -> Settings:
        """What a clone keeps of them (:attr:`hlaid.clone.Clone.settings`)."""
        from ..config import config_to_dict

        return Settings(config=config_to_dict(self.config),
                        choices=tuple(SettingChoice(c.setting, c.value, c.reason) for c in self.choices),
                        given=None if self.given is None else config_to_dict(self.given))


def resolve_settings(measurements: Measurement | Sequence[Measurement], cfg: IdentifyConfig) -> Resolution:
    """Every ``"auto"`` of ``cfg`` chosen from ``measurements`` (records of one building, one set
    of choices for all), with the evidence; values given in ``cfg`` are kept."""
    meas = [measurements] if isinstance(measurements, Measurement) else list(measurements)
    given = cfg
    hla = resolve_hla(meas, cfg.hla, prefix="hla.")
    cfg = dataclasses.replace(cfg, hla=hla.config)
    choices = list(hla.choices)
    rc, new = cfg.refine, cast("dict[str, Any]", {})
    band = cfg.hla.preprocess.band_hz
    if rc.method == AUTO:
        if hla.first_mode_band:
            new["method"] = "least_squares"
            why = ("HLA's first-mode band: the records are not a shear building's above their first mode, so a "
                   "shear-building clone's misfit there is model error, which the errors-in-variables weighting "
                   "(sensor noise only) does not model")
        else:
            new["method"] = "eiv"
            why = ("errors in variables: the records' modes are a shear building's (the fit falls back to least "
                   "squares where it misses the data by more than their noise)")
        choices.append(Choice("refine.method", new["method"], why))
    if rc.band_hz == AUTO:
        if band is None:
            new["band_hz"] = BROAD_BAND_HZ
            why = "each record has its own HLA band: the replay of a shear building is compared over every mode"
        elif hla.first_mode_band:
            new["band_hz"] = records_band(meas)
            why = (f"the band the records hold (their floor accelerations above their noise floor up to "
                   f"{new['band_hz'][1]:g} Hz): the clone is used under the whole ground motion, so its replay is "
                   f"fitted on every mode the records hold, not only in HLA's first-mode band {list(band)}")
        else:
            new["band_hz"] = tuple(band)
            why = "HLA's band (given)"
        choices.append(Choice("refine.band_hz", list(new["band_hz"]), why))
    if rc.parameters == AUTO:
        unknown = [m.name or f"record {k + 1}" for k, m in enumerate(meas) if m.mass is None]
        if unknown and cfg.hla.force.mass_ratios is None:
            new["parameters"] = tuple(p for p in PARAMETERS if p != "k0")
            why = ("the floor masses are unknown (equal ratios assumed): the replay fit of k0 is ill-conditioned, "
                   "k0 stays HLA's")
        else:
            new["parameters"] = PARAMETERS
            why = ("the floor masses are known" if not unknown else "the mass ratios are given") + \
                ": k0 is fitted to the replay with the others"
        choices.append(Choice("refine.parameters", list(new["parameters"]), why))
    if rc.damping == AUTO:
        new["damping"] = cfg.hla.force.damping == "regression"
        why = (f"HLA's damping is {cfg.hla.force.damping}: "
               + ("the assumed ratio is not the building's, so the replay fits it" if new["damping"]
                  else f"the assumed {100 * cfg.damping_ratio:g} % Rayleigh ratio is held"))
        choices.append(Choice("refine.damping", new["damping"], why))
    if rc.compare == AUTO:
        source = cfg.hla.preprocess.displacement
        wide = hla.first_mode_band and rc.band_hz == AUTO
        if source == "measured" and wide:
            new["compare"] = "disp+drift"
            why = ("the records' floor displacements resolve every story's drift and the fit's band holds the "
                   "higher modes, where the records are not a shear building's: a joint fit compares the floor "
                   "displacements and story drifts (least squares), the quantities the clone is judged on, not "
                   "the accelerations, whose higher-mode content a shear building cannot follow")
        elif source == "measured":
            new["compare"] = "acc+drift"
            why = ("the records' floor displacements resolve every story's drift: a joint fit compares the story "
                   "drifts with the accelerations (least squares), so the drift is put in the right story")
        else:
            new["compare"] = "acc"
            why = ("the records' floor displacements do not resolve every story's drift: a joint fit compares the "
                   "accelerations" if source == "integrate" and all(m.floor_disp is not None for m in meas) else
                   "no floor displacements in every record: a joint fit compares the accelerations")
        choices.append(Choice("refine.compare", new["compare"], why))
    if new:
        cfg = dataclasses.replace(cfg, refine=dataclasses.replace(rc, **new))
    if cfg.system is None:
        choices.append(Choice("system", None, "not in the data (the records cannot tell a steel frame from a concrete "
                                              "one): the generic prior holds what they say little about (several "
                                              "records, or one that stays nearly elastic); name it where known"))
    return Resolution(config=cfg, choices=tuple(choices), given=given)


DAMPING_RUNAWAY = 0.45
"""A fitted damping ratio at or above this (the model's bound is 0.5) took up model error, not the
building's damping (a mini shake-table model whose accelerations a heavily damped clone fits
best, at R 0.3): it is held instead."""


def damping_ran_away(cfg: IdentifyConfig, building) -> bool:
    """Whether ``cfg`` fitted the damping and ``building``'s ratio ran to the model's bound."""
    return cfg.refine.damping is True and building.damping.ratio >= DAMPING_RUNAWAY


def held_damping(settings: Resolution, fitted: float, held: float) -> Resolution:
    """``settings`` with the damping held at ``held`` after a fit ran it to ``fitted``: the
    ``refine.damping`` choice says so (the config: ``refine.damping`` false)."""
    cfg = settings.config
    cfg = dataclasses.replace(cfg, refine=dataclasses.replace(cfg.refine, damping=False))
    why = (f"fitted, the damping ratio ran to {fitted:.2f}, the model's bound: it took up model error, not the "
           f"building's damping; held at {held:.3g} and fitted again")
    choices = tuple(c for c in settings.choices if c.setting != "refine.damping")
    return Resolution(config=cfg, choices=choices + (Choice("refine.damping", False, why),), given=settings.given)


def resolve_like(settings: Settings | None, measurements: Measurement | Sequence[Measurement],
                 cfg: IdentifyConfig) -> Resolution:
    """The ``"auto"`` settings of ``cfg`` as a clone was identified with them (its ``settings``),
    so that more records of the same building are analysed alike; a clone that does not say (made
    before the settings were chosen from the data) has them chosen from ``measurements``. Values
    given in ``cfg`` are kept."""
    stored: Mapping = {} if settings is None else settings.config
    cfg_given = cfg
    todo = cfg.unresolved()
    fixed: dict[str, object] = {}
    for key in todo:
        value = _lookup(stored, key)
        if value is not _MISSING and value != AUTO:
            fixed[key] = value
    if not fixed:
        return resolve_settings(measurements, cfg)
    cfg = _with(cfg, fixed)
    rest = resolve_settings(measurements, cfg)
    known = {} if settings is None else {c.setting: c for c in settings.choices}
    kept = [Choice(k, _plain(v), "as the clone was identified" + (f" ({known[k].reason})" if k in known else ""))
            for k, v in fixed.items()]
    return Resolution(config=rest.config, choices=tuple(kept) + rest.choices, given=cfg_given)


_MISSING = object()


def _lookup(d: Mapping, key: str):
    for part in key.split("."):
        if not isinstance(d, Mapping) or part not in d:
            return _MISSING
        d = d[part]
    return d


def _plain(v):
    return list(v) if isinstance(v, tuple) else v


def _with(cfg: IdentifyConfig, values: dict) -> IdentifyConfig:
    """``cfg`` with dotted keys set (lists of the config file as tuples where the schema has them)."""
    from ..config import config_from_dict, config_to_dict

    d = config_to_dict(cfg)
    for key, v in values.items():
        node = d
        *path, last = key.split(".")
        for part in path:
            node = node[part]
        node[last] = v
    return config_from_dict(IdentifyConfig, d, source="the clone's settings")


__all__ = ["Resolution", "resolve_settings", "records_band", "BROAD_BAND_HZ",
           "resolve_like", "damping_ran_away", "held_damping",
           "HLAResolution", "Choice"]
