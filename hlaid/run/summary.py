"""``summary.json``: what a run found, as one typed, versioned record (:class:`RunSummary`).

``hlaid run`` / ``hlaid demo`` build it, ``hlaid report`` renders it, ``hlaid loss RUN_DIR`` adds
its ``loss`` block. :meth:`RunSummary.from_dict` checks a file against the dataclasses below
(their annotations are the schema, :mod:`hlaid.run._schema`): a tampered or truncated summary is
one :class:`~hlaid.errors.InputError` naming summary.json and the field. The JSON keys are the
field names; :meth:`RunSummary.to_dict` writes them in this order, after ``format`` and ``version``.

Versions: 1 (hlaid 0.1) and 2 (this one) hold the same fields; version 2 is the first written
from this schema, and this hlaid reads both. Fields added since (``events``, ``survival``,
``flags``, ``basis``, the assessment's ``events`` and ``survival``) are optional: older summaries read without them.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

from .._inputs import read_json
from ..errors import InputError, kind_of
from ._schema import NONEMPTY, NUMBER_KEYS, Block, Document

FORMAT = "hlaid-run"
VERSION = 2
READS = (1, 2)
FILE = "summary.json"


@dataclass(frozen=True, kw_only=True)
class ParameterRow(Block):
    """One identified parameter of one story (the paper's Table 4 layout); ``true`` and ``error``
    when the truth is known (a simulation); ``interval`` the 90 % interval ``(lo, hi)`` of an
    identification with uncertainty (JSON ``lo90``, ``hi90``; None items: no interval for this one),
    None when the run has none (the keys are absent)."""

    parameter: str
    story: int
    identified: float | None = None
    true: float | None = None
    error: float | None = None
    interval: tuple[float | None, float | None] | None = None

    @classmethod
    def _read_block(cls, d, where):
        row = super()._read_block(d, where)
        if "lo90" not in d and "hi90" not in d:
            return row
        iv = Interval._read_block(d, where)
        return dataclasses.replace(row, interval=(iv.lo90, iv.hi90))

    def to_dict(self) -> dict:
        d = {"parameter": self.parameter, "story": self.story, "identified": self.identified, "true": self.true,
             "error": self.error}
        if self.interval is not None:
            d["lo90"], d["hi90"] = self.interval
        return d


@dataclass(frozen=True, kw_only=True)
class Interval(Block):
    """The ``lo90``/``hi90`` keys of a :class:`ParameterRow`."""

    lo90: float | None = None
    hi90: float | None = None


@dataclass(frozen=True, kw_only=True)
class Replay(Block):
    """The clone replayed on the measured ground motion: correlation with the measured floor
    displacement per floor (and with the true one of a simulation), stiffness-evolution error per story."""

    r_measured: Annotated[tuple[float, ...], NONEMPTY]
    r_true: tuple[float, ...] | None = None
    stiffness_error: tuple[float, ...]


# ------------------------------------------------------------------ IDA (hlaid.ida's summary.json)
@dataclass(frozen=True, kw_only=True)
class Fragility(Block):
    """A lognormal fragility as :class:`hlaid.ida.LognormalFragility` writes it (``not_fitted``:
    why there is none)."""

    median_g: float | None = None
    beta: float | None = None
    median_ci_g: tuple[float | None, float | None] | None = None
    beta_ci: tuple[float | None, float | None] | None = None
    ci: float | None = None
    n_records: int | None = None
    n_censored: int | None = None
    not_fitted: str | None = None


@dataclass(frozen=True, kw_only=True)
class CollapseFits(Block):
    capacities: Fragility | None = None
    counts: Fragility | None = None


@dataclass(frozen=True, kw_only=True)
class IntensityMeasure(Block):
    name: str | None = None
    label: str | None = None
    period_s: float | None = None


@dataclass(frozen=True, kw_only=True)
class CollapseCriteria(Block):
    drift_limit: float = 0.0
    slope_ratio: float = 0.0


@dataclass(frozen=True, kw_only=True)
class DriftLimit(Block):
    fragility: Fragility | None = None


@dataclass(frozen=True, kw_only=True)
class IDASummary(Document):
    """The IDA of the clone (``ida``: undamaged; ``ida_after``: from the state its event left).

    ``document`` is the IDA's own ``summary.json`` (:meth:`hlaid.ida.IDAResult.summary`), kept and
    written back whole; the other fields are the typed view of it a reader uses."""

    intensity_measure: IntensityMeasure = field(default_factory=IntensityMeasure)
    edp: str | None = None
    collapse_criteria: CollapseCriteria = field(default_factory=CollapseCriteria)
    levels_g: tuple[float, ...] = ()
    records: tuple[Any, ...] = ()
    collapse_fragility: CollapseFits | None = None
    drift_limits: Annotated[dict[str, DriftLimit], NUMBER_KEYS] | None = None
    n_runs: int | None = None
    notes: tuple[str, ...] = ()

    @property
    def collapse_fit(self) -> Fragility | None:
        """The collapse fragility: the fit to the records' collapse capacities, else to the counts."""
        cf = self.collapse_fragility
        return None if cf is None else cf.capacities or cf.counts


# ------------------------------------------------------------------ what the building survived
@dataclass(frozen=True, kw_only=True)
class EventRisk(Block):
    """P(collapse) at the intensity of an event the clone was identified from (the building
    survived it): ``source`` says whose fragility (the ensemble's, or the identified clone's IDA)."""

    name: str
    im: float | None = None
    p_collapse: float | None = None
    p_collapse_band: tuple[float, float] | None = None
    source: str | None = None


@dataclass(frozen=True, kw_only=True)
class Survival(Block):
    """The clone's events as evidence (:meth:`hlaid.events.evidence.Survival.to_dict`): members
    drawn and rejected for collapsing under an event the building survived, and whether the nominal
    clone survives them with the collapse law in force."""

    n_wanted: int = 0
    n_drawn: int = 0
    n_rejected: int = 0
    n_members: int = 0
    events: tuple[str, ...] = ()
    unchecked: tuple[str, ...] = ()
    nominal_survives: bool | None = None
    nominal_collapsed_in: str | None = None
    nominal_peak_drift_mm: tuple[float, ...] | None = None
    notes: tuple[str, ...] = ()


# ------------------------------------------------------------------ ensemble assessment
@dataclass(frozen=True, kw_only=True)
class Assessment(Block):
    """The ensemble of clones drawn from the identification uncertainty (:func:`hlaid.ida.assess`):
    collapse fragility and its band, P(collapse) and drift exceedance at the measured record's
    intensity ``own_im`` with their bands, the re-occupancy indicator and why."""

    n_ensemble: int
    n_records: int
    ci: float
    im_label: str
    period: float | None = None
    collapse_median: float
    collapse_median_band: tuple[float, float]
    beta: float | None = None
    own_im: float | None = None
    p_collapse: float | None = None
    p_collapse_band: tuple[float, float] | None = None
    drift_limits: tuple[float, ...]
    p_exceed: tuple[float, ...]
    p_exceed_band: tuple[tuple[float, float], ...] | None = None
    indicator: str | None = None
    placard: str | None = None
    reasons: tuple[str, ...]
    thresholds: dict[str, float] | None = None
    own_residual_drift_median: float | None = None
    own_peak_drift_median: float | None = None
    events: tuple[EventRisk, ...] = ()
    survival: Survival | None = None


# ------------------------------------------------------------------ losses
@dataclass(frozen=True, kw_only=True)
class RecordedLoss(Block):
    """FEMA P-58 at the measured record (:func:`hlaid.loss.assess_demands`' summary): repair cost,
    its ratio to the replacement cost and repair time (median, ``ci`` band), P(collapse),
    P(irreparable), P(replacement)."""

    n_realizations: int
    ci: float | None = None
    cost_unit: str
    time_unit: str | None = None
    replacement_cost: float | None = None
    replacement_time: float | None = None
    repair_cost_median: float
    repair_cost_band: tuple[float, float]
    repair_cost_mean: float
    repair_cost_ratio_median: float
    repair_cost_ratio_band: tuple[float, float]
    repair_cost_ratio_mean: float | None = None
    repair_time_parallel_median: float
    repair_time_parallel_band: tuple[float | None, float | None] | None = None
    repair_time_sequential_median: float
    repair_time_sequential_band: tuple[float | None, float | None] | None = None
    p_collapse: float | None = None
    p_irreparable: float
    p_replacement: float | None = None
    name: str | None = None
    level_g: float | None = None
    im: float
    im_label: str
    n_demand_realizations: int
    n_collapsed_in_replay: int | None = None
    notes: tuple[str, ...] = ()

    @classmethod
    def _read_block(cls, d, where):
        if "n_demand_realisations" in d and "n_demand_realizations" not in d:  # the spelling of older runs
            d = {**d, "n_demand_realizations": d["n_demand_realisations"]}
        return super()._read_block(d, where)


@dataclass(frozen=True, kw_only=True)
class LossCurvePoint(Block):
    """The losses at one IDA stripe."""

    level_g: float
    repair_cost_ratio_mean: float
    repair_cost_ratio_median: float | None = None
    repair_cost_ratio_band: tuple[float | None, float | None] | None = None
    p_collapse: float
    p_irreparable: float


@dataclass(frozen=True, kw_only=True)
class CollapseUsed(Block):
    """The collapse fragility the losses used and where it came from."""

    median_g: float | None
    beta: float | None
    source: str


@dataclass(frozen=True, kw_only=True)
class Irreparable(Block):
    """FEMA P-58's residual-drift fragility of irreparable damage."""

    median: float
    beta: float


@dataclass(frozen=True, kw_only=True)
class LossSummary(Block):
    """FEMA P-58 losses through pelicun (``loss/loss.json`` holds the stripes in full): the settings,
    the measured record's losses (``recorded``) and the loss curve over the IDA stripes."""

    engine: str
    system: str
    inventory: str
    floor_area_m2: tuple[float, ...]
    floor_area_source: str | None = None
    replacement_cost: float
    replacement_time: float
    collapse_fragility: CollapseUsed
    irreparable: Irreparable
    n_ensemble: int
    realizations: int
    assumptions: tuple[str, ...]
    recorded: RecordedLoss | None = None
    curve: tuple[LossCurvePoint, ...] = ()

    @classmethod
    def of_losses(cls, block: dict) -> LossSummary:
        """The run's loss block from :func:`hlaid.loss.assess_losses`' result (``loss.json``): its
        settings, the measured record's losses and the curve over the stripes."""
        d = {f: block[f] for f in cls.__dataclass_fields__ if f != "curve"}
        d["curve"] = block["stripes"]
        return cls.from_dict(d, file="loss/loss.json")


# ------------------------------------------------------------------ the run
@dataclass(frozen=True, kw_only=True)
class ConfigRecord(Document):
    """The run config as the run used it (:func:`hlaid.config.config_to_dict` of its
    :class:`~hlaid.run.RunConfig`), kept whole in ``document``; the blocks a later step reads
    (``hlaid loss RUN_DIR``: the IDA settings, the ensemble, the loss settings) checked to be mappings."""

    ida: dict[str, Any] | None = None
    assess: dict[str, Any] | None = None
    loss: dict[str, Any] | None = None


@dataclass(frozen=True, kw_only=True)
class RunSummary(Block):
    """A run's summary (``summary.json``): the run (name, hlaid version, config as run, measurement
    source, timings), the identification (parameters against the truth when known, the paper's
    method alone, the replay), the IDA before and after the event, the ensemble assessment and the
    losses (each None when the run did not compute it); P(collapse) at the intensity of every event
    the clone was identified from (``events``), the clone's events as evidence (``survival``) and
    what a reader must know (``flags``: large stiffness-evolution errors, parameters at limits or
    from the prior, a clone that collapses under its own event, extrapolation, assumed heights or
    masses)."""

    name: str
    hlaid_version: str
    config: ConfigRecord = field(default_factory=lambda: ConfigRecord(document={}))
    source: str | None = None
    n_stories: int
    mass_normalised: bool | None = None
    parameters: tuple[ParameterRow, ...]
    paper_method: tuple[ParameterRow, ...] | None = None
    replay: Replay
    outer_iterations: int
    identify_timings: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float]
    ida: IDASummary | None = None
    ida_after: IDASummary | None = None
    noise_rms: float | None = None
    assessment: Assessment | None = None
    loss: LossSummary | None = None
    events: tuple[EventRisk, ...] = ()
    survival: Survival | None = None
    flags: tuple[str, ...] = ()
    basis: dict[str, Any] | None = None
    """What the decision rests on (:meth:`hlaid.ida.basis.DecisionBasis.to_dict`; None: no IDA, or an
    older summary)."""
    figures: bool = True
    """Whether the run made its figures (``hlaid run --no-plots``: the report holds the tables alone)."""

    @classmethod
    def from_dict(cls, d, *, file: str = FILE, source: str | None = None, path: str = "") -> RunSummary:
        """The summary in mapping ``d`` (``summary.json``, version 1 or 2), checked field by field."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"{file} is not an hlaid run summary", source=source)
        version = d.get("version")
        if isinstance(version, bool) or version not in READS:
            small = isinstance(version, int) and not isinstance(version, bool) and abs(version) < 10**9
            shown = repr(version) if small else kind_of(version)
            raise InputError(f"{file}: version {shown} is not supported; this hlaid reads "
                             f"versions {', '.join(map(str, READS))}", source=source)
        return super().from_dict(d, file=file, source=source, path=path)

    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": VERSION, **super().to_dict()}


def read_summary(run_dir: str | os.PathLike) -> RunSummary:
    """The summary of a run folder (``summary.json``, checked: :meth:`RunSummary.from_dict`)."""
    d = Path(run_dir)
    src = str(d)
    if not d.is_dir():
        raise InputError("not found or not a folder; expected a run folder written by hlaid run or hlaid demo"
                         if not d.exists() else "is not a folder; expected a run folder", source=src)
    if not os.path.lexists(d / "summary.json"):
        raise InputError("not an hlaid run folder (no summary.json)", source=src)
    try:
        s = read_json(d / "summary.json")
    except InputError as err:
        raise InputError(f"not an hlaid run folder ({err})", source=src) from None
    return RunSummary.from_dict(s, source=src)


__all__ = ["RunSummary", "read_summary", "ParameterRow", "Replay", "IDASummary", "Fragility", "CollapseFits",
           "EventRisk", "Survival",
           "IntensityMeasure", "CollapseCriteria", "DriftLimit", "Assessment", "LossSummary", "RecordedLoss",
           "LossCurvePoint", "CollapseUsed", "Irreparable", "ConfigRecord", "FORMAT", "VERSION", "READS"]
