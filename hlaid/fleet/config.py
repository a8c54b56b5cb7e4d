"""``hlaid fleet`` configuration: buildings, the events they recorded, the IDA records and settings.

Validated on load like every hlaid config (:mod:`hlaid.config`): unknown keys, wrong types and
bad values are ``FILE:LINE: key: what is wrong`` (exit 2). Relative paths are taken from the
folder of the config file. Example (``configs/fleet_example.yaml``)::

    name: downtown network, 2026-11-24
    events: [{name: ev1, description: M6.1 at 12 km}]
    records: builtin-suite         # IDA records: a folder, builtin-suite, or a list of files
    n_ensemble: 20                 # clones per building (hlaid.uncertainty)
    seed: 0
    identify: {training: {samples: 800}}        # any key of configs/identify.yaml
    ida: {n_levels: 10, drift_limit: 0.10}      # any key of configs/ida.yaml except records
    loss: {system: steel-moment-frame}          # optional: FEMA P-58 losses at each event (hlaid[loss])
    history: false                 # true: a building's unit at event k is the clone of its events 1..k
    cluster: {n_workers: 2, threads_per_worker: 1}
    buildings:
      - name: B001
        mass_t: [17.5, 17.5, 9.2]
        height_mm: [3000, 3000, 3000]
        measurements:
          ev1: {file: b001_ev1.npz}                  # any format hlaid reads ...
      - name: B002
        measurements:
          ev1:
            station:                                 # ... or station data through ObsPy
              files: [b002.mseed]
              ground: {channel: XX.B002.00.HNE, units: m/s^2}
              floors: [{channel: XX.B002.01.HNE}, {channel: XX.B002.02.HNE}]
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..bounds import SEED, bounded, check_bounds, with_bounds
from ..config import config_from_node, load_yaml
from ..errors import ConfigError, InputError
from ..ida.config import IDAConfig
from ..identify.config import IdentifyConfig
from ..io.station import StationConfig
from ..loss.config import LossConfig
from ..model.schema import STORY_BOUNDS
from ..specs import SimulationConfig
from ..uncertainty.config import MAX_ENSEMBLE, N_ENSEMBLE

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
"""Building and event names: they name result files (``buildings/NAME@EVENT.json``)."""


def _check_name(kind: str, name: str) -> None:
    if not _NAME.fullmatch(name):
        raise InputError(f"{kind} name {name!r} must be 1-64 letters, digits, '_', '.' or '-' "
                         "(it names the result files), starting with a letter or digit")


@dataclass(frozen=True, kw_only=True)
class EventSpec:
    """An earthquake the buildings recorded."""

    name: str
    description: str = ""

    def __post_init__(self):
        _check_name("event", self.name)


MEMORY_LIMIT = re.compile(r"\s*(auto|(\d+(\.\d*)?|\.\d+)(e[+-]?\d+)?\s*([kmgtp]i?b?|b)?)\s*\Z", re.I)
"""What dask reads as a worker's memory limit: 'auto', a number of bytes with an optional unit, or a
fraction (<= 1) of the machine's memory."""


@dataclass(frozen=True, kw_only=True)
class FleetMeasurement:
    """One building's record of one event: a measurement ``file`` (any format hlaid reads, with
    ``format``/``options`` as in ``hlaid run``), ``station`` data through ObsPy, or a
    ``simulate`` config (tests, benchmarks). ``mass_t``/``height_mm`` replace the building's."""

    file: str | None = None
    format: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    station: StationConfig | None = None
    simulate: SimulationConfig | None = None
    mass_t: list[float] | None = with_bounds(STORY_BOUNDS["mass"], None)
    height_mm: list[float] | None = with_bounds(STORY_BOUNDS["height"], None)

    def __post_init__(self):
        check_bounds(self)
        from ..run.config import check_reader_options

        check_reader_options(self.options, "options")
        given = [k for k in ("file", "station", "simulate") if getattr(self, k) is not None]
        if len(given) != 1:
            raise InputError("give exactly one of file, station or simulate"
                             + (f" (got {', '.join(given)})" if given else ""))


@dataclass(frozen=True, kw_only=True)
class BuildingEntry:
    """A building: its name, floor masses [t] and story heights [mm] (when the measurements do
    not carry them; without masses the clone is mass-normalised), and one measurement per event."""

    name: str
    measurements: dict[str, FleetMeasurement]
    mass_t: list[float] | None = with_bounds(STORY_BOUNDS["mass"], None)
    height_mm: list[float] | None = with_bounds(STORY_BOUNDS["height"], None)
    description: str = ""

    def __post_init__(self):
        check_bounds(self)
        _check_name("building", self.name)
        if not self.measurements:
            raise InputError("measurements: give at least one event's record (event name: {file: ...})")
        for ev in self.measurements:
            _check_name("event", ev)


