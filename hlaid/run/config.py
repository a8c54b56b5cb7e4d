"""The ``hlaid run`` config (measurement, identification, IDA, assessment): schemas only.

Loading one imports no heavy library of its own (the measurement, the IDA and the assessment
blocks are light); the ``identify`` block's schema is :mod:`hlaid.identify.config`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..bounds import check_bounds, with_bounds
from ..config import config_from_node, load_yaml
from ..errors import InputError
from ..ida.config import IDAConfig
from ..identify.config import IdentifyConfig
from ..loss.config import LossConfig
from ..model.schema import STORY_BOUNDS
from ..specs import SimulationConfig
from ..uncertainty.config import AssessConfig

RESERVED_OPTIONS = ("path", "kind", "format")
"""Names a reader's ``options`` cannot hold: the reading itself takes them (the file, what it is)."""


def check_reader_options(options: dict, where: str) -> None:
    """Refuse reader ``options`` that no reader takes as such: a name of :data:`RESERVED_OPTIONS`
    (the file is ``file``, its layout ``format``) or a key that is not a name."""
    for k in options:
        if not isinstance(k, str) or not k.isidentifier():
            raise InputError(f"{where}: {str(k)[:40]!r} is no option name (expected a name such as event or floors)")
        if k in RESERVED_OPTIONS:
            what = "the file is given as file:" if k == "path" else "the layout is given as format:" \
                if k == "format" else "what is read is told by the command"
            raise InputError(f"{where}.{k} is not a reader option ({what}); remove it")


@dataclass(frozen=True, kw_only=True)
class MeasurementSource:
    """Where the measurement comes from: a file (``file``, optional ``format`` and reader
    ``options``), several files of one building's events, oldest first (``file: [s1, s2, s3]``:
    the clone of events 1..k as ``hlaid identify`` makes it, the decisions at the last, or at the
    one ``decide_at`` names: its file as given or its name without the folder and suffixes, the
    clone then of the events up to it), or a simulation (``simulate``: the ``hlaid simulate``
    config). ``mass_t`` and ``height_mm`` add or replace floor masses [t] and story heights [mm]."""

    file: str | list[str] | None = None
    decide_at: str | None = None
    format: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    simulate: SimulationConfig | None = None
    mass_t: list[float] | None = with_bounds(STORY_BOUNDS["mass"], None)
    height_mm: list[float] | None = with_bounds(STORY_BOUNDS["height"], None)

    def __post_init__(self):
        if (self.file is None) == (self.simulate is None):
            raise InputError("give exactly one of measurement.file or measurement.simulate")
        check_reader_options(self.options, "measurement.options")
        check_bounds(self)
        if isinstance(self.file, list) and not self.file:
            raise InputError("measurement.file: give a file, or a list of one building's event files, oldest first")
        if self.decide_at is not None:
            files = [self.file] if isinstance(self.file, str) else list(self.file or ())
            if not any(self.decide_at in (f, _stem(f)) for f in files):
                raise InputError(f"measurement.decide_at names no file of measurement.file ({len(files)} given): "
                                 "give one of them as written, or its name without folder and suffixes")

    @property
    def files(self) -> list[str]:
        """The event files whose clone the decisions rest on, oldest first, up to ``decide_at``."""
        files = [] if self.file is None else [self.file] if isinstance(self.file, str) else list(self.file)
        if self.decide_at is None:
            return files
        k = next(i for i, f in enumerate(files) if self.decide_at in (f, _stem(f)))
        return files[:k + 1]


def _stem(path: str) -> str:
    """A file's name without its folder and suffixes (``runs/s1.tsv.gz`` -> ``s1``)."""
    name = Path(path).name
    return name.split(".")[0] if not name.startswith(".") else name


@dataclass(frozen=True, kw_only=True)
class RunConfig:
    """``hlaid run`` config: measurement, identification and (optionally) IDA settings, the
    ensemble assessment (``assess``, needs ``ida``) and the FEMA P-58 losses (``loss``, needs ``ida``
    and the extra ``hlaid[loss]``)."""

    measurement: MeasurementSource
    identify: IdentifyConfig = field(default_factory=IdentifyConfig)
    ida: IDAConfig | None = None
    assess: AssessConfig | None = None
    loss: LossConfig | None = None
    name: str = "hlaid run"


def load_run_config(path) -> RunConfig:
    """Load a run config; its ``ida`` block is validated against :class:`hlaid.ida.IDAConfig`
    (errors there give the line of the offending value in the run config, like any other)."""
    source = str(path)
    root = load_yaml(source)
    cfg = config_from_node(RunConfig, root, source)
    if cfg.assess is not None and cfg.ida is None:
        raise InputError(f"{source}: the assess block needs an ida block (records and IDA settings)")
    if cfg.loss is not None and cfg.ida is None:
        raise InputError(f"{source}: the loss block needs an ida block (the collapse fragility and the stripes)")
    return cfg


def input_paths(cfg: RunConfig, base_dir: str | Path | None) -> list[Path]:
    """The files and folders a run reads (its measurement, motion and IDA records), relative
    paths taken from ``base_dir``: an output of the run must not replace one of them."""
    def resolve(spec: str | None) -> list[Path]:
        if not spec or spec.startswith("builtin"):
            return []
        p = Path(spec)
        return [p if p.is_absolute() or base_dir is None else Path(base_dir) / p]

    m = cfg.measurement
    out = [p for f in m.files for p in resolve(f)] + (resolve(m.simulate.motion.file) if m.simulate is not None
                                                      else [])
    for spec in (cfg.ida.record_specs(base_dir) or []) if cfg.ida is not None else []:
        out += resolve(spec)
    if cfg.loss is not None:
        out += resolve(cfg.loss.inventory)
    return out


__all__ = ["MeasurementSource", "RunConfig", "load_run_config", "input_paths"]
