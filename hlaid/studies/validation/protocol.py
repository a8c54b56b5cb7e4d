"""The validation protocol over the structures of a config: clones, then their predictions."""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ... import _progress
from ...config import config_to_dict
from ...errors import InputError
from ...identify.auto import resolve_settings
from .clones import IdentifiedClone, identify_event
from .predict import StudyPrediction, nanmean, study_prediction
from .schema import PaperTargets, ValidationConfig, identify_config_of, read_event

if TYPE_CHECKING:
    from ...measurement import Measurement


@dataclass(frozen=True, eq=False)
class ValidationResult:
    """Clones and predictions of a validation run.

    Attributes
    ----------
    clones : one per (structure, identification event) that gave a clone
    predictions : self-replays and cross-event predictions
    targets : the paper's numbers
    notes : per structure, what the data allow
    seconds : wall time
    """

    clones: list[IdentifiedClone]
    predictions: list[StudyPrediction]
    targets: PaperTargets
    notes: dict[str, str]
    seconds: float

    def structure_summary(self) -> list[dict]:
        """Per structure: mean and worst R and mean stiffness error over the cross-event
        predictions (and the self-replays apart)."""
        out = []
        for name in dict.fromkeys(p.structure for p in self.predictions):
            row: dict[str, Any] = {"structure": name}
            for tag, sel in (("cross", False), ("self", True)):
                ps = [p for p in self.predictions if p.structure == name and p.self_replay == sel]
                if not ps:
                    continue
                r = np.array([p.r for p in ps])
                se = np.array([p.stiffness_error for p in ps])
                pe = np.abs(np.array([p.peak_drift_error for p in ps]))
                row[tag] = {"n": len(ps), "r_mean": float(r.mean()), "r_worst": float(r.min()),
                            "r_mean_per_floor": r.mean(axis=0).tolist(),
                            "peak_drift_error_mean": float(pe.mean()), "peak_drift_error_worst": float(pe.max()),
                            "stiffness_error_mean": nanmean(se)}
            out.append(row)
        return out

    def to_dict(self) -> dict:
        return {"format": "hlaid-validation", "version": 1, "seconds": self.seconds,
                "targets": config_to_dict(self.targets), "notes": self.notes,
                "clones": [c.summary() for c in self.clones],
                "predictions": [p.summary() for p in self.predictions],
                "summary": self.structure_summary()}


def run_validation(cfg: ValidationConfig, *, clone_dir: str | None = None, structures: list[str] | None = None,
                   cache_dir: str | None = None) -> ValidationResult:
    """Run the protocol over the structures of ``cfg`` (or the named ``structures``).

    Parameters
    ----------
    cfg : the validation config (:func:`load_validation_config`)
    clone_dir : where the clone JSON files are written (default: a temporary folder)
    structures : names of the structures to run (default all)
    cache_dir : classifier cache (overrides ``cfg.cache_dir``)
    """
    t0 = time.perf_counter()
    names = [s.name for s in cfg.structures]
    for n in structures or []:
        if n not in names:
            raise InputError(f"unknown structure {n!r}; expected one of {names}", source=cfg.source or None)
    cache = cache_dir if cache_dir is not None else cfg.cache_dir
    clones, preds = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(clone_dir) if clone_dir else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        for spec in cfg.structures:
            if (structures and spec.name not in structures) or (not structures and spec.optional):
                continue
            icfg = identify_config_of(spec, source=cfg.source or "<validation>")
            meas: dict[str, Measurement] = {}

            def get(ev, spec=spec, meas=meas):
                if ev not in meas:
                    meas[ev] = read_event(spec, ev, cfg.data_dir)
                return meas[ev]

            for src in spec.identify_from:
                _progress.info(f"[validate] {spec.name}: identifying a clone from {src}")
                rcfg = resolve_settings(get(src), icfg).config  # the config's "auto" settings, from this record
                ic = identify_event(spec, src, get(src), rcfg, out, cache)
                if ic is None:
                    continue
                clones.append(ic)
                for ev in [src] + spec.targets_of(src):
                    preds.append(study_prediction(ic.clone, get(ev), rcfg.hla, compare_band_hz=spec.compare_band_hz,
                                                  input_lowpass_hz=spec.input_lowpass_hz, self_replay=ev == src,
                                                  labels=(spec.name, src, ev, ic.kind)))
                    p = preds[-1]
                    _progress.info(f"[validate] {spec.name}: {src} -> {ev}: R {np.round(p.r, 3)}, "
                                   f"stiffness error {_fmt_pct(nanmean(p.stiffness_error))}")
    return ValidationResult(clones=clones, predictions=preds, targets=cfg.targets,
                            notes={s.name: s.notes for s in cfg.structures
                                   if (s.name in structures if structures else not s.optional)},
                            seconds=time.perf_counter() - t0)


def _fmt_pct(x) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{100 * x:.1f} %"
