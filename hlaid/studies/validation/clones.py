"""Clones of a validation study: the paper's identification, or a labelled linear fallback."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ... import _progress
from ... import signal as sg
from ...clone import Clone
from ...config import config_to_dict
from ...errors import InputError, NotIdentifiableError
from ...events.identify import identify_clone
from ...hla import run_hla
from ...identify import IdentifyConfig, refine_replay
from ...identify.auto import resolve_settings
from ...measurement import Measurement
from ...model import Building, Damping
from ...motions import GroundMotion
from ...record import Settings
from ...simulate import simulate_response
from .schema import StructureSpec

FALLBACK_FITS = ("scale+damping", "k0+damping", "k0", "damping", "none")
"""What the replay refinement fits of a linear clone (see :func:`linear_clone`)."""


@dataclass(frozen=True, eq=False)
class IdentifiedClone:
    """A clone identified from one event.

    Attributes
    ----------
    structure, event : where it came from
    clone : the clone as loaded back from its JSON file
    kind : ``"nonlinear"`` (paper's method) or ``"linear"`` (fallback: no story yielded)
    reason : why the fallback was taken ("" for nonlinear clones)
    path : file name of the clone JSON written
    seconds : wall time of the identification
    """

    structure: str
    event: str
    clone: Clone
    kind: str
    reason: str
    path: str
    seconds: float

    def identification(self) -> dict:
        """Per story: identifiable or not, and the SVM test accuracies of the last pass
        (nonlinear clones only)."""
        paper = self.clone.paper
        if self.kind != "nonlinear" or paper is None:
            return {}
        return {"identifiable": [s.identifiable for s in paper.stories],
                "svm_test_accuracy": [None if s.svm_test_accuracy is None else dict(s.svm_test_accuracy)
                                      for s in paper.stories],
                "refine": None if paper.refine is None else dict(paper.refine)}

    def summary(self) -> dict:
        b = self.clone.building
        return {"structure": self.structure, "event": self.event, "kind": self.kind, "reason": self.reason,
                "identification": self.identification(),
                "mass_normalised": self.clone.mass_normalised, "mass": b.mass.tolist(),
                **{k: getattr(b, k).tolist() for k in ("k0", "alpha", "p", "dy", "delta_eta")},
                "damping_ratio": b.damping.ratio, "periods_s": b.periods().tolist(), "path": self.path,
                "seconds": self.seconds}


def linear_clone(meas: Measurement, cfg: IdentifyConfig, *, fit: str = "scale+damping", reason: str = "") -> Clone:
    """A linear (``alpha = 1``) clone: HLA's k0 and the config's damping ratio, then fitted to
    the measured floor accelerations (``fit``): ``"scale+damping"`` one factor on every k0 and
    the damping ratio (HLA's stiffness distribution kept); ``"k0+damping"``, ``"k0"``,
    ``"damping"`` by :func:`refine_replay`; ``"none"``: HLA's k0 as they are. The config's
    ``"auto"`` settings are chosen from ``meas`` first (:func:`hlaid.identify.auto.resolve_settings`)."""
    if cfg.unresolved():
        cfg = resolve_settings(meas, cfg).config
    res = run_hla(meas, cfg.hla)
    n = res.n_stories
    peak = np.array([np.max(np.abs(s.drift)) for s in res.stories])
    b = Building(mass=res.mass, k0=res.k0, alpha=np.ones(n), p=np.full(n, 2.0), dy=np.maximum(1e3 * peak, 1.0),
                 delta_eta=np.zeros(n), height=meas.height, damping=Damping(ratio=cfg.damping_ratio),
                 pdelta=meas.pdelta_active if meas.height is not None else None, name=meas.name)
    if fit not in FALLBACK_FITS:
        raise InputError(f"linear clone fit {fit!r}; expected one of {', '.join(FALLBACK_FITS)}")
    diag = {"kind": "linear", "reason": reason, "k0_hla": res.k0.tolist(), "hla_band_hz": list(res.band_hz),
            "fit": fit, "refine": None}
    if fit == "scale+damping":
        b, diag["refine"] = _fit_scale_damping(b, meas, cfg.refine.band_hz, cfg.refine.max_iterations)
    elif fit != "none":
        rr = refine_replay(b, meas, parameters=("k0",) if fit.startswith("k0") else (), damping="damping" in fit,
                           band_hz=cfg.refine.band_hz, max_iterations=cfg.refine.max_iterations)
        b = rr.building
        diag["refine"] = {"cost_initial": rr.cost_initial, "cost_final": rr.cost_final, "nfev": rr.nfev,
                          "message": rr.message}
    prov = {"source": meas.source, "method": f"linear clone (HLA k0; fitted: {fit})"}
    return Clone(building=b, mass_normalised=res.mass_normalised, diagnostics=diag, provenance=prov,
                 settings=Settings(config=config_to_dict(cfg)))


def _fit_scale_damping(b: Building, meas: Measurement, band_hz, max_iterations: int) -> tuple[Building, dict]:
    """Least squares of the replayed against the measured floor accelerations (band-passed, as
    :func:`refine_replay`) over one common factor on every story's k0 and the damping ratio:
    HLA's distribution of stiffness over the stories is kept."""
    from scipy.optimize import least_squares

    dt = meas.dt
    hi = sg.cap_corner(band_hz[1], dt)
    ground = GroundMotion(dt=dt, acc=sg.bandpass(np.asarray(meas.ground_acc), dt, (0.0, hi)), name=meas.name)
    target = sg.bandpass(np.asarray(meas.floor_acc), dt, (band_hz[0], hi))
    rms = np.sqrt(np.mean(target**2, axis=0))
    d = b.damping

    def make(x):
        return b.replace(k0=b.k0 * np.exp(x[0]), damping=dataclasses.replace(d, ratio=float(x[1])))

    def fun(x):
        r = simulate_response(make(x), ground)
        if r.status[0] != 0:
            return np.full(target.size, 1e3)
        return ((sg.bandpass(np.nan_to_num(r.acc[0]), dt, (band_hz[0], hi)) - target) / rms).ravel()

    sol = least_squares(fun, [0.0, d.ratio], bounds=([-1.0, 0.0], [1.0, 0.5]), x_scale=[0.05, 0.01],
                        max_nfev=max_iterations)
    return make(sol.x), {"k0_factor": float(np.exp(sol.x[0])), "cost_final": float(sol.cost),
                         "nfev": int(sol.nfev), "message": str(sol.message)}


def identify_event(spec: StructureSpec, event: str, meas: Measurement, cfg: IdentifyConfig, out_dir: Path,
                   cache_dir: str | None = None) -> IdentifiedClone | None:
    """Identify a clone from ``meas``; the linear fallback when no story yielded (None when
    the structure's ``fallback`` is ``"none"``). The clone is written to
    ``out_dir/<structure>_<event>.json`` and read back."""
    t0 = time.perf_counter()
    kind, reason = "nonlinear", ""
    try:
        if spec.clone == "linear":
            raise NotIdentifiableError("the config asks for a linear clone (clone: linear)")
        res = identify_clone(meas, cfg, cache_dir=cache_dir)
        if not res.passes:  # no story yielded: the loop shape would be the structural prior's alone
            raise NotIdentifiableError("no story yielded: stiffness and damping only")
        clone = res.clone
    except NotIdentifiableError as err:
        reason = str(err).removeprefix(f"{meas.source}: ")
        if spec.fallback == "none" and spec.clone != "linear":
            _progress.warn(f"{spec.name}/{event}: not identifiable, skipped ({reason})")
            return None
        _progress.info(f"[validate] {spec.name}/{event}: linear clone ({reason})")
        kind = "linear"
        clone = linear_clone(meas, cfg, fit=spec.fallback_fit, reason=reason)
    path = out_dir / f"{spec.name}_{event}.json"
    clone.save(path, force=True)  # clone_dir is rewritten on every run
    loaded = Clone.load(path)
    return IdentifiedClone(structure=spec.name, event=event, clone=loaded, kind=kind, reason=reason, path=path.name,
                           seconds=time.perf_counter() - t0)