@dataclass(frozen=True, kw_only=True)
class ClusterConfig:
    """The embedded dask ``LocalCluster`` (``--scheduler`` replaces it with an existing cluster).

    One worker assesses one building at a time (``threads_per_worker: 1``), with ``task_threads``
    torch and numba threads inside the task (1: the workers, one per core, do not oversubscribe
    the cores); a building's records stay on one worker. ``processes: false`` runs the workers
    as threads of this process (tests)."""

    n_workers: int = bounded(2, lo=1, hi=1024)
    threads_per_worker: int = bounded(1, lo=1, hi=1024)
    memory_limit: str = "auto"
    processes: bool = True
    task_threads: int = bounded(1, lo=1, hi=1024)

    def __post_init__(self):
        check_bounds(self)
        if not MEMORY_LIMIT.match(str(self.memory_limit)):
            raise InputError(f"memory_limit = {str(self.memory_limit)[:40]!r}: expected 'auto', a size such "
                             "as 4GB, 2 GiB or 500MB, or a fraction of the machine's memory such as 0.5")


@dataclass(frozen=True, kw_only=True)
class FleetConfig:
    """``hlaid fleet`` config (see the module docstring)."""

    buildings: list[BuildingEntry]
    records: str | list[str] | None = None
    events: list[EventSpec] | None = None
    n_ensemble: int = bounded(N_ENSEMBLE, lo=0, hi=MAX_ENSEMBLE)
    seed: int = with_bounds(SEED, 0)
    identify: IdentifyConfig = field(default_factory=IdentifyConfig)
    ida: IDAConfig = field(default_factory=IDAConfig)
    cluster: ClusterConfig = field(default_factory=ClusterConfig)
    loss: LossConfig | None = None
    name: str = "hlaid fleet"
    history: bool = False
    """True: a building's unit at its event k is the clone of its events 1..k (its measurements in
    the order the config lists them, as ``hlaid identify`` takes several records), the decisions at
    event k; False: the clone of each event alone."""

    def __post_init__(self):
        if not self.buildings:
            raise InputError("buildings: list at least one building")
        check_bounds(self)

    def units(self) -> list[tuple[BuildingEntry, str]]:
        """Every (building, event) pair to assess, in config order."""
        return [(b, ev) for b in self.buildings for ev in b.measurements]

    def record_specs(self, base_dir: Path | None) -> list[str]:
        """The IDA records (``records``, else ``ida.records``), relative paths resolved."""
        cfg = self.ida if self.records is None else dataclasses.replace(self.ida, records=self.records)
        specs = cfg.record_specs(base_dir)
        if specs is None:
            raise InputError("no IDA records: give 'records:' (a folder, builtin-suite or a list of files)")
        return specs

    def check_measurement_files(self, base_dir: Path | None) -> None:
        """Refuse a fleet whose measurement files are missing or no regular files (relative paths
        from ``base_dir``), before it runs."""
        from .._inputs import check_input

        for b in self.buildings:
            for event, m in b.measurements.items():
                if m.file is None or str(m.file).startswith("builtin"):
                    continue
                p = Path(m.file)
                try:
                    check_input(p if p.is_absolute() or base_dir is None else base_dir / p)
                except InputError as err:
                    raise InputError(f"building {b.name!r}, event {event!r}: {err}") from None


def unit_id(building: str, event: str) -> str:
    """The name of a (building, event) result: ``B001@ev1``."""
    return f"{building}@{event}"


def load_fleet_config(path) -> FleetConfig:
    """Load and validate a fleet config; cross-checks (unique building names, events declared in
    ``events``) name the line of the offending value."""
    source = str(path)
    root = load_yaml(source)
    cfg = config_from_node(FleetConfig, root, source)
    bnodes = root.value["buildings"].value
    seen: dict[str, int] = {}
    for b, node in zip(cfg.buildings, bnodes):
        line = node.value["name"].line
        if b.name in seen:
            raise ConfigError(f"{source}:{line}: buildings: building name {b.name!r} appears twice "
                              f"(first on line {seen[b.name]})")
        seen[b.name] = line
    if cfg.events is not None:
        names = [e.name for e in cfg.events]
        enodes = root.value["events"].value
        for i, e in enumerate(names):
            if e in names[:i]:
                raise ConfigError(f"{source}:{enodes[i].line}: events: event {e!r} appears twice")
        for b, node in zip(cfg.buildings, bnodes):
            mnode = node.value["measurements"]
            for ev in b.measurements:
                if ev not in names:
                    raise ConfigError(f"{source}:{mnode.keys.get(ev, mnode.line)}: buildings.{b.name}.measurements: "
                                      f"event {ev!r} is not in events ({', '.join(names)})")
    return cfg


__all__ = ["FleetConfig", "BuildingEntry", "FleetMeasurement", "EventSpec", "ClusterConfig", "load_fleet_config",
           "unit_id"]
