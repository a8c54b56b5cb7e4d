"""A clone of the validation study replayed under a recorded event: :func:`hlaid.predict_event`
from an undamaged start with the check against HLA of the event, labelled by the study."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...clone import Clone
from ...events.predict import Prediction, predict_event
from ...hla import HLAConfig, HLAResult
from ...measurement import Measurement


@dataclass(frozen=True, eq=False)
class StudyPrediction:
    """One prediction of the validation study.

    Attributes
    ----------
    structure, identified_from, event, kind : which clone (``kind``: nonlinear or linear), which event
        (the study's labels)
    self_replay : the event is the one the clone was identified from
    prediction : the prediction, with its :attr:`~hlaid.events.predict.Prediction.hla_check`
    """

    structure: str
    identified_from: str
    event: str
    kind: str
    self_replay: bool
    prediction: Prediction

    @property
    def band_hz(self) -> tuple[float, float]:
        return self.prediction.band_hz

    @property
    def pga_g(self) -> float:
        return self.prediction.pga_g

    @property
    def r(self) -> np.ndarray:
        return self.prediction.r

    @property
    def peak_drift_error(self) -> np.ndarray:
        return self.prediction.peak_drift_error

    @property
    def r_broadband(self) -> np.ndarray:
        assert self.prediction.hla_check is not None  # study predictions always check against HLA
        return self.prediction.hla_check.r_broadband

    @property
    def stiffness_error(self) -> np.ndarray:
        assert self.prediction.hla_check is not None
        return self.prediction.hla_check.stiffness_error

    @property
    def status(self) -> int:
        """The replay's simulator status (0 ok)."""
        return self.prediction.status

    @property
    def hla(self) -> HLAResult | None:
        return None if self.prediction.hla_check is None else self.prediction.hla_check.hla

    def summary(self) -> dict:
        p = self.prediction
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in
                (("structure", self.structure), ("identified_from", self.identified_from), ("event", self.event),
                 ("kind", self.kind), ("self_replay", self.self_replay), ("pga_g", p.pga_g),
                 ("band_hz", list(p.band_hz)), ("r", p.r), ("r_mean", float(np.mean(p.r))),
                 ("r_broadband", self.r_broadband),
                 ("peak_drift_measured", p.peak_drift_measured), ("peak_drift_predicted", p.peak_drift_predicted),
                 ("peak_drift_error", p.peak_drift_error), ("stiffness_error", self.stiffness_error),
                 ("stiffness_error_mean", nanmean(self.stiffness_error)), ("status", p.status),
                 ("wide", p.other_bands["records"].to_dict() if "records" in p.other_bands else None))}


def nanmean(x) -> float | None:
    """The mean of the finite entries (None where there is none)."""
    x = np.asarray(x, dtype=float)
    return float(np.nanmean(x)) if np.isfinite(x).any() else None


def study_prediction(clone: Clone, meas: Measurement, hla_config: HLAConfig, *, compare_band_hz=None,
                     input_lowpass_hz: float | None = None, labels: tuple[str, str, str, str] = ("", "", "", ""),
                     self_replay: bool = False) -> StudyPrediction:
    """:func:`hlaid.predict_event` of ``clone`` under ``meas`` from an undamaged start, checked
    against HLA of the event; ``labels``: ``(structure, identified_from, event, kind)``."""
    p = predict_event(clone, meas, band_hz=compare_band_hz, start="undamaged", hla_config=hla_config,
                      input_lowpass_hz=input_lowpass_hz, check_hla=True)
    return StudyPrediction(structure=labels[0], identified_from=labels[1], event=labels[2], kind=labels[3],
                           self_replay=self_replay, prediction=p)
