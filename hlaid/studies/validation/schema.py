"""Schema of a validation study (``configs/validate_real.yaml``): structures, events, targets."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from ...config import config_from_dict, config_to_dict, load_config
from ...errors import InputError
from ...identify import IdentifyConfig
from ...io import MEASUREMENT_READERS
from ...io.formats import read_by_format
from ...measurement import Measurement


@dataclass(frozen=True, kw_only=True)
class EventSpec:
    """One recorded event of a structure.

    Attributes
    ----------
    name : label used in ``identify_from`` / ``predict`` and in the tables
    path : data file or folder, relative to ``data_dir``
    options : reader options of this event (e.g. ``{event: 13}`` for the hotel)
    """

    name: str
    path: str
    options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, kw_only=True)
class StructureSpec:
    """A structure, its events, and how its clones are identified and compared.

    Attributes
    ----------
    name : short label (file names, tables); ``title`` a longer one
    reader : a :data:`hlaid.io.MEASUREMENT_READERS` name (null: detected from the file)
    options : reader options shared by every event
    events : the recorded events
    identify_from : events a clone is identified from
    predict : events every clone predicts (null: every event but its own); the clone's own
        event is always replayed too (self-replay, reported apart)
    identify_config : identification YAML (:class:`~hlaid.identify.IdentifyConfig`), relative
        to the validation config (null: the defaults)
    overrides : nested settings merged into it (e.g. ``{hla: {preprocess: {band_hz: [0.3, 2.5]}}}``)
    mass_ratios : relative floor masses (masses are unknown; null: equal)
    clone : ``"auto"``: the paper's identification, the fallback when no story yielded;
        ``"linear"``: the linear clone directly (for data known to be linear, where a yield
        flag of HLA would be an artefact)
    fallback : ``"linear"``: a labelled linear clone when no story yielded; ``"none"``: skip
    fallback_fit : what the replay fits of the linear clone, starting from HLA's k0 and the
        config's damping ratio (see :func:`linear_clone`)
    compare_band_hz : band [Hz] of the compared displacements and of the HLA of the predicted
        events (null: the HLA band that the identification config gives for each event)
    input_lowpass_hz : low-pass [Hz] of the ground motion the clone is driven by (null: the
        upper corner of the compared band)
    levels : names of the measured levels, bottom to top (null: floor 1, 2, ...)
    optional : run only when named (``structures=`` / ``--structures``), e.g. a sensitivity variant
    notes : what the data allow, printed with the tables
    """

    name: str
    title: str = ""
    reader: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    events: list[EventSpec]
    identify_from: list[str]
    predict: list[str] | None = None
    identify_config: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    mass_ratios: list[float] | None = None
    clone: Literal["auto", "linear"] = "auto"
    fallback: Literal["linear", "none"] = "linear"
    fallback_fit: Literal["scale+damping", "k0+damping", "k0", "damping", "none"] = "scale+damping"
    optional: bool = False
    compare_band_hz: tuple[float, float] | None = None
    input_lowpass_hz: float | None = None
    levels: list[str] | None = None
    notes: str = ""

    def __post_init__(self):
        names = [e.name for e in self.events]
        if len(set(names)) != len(names):
            raise InputError(f"structure {self.name!r}: event names must be unique, got {names}")
        for what, lst in (("identify_from", self.identify_from), ("predict", self.predict or [])):
            bad = [n for n in lst if n not in names]
            if bad:
                raise InputError(f"structure {self.name!r}: {what} names unknown events {bad}; "
                                 f"expected some of {names}")
        if not self.identify_from:
            raise InputError(f"structure {self.name!r}: identify_from is empty")
        if self.reader is not None and self.reader not in MEASUREMENT_READERS:
            raise InputError(f"structure {self.name!r}: reader {self.reader!r} unknown; expected one of "
                             f"{', '.join(sorted(MEASUREMENT_READERS))}")
        if self.compare_band_hz is not None and not 0 <= self.compare_band_hz[0] < self.compare_band_hz[1]:
            raise InputError(f"structure {self.name!r}: compare_band_hz = {list(self.compare_band_hz)}; expected "
                             "[low, high] with 0 <= low < high")

    def event(self, name: str) -> EventSpec:
        return next(e for e in self.events if e.name == name)

    def targets_of(self, source: str) -> list[str]:
        return [e.name for e in self.events if e.name != source] if self.predict is None else \
            [n for n in self.predict if n != source]


@dataclass(frozen=True, kw_only=True)
class PaperTargets:
    """The paper's real-building results (E-Defense 3-story): replayed displacement
    ``R_corrcoef`` per floor and mean, and the stiffness-evolution error."""

    r_per_floor: list[float] = field(default_factory=lambda: [0.94, 0.92, 0.89])
    r_mean: float = 0.92
    stiffness_error: float = 0.021


@dataclass(frozen=True, kw_only=True)
class ValidationConfig:
    """``configs/validate_real.yaml``.

    Attributes
    ----------
    data_dir : folder of the datasets, relative to the config file
    cache_dir : classifier cache (null: ``~/.cache/hlaid/svm``; ``""``: none)
    structures : the structures
    targets : the paper's numbers the results are held against
    source : the config file (set by :func:`load_validation_config`)
    """

    data_dir: str = "."
    cache_dir: str | None = None
    structures: list[StructureSpec]
    targets: PaperTargets = field(default_factory=PaperTargets)
    source: str = ""

    def __post_init__(self):
        names = [s.name for s in self.structures]
        if len(set(names)) != len(names):
            raise InputError(f"structure names must be unique, got {names}")


def load_validation_config(path) -> ValidationConfig:
    """Load ``path`` (validated; FILE:LINE in every error) and resolve its relative paths
    against the config's folder."""
    cfg = load_config(path, ValidationConfig)
    base = Path(path).resolve().parent
    structures = [dataclasses.replace(s, identify_config=None if s.identify_config is None else
                                      str(base / s.identify_config)) for s in cfg.structures]
    return dataclasses.replace(cfg, data_dir=str(base / cfg.data_dir), structures=structures, source=str(path))


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def identify_config_of(spec: StructureSpec, *, source: str = "<validation>") -> IdentifyConfig:
    """The structure's :class:`IdentifyConfig`: its file, the overrides, the mass ratios."""
    base = load_config(spec.identify_config, IdentifyConfig) if spec.identify_config else IdentifyConfig()
    d = _merge(config_to_dict(base), spec.overrides)
    if spec.mass_ratios is not None:
        d = _merge(d, {"hla": {"force": {"mass_ratios": list(spec.mass_ratios)}}})
    return config_from_dict(IdentifyConfig, d, source=f"{source}: structure {spec.name!r} (identify config)")


def read_event(spec: StructureSpec, event: str, data_dir: str) -> Measurement:
    """The measurement of ``event`` (reader options: the structure's, then the event's)."""
    ev = spec.event(event)
    return read_by_format(Path(data_dir) / ev.path, spec.reader, **{**spec.options, **ev.options})
