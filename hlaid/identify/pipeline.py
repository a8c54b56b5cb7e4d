"""Automated identification of a digital clone (paper section 2.2, DESIGN.md section 6).

HLA of the measurement; then, per story, alpha and p from RBF SVMs trained on simulated half
cycles (a coarse pass over the paper's Table 2-3 bins, a fine pass over the predicted bin and
its neighbours), delta_eta and dy by the regressions of eq 12-17, and an outer loop that
repeats with the new values until they settle. Optionally a replay refinement polishes the
result against the measured accelerations (:mod:`hlaid.identify.refine`).
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import hashlib
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import _progress
from .._version import __version__
from ..clone import Clone
from ..config import config_to_dict
from ..errors import NotIdentifiableError, TangentTooLargeError, UnstableTangentError
from ..hla import HLAResult, reanalyse_story, run_hla
from ..hla.features import half_cycle_features
from ..measurement import Measurement, measured_ground
from ..model import Building, Damping
from ..uncertainty.laplace import uncertainty_of_refinement
from .cache import MachineCache, default_cache_dir
from .classify import Bins, pass_result, vote
from .config import IdentifyConfig
from .drift import reconstruct_drift
from .loopfit import fit_story_loop
from .passes import PARAMS, machines_of, path_pass, train_pass
from .patherrors import path_error_bank
from .pathtrain import noise_bank, story_paths
from .refine import RefineResult, refine_replay
from .regression import plausible_limits, story_delta_eta, story_yield_displacement
from .replaycheck import ReplayCheck, replay_check
from .tb import TBLogger
from .training import strong_motion_window


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Everything an identification produced.

    Attributes
    ----------
    clone : the identified clone (write it with ``clone.save``)
    hla : the hysteresis loop analysis of the measurement
    paper_estimate : the building after regressions + classifiers (before refinement)
    passes : per outer iteration, per story, the classifier passes
    iterations : outer-loop iterations run
    replay : replay of the clone on the measured ground motion
    timings : seconds per step
    refinement : the replay refinement's final stage (its Jacobian and residuals at the
        solution give ``clone.uncertainty``), None without refinement
    """

    clone: Clone
    hla: HLAResult
    paper_estimate: Building
    passes: list
    iterations: int
    replay: ReplayCheck
    timings: dict
    refinement: object = None


def estimate_noise_rms(meas: Measurement) -> float:
    """Sensor noise as a fraction of channel RMS, from the flat spectrum floor above 0.6 x
    Nyquist (white noise extrapolated over the whole band); the median over channels."""
    from scipy import signal

    fs = 1.0 / meas.dt
    chans = np.column_stack([meas.ground_acc, meas.floor_acc])
    f, p = signal.welch(chans - chans.mean(axis=0), fs=fs, nperseg=min(1024, chans.shape[0]), axis=0)
    hf = f >= 0.6 * fs / 2
    if hf.sum() < 3:
        return 0.0
    noise_var = p[hf].mean(axis=0) * fs / 2
    rms2 = np.mean((chans - chans.mean(axis=0)) ** 2, axis=0)
    return float(np.median(np.sqrt(noise_var / rms2)))


def _noise_level(meas: Measurement, cfg: IdentifyConfig) -> float:
    if cfg.training.noise_rms is not None:
        return cfg.training.noise_rms
    if meas.noise_rms is not None:
        return meas.noise_rms
    return estimate_noise_rms(meas)


def _file_digest(path: str) -> str | None:
    p = Path(path)
    if not p.is_file():
        return None
    return hashlib.sha256(p.read_bytes()).hexdigest()


class _Identifier:
    """One identification run (state shared by its steps)."""

    def __init__(self, meas: Measurement, cfg: IdentifyConfig, tensorboard: str | None, cache_dir):
        self.meas, self.cfg = meas, cfg
        self.tb = TBLogger(tensorboard)
        self.cache = MachineCache(default_cache_dir() if cache_dir is None else (cache_dir or None))
        self.timings: dict[str, float] = {}
        self.passes: list = []

    # ------------------------------------------------------------------ steps
    def run(self) -> IdentificationResult:
        cfg, meas = self.cfg, self.meas
        t_all = time.perf_counter()
        t = time.perf_counter()
        _progress.info("[identify] hysteresis loop analysis")
        res = run_hla(meas, cfg.hla)
        self.timings["hla"] = time.perf_counter() - t
        self.res = res
        n = res.n_stories
        nseg = cfg.training.n_segments
        self.features = [half_cycle_features(s, nseg, yield_ratio=cfg.hla.stiffness.yield_ratio, with_ke=True)
                         for s in res.stories]
        self.path_mode = cfg.training.mode == "path"
        self.stories = list(res.stories)  # the stories the regressions see (drift = the path)
        self._path_features: dict = {}  # story -> its yielding half cycles along the path
        self.chosen_C: dict = {}  # machine -> (C, gamma factor) cross-validated in this run's first pass
        self.identifiable = np.array([s.yielded and len(F) >= 3 for s, F in zip(res.stories, self.features)])
        if not self.identifiable.any():
            peaks = ", ".join(f"{np.max(np.abs(s.drift)):.3g}" for s in res.stories)
            raise NotIdentifiableError(f"no story yielded in this record (peak drifts {peaks} mm): a nonlinear clone "
                                       "cannot be identified from it; use a record that drove the building past "
                                       "yield", source=meas.source or None)
        self.k0 = res.k0.copy()
        ke_min = np.array([np.nanmin(s.half_cycles.ke) / s.k0 for s in res.stories])
        self.alpha_max = np.clip(ke_min, 0.05, 0.95)
        self.ground = measured_ground(meas, res.band_hz[1])
        self.noise = _noise_level(meas, cfg)
        self.training_motion = strong_motion_window(self.ground, cfg.training.arias_fraction, cfg.training.tail_s)
        alpha = np.where(self.identifiable, 0.5 * self.alpha_max, 0.1)
        p = np.full(n, 0.5 * sum(cfg.bins.p_range))
        de, dy, reg = self._regressions(alpha, p)
        history = []
        for it in range(cfg.outer.max_iterations):
            est = self._building(alpha, p, dy, de)
            t = time.perf_counter()
            if self.path_mode and it > 0 and cfg.training.path == "replay":
                self._set_paths(reconstruct_drift(res, self.ground, est, crossover_hz=cfg.training.crossover_hz))
                de, dy, reg = self._regressions(alpha, p)
                if cfg.outer.k0 == "loop":
                    self._fit_k0(alpha, p, dy, de)
                    de, dy, reg = self._regressions(alpha, p)
                est = self._building(alpha, p, dy, de)
            if it == 0:
                coarse = self._pass(est, "coarse", it, None)
                centre = (np.array([c["alpha"].value if c else a for c, a in zip(coarse, alpha)]),
                          np.array([c["p"].value if c else q for c, q in zip(coarse, p)]))
                if self.path_mode:  # the fine pass is centred on the regressions with the coarse alpha, p
                    de, dy, reg = self._regressions(*centre)
                    est = self._building(centre[0], centre[1], dy, de)
            else:
                centre = (alpha, p)
            if it == 0 and not cfg.outer.first_fine:  # fine passes only along reconstructed paths
                a_new, p_new = centre
            else:
                fine = self._pass(est, "fine", it, centre)
                a_new = np.array([f["alpha"].value if f else a for f, a in zip(fine, alpha)])
                p_new = np.array([f["p"].value if f else q for f, q in zip(fine, p)])
            self.timings[f"classifiers_{it + 1}"] = time.perf_counter() - t
            de_new, dy_new, reg = self._regressions(a_new, p_new)
            change = max(_rel_change(a_new, alpha), _rel_change(p_new, p), _rel_change(de_new, de),
                         _rel_change(dy_new, dy))
            history.append({"iteration": it + 1, "alpha": a_new.tolist(), "p": p_new.tolist(),
                            "delta_eta": de_new.tolist(), "dy": dy_new.tolist(), "change": change})
            alpha, p, de, dy = a_new, p_new, de_new, dy_new
            _progress.info(f"[identify] outer iteration {it + 1}: alpha {np.round(alpha, 3)}, p {np.round(p, 2)}, "
                           f"delta_eta {np.round(de, 3)}, dy {np.round(dy, 3)} (change {change:.3f})")
            for i in range(n):
                for name, v in (("alpha", alpha), ("p", p), ("delta_eta", de), ("dy", dy)):
                    self.tb.scalar(f"estimate/story{i + 1}/{name}", v[i], it + 1)
            if change < cfg.outer.tol:
                break
        paper = self._building(alpha, p, dy, de)
        final = paper
        refine_info = None
        if cfg.refine.method != "none":
            final, refine_info = self._refine(paper, alpha, p)
        t = time.perf_counter()
        check = replay_check(final, meas, res)
        self.timings["replay"] = time.perf_counter() - t
        self.timings["total"] = time.perf_counter() - t_all
        for i, r in enumerate(check.r_measured):
            self.tb.scalar(f"replay/story{i + 1}/R_measured", r)
        self.tb.close()
        diagnostics = self._diagnostics(paper, final, reg, history, check, refine_info)
        provenance = {"source": meas.source, "sha256": _file_digest(meas.source) if meas.source else None,
                      "hlaid_version": __version__, "config": config_to_dict(cfg), "timings": self.timings,
                      "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                      "noise_rms_used": self.noise}
        rr = getattr(self, "refinement", None)
        unc = None if rr is None else uncertainty_of_refinement(rr, rr.channels or meas.n_floors, noise_rms=self.noise,
                                                                band_hz=cfg.refine.band_hz, dt=meas.dt)
        clone = Clone(building=final, mass_normalised=res.mass_normalised, diagnostics=diagnostics,
                      provenance=provenance, uncertainty=unc)
        return IdentificationResult(clone=clone, hla=res, paper_estimate=paper, passes=self.passes,
                                    iterations=len(history), replay=check, timings=self.timings, refinement=rr)

    # ------------------------------------------------------------------ helpers
    def _refine(self, paper: Building, alpha, p):
        """Replay refinement in two stages: k0 alone first (HLA's k0 is its least certain
        output and the regressions amplify its error), the regressions again with it, then
        every parameter of the identifiable stories: with ``ground_noise: tangent`` the
        errors-in-variables fit from there (:meth:`_tangent_fit`), falling back to least squares
        (and its restart) followed by the errors-in-variables finish (:meth:`_tangent_stage`)
        where that fit misses the data or its tangent is unstable."""
        cfg, meas = self.cfg, self.meas
        _progress.info("[identify] replay refinement against the measured accelerations")
        t = time.perf_counter()
        ident = [i for i in range(self.res.n_stories) if self.identifiable[i]]
        rc = cfg.refine
        common: dict[str, Any] = {"band_hz": rc.band_hz, "max_iterations": rc.max_iterations,
                                  "upper_factor": rc.upper_factor, "substeps": rc.substeps,
                                  "jac_substeps": rc.jac_substeps,
                                  "ground_noise": "ignore" if rc.ground_noise == "tangent" else rc.ground_noise}
        info: dict[str, Any] = {}
        start = paper
        if "k0" in rc.parameters:
            s1 = refine_replay(paper, meas, parameters=("k0",), damping=False, ftol=rc.ftol, **common)
            self.k0 = s1.building.k0.copy()
            de, dy, _ = self._regressions(alpha, p)
            start = self._building(alpha, p, dy, de)
            info["stage1_k0"] = {"cost_initial": s1.cost_initial, "cost_final": s1.cost_final, "nfev": s1.nfev}
        rr = None
        if rc.ground_noise == "tangent" and rc.eiv_start == "regressions":
            rr, info["tangent"] = self._tangent_fit(start, ident, common)
        if rr is None:
            rr = self._least_squares(start, paper, ident, common, info)
            if rc.ground_noise == "tangent":
                rr, stage = self._tangent_stage(rr, ident, common)
                info.setdefault("tangent", {}).update(stage)
        # whitened residuals have another scale (no ratio, no restart)
        info["noise_ratio"] = None if rc.ground_noise == "whiten" else self._noise_ratio(rr)
        self.refinement = rr
        info.update({"cost_initial": rr.cost_initial, "cost_final": rr.cost_final, "nfev": rr.nfev,
                     "message": rr.message})
        self.timings["refine"] = time.perf_counter() - t
        return rr.building, info

    def _least_squares(self, start: Building, paper: Building, ident: list[int], common: dict,
                       info: dict) -> RefineResult:
        """Least squares of the residuals from ``start``, again from a neutral start where the fit
        misses the data by more than ``restart_ratio`` times its noise (``info["restart"]``)."""
        rc, meas = self.cfg.refine, self.meas
        rr = refine_replay(start, meas, parameters=rc.parameters, stories=ident, damping=rc.damping, ftol=rc.ftol,
                           **common)
        ratio = None if rc.ground_noise == "whiten" else self._noise_ratio(rr)
        if rc.restart_ratio is not None and ratio is not None and ratio > rc.restart_ratio:
            _progress.info(f"[identify] the refined replay misses the data by {ratio:.1f}x its noise level: "
                           "refining again from a neutral start")
            alt = refine_replay(self._neutral_start(paper), meas, parameters=rc.parameters, damping=rc.damping,
                                ftol=rc.ftol, **common)
            kept = alt.cost_final < 0.8 * rr.cost_final
            info["restart"] = {"noise_ratio": ratio, "cost_final": alt.cost_final, "nfev": alt.nfev, "kept": kept,
                               "stories": "all"}
            if kept:
                rr = alt
        return rr

    def _noise_ratio(self, rr: RefineResult) -> float:
        """The least-squares (un-whitened) cost over ``0.5 N sigma^2`` (N residuals, sigma the noise
        level, at least 1 %: a noise-free record fits to the model's own discretisation, not to zero)."""
        cost = rr.cost_final if rr.plain_cost is None else rr.plain_cost
        return cost / (0.5 * np.asarray(self.meas.floor_acc).size * max(self.noise, 0.01) ** 2)

    def _eiv(self, building: Building, ident: list[int], common: dict, start: str) -> tuple[RefineResult | None, dict]:
        """The errors-in-variables fit from ``building`` (``start`` names it), with its summary;
        None and the reason where the tangent is unstable or larger than ``tangent_max_mb``."""
        rc = self.cfg.refine
        try:
            eiv = refine_replay(building, self.meas, parameters=rc.parameters, stories=ident, damping=rc.damping,
                                ftol=rc.eiv_ftol, **{**common, "ground_noise": "tangent"},
                                ground_memory_s=rc.ground_memory_s, tangent_max_mb=rc.tangent_max_mb)
        except (UnstableTangentError, TangentTooLargeError) as err:
            return None, {"why": str(err)}
        return eiv, {"start": start, "cost_initial": eiv.cost_initial, "cost_final": eiv.cost_final, "nfev": eiv.nfev,
                     "seconds": eiv.seconds}

    def _ratio_limit(self) -> float:
        """The noise ratio above which a fit misses the data (``restart_ratio``; 1 when None)."""
        ratio = self.cfg.refine.restart_ratio
        return 1.0 if ratio is None else ratio

    def _tangent_fit(self, start: Building, ident: list[int], common: dict) -> tuple[RefineResult | None, dict]:
        """The errors-in-variables fit from the regressions' building ``start``, whitened by the
        tangent of its replay (close enough to weight the residuals: Table 1 came out as from the
        least-squares optimum, docs/identification.md); None, with the reason, where the tangent
        is unstable or larger than ``tangent_max_mb``, or the fit misses the data by more than
        ``restart_ratio`` (1 when None) times its noise or stops on ``max_iterations`` (a start
        too far for its tangent: one of 30 random buildings ran into k0's bound that way)."""
        eiv, info = self._eiv(start, ident, common, "regressions")
        if eiv is None:
            why = info["why"]
        else:
            ratio = self._noise_ratio(eiv)
            if ratio <= self._ratio_limit() and eiv.converged:
                return eiv, info
            why = (f"the errors-in-variables fit misses the data by {ratio:.1f}x its noise level"
                   if ratio > self._ratio_limit() else
                   f"the errors-in-variables fit did not converge in {eiv.nfev} evaluations")
        _progress.info(f"[identify] {why}: least squares first")
        return None, {"fallback": why}

    def _tangent_stage(self, rr: RefineResult, ident: list[int], common: dict) -> tuple[RefineResult, dict]:
        """The errors-in-variables finish from the least-squares optimum ``rr`` (the fall-back of
        :meth:`_tangent_fit`); skipped, keeping ``rr``, where that fit misses the data by more
        than its noise (``restart_ratio``, 1 when None: a tangent taken there weights nothing
        real) or the replay's tangent is unstable (found on two random buildings driven to
        80-200 x dy) or too large."""
        ratio = self._noise_ratio(rr)
        if ratio > self._ratio_limit():
            why = f"the least-squares fit misses the data by {ratio:.1f}x its noise level"
        else:
            eiv, info = self._eiv(rr.building, ident, common, "least squares")
            if eiv is not None:
                return eiv, info
            why = info["why"]
        _progress.info(f"[identify] errors-in-variables stage skipped: {why}")
        return rr, {"skipped": why}

    def _neutral_start(self, paper: Building) -> Building:
        """The restart of the refinement (``refine.restart_ratio``): mid-range shape parameters,
        yield at a tenth of each story's peak drift, k0 1.5x the estimate (HLA's k0 is low when a
        story yields before it completes a half cycle that HLA sees)."""
        n = paper.n_stories
        peak = np.array([np.max(np.abs(s.drift)) for s in self.res.stories])
        return paper.replace(k0=1.5 * paper.k0, alpha=np.full(n, 0.2), p=np.full(n, 2.0),
                             dy=np.maximum(peak / 10, 1e-3), delta_eta=np.full(n, 0.5))

    def _building(self, alpha, p, dy, de) -> Building:
        meas = self.meas
        return Building(mass=self.res.mass, k0=self.k0, alpha=alpha, p=p, dy=dy, delta_eta=de,
                        height=meas.height, damping=Damping(ratio=self.cfg.damping_ratio),
                        pdelta=meas.pdelta_active if meas.height is not None else None, name=meas.name)

    def _regressions(self, alpha, p):
        """delta_eta and dy of every story (fallbacks for stories that did not yield)."""
        n = self.res.n_stories
        de, dy, info = np.zeros(n), np.zeros(n), []
        for i, s in enumerate(self.stories):
            if not self.identifiable[i]:
                info.append(None)
                continue
            fd = story_delta_eta(s, mass=self.res.mass[i], alpha=alpha[i], k0=self.k0[i])
            fy = story_yield_displacement(s, self._features(i), alpha=alpha[i], p=p[i], k0=self.k0[i])
            de[i] = max(fd.value, 0.0) if np.isfinite(fd.value) else 0.0
            dy[i] = fy.value if np.isfinite(fy.value) and fy.value > 0 else np.max(np.abs(s.drift)) / 3.0
            info.append({"delta_eta": vars(fd), "dy": vars(fy)})
            if self.path_mode:  # keep a regression on a poor alpha from running away
                de_max, dy_max = plausible_limits(s, mass=self.res.mass[i], alpha=alpha[i], k0=self.k0[i])
                de[i], dy[i] = min(de[i], de_max), min(dy[i], dy_max)
        ok = self.identifiable
        for i, s in enumerate(self.res.stories):
            if not ok[i]:  # an elastic story: borrow from the identified ones, dy above what it reached
                de[i] = float(np.median(de[ok]))
                dy[i] = max(1.2 * float(np.max(np.abs(s.drift))), 1e-3)
        return de, dy, info

    def _set_paths(self, paths: np.ndarray) -> None:
        """Use ``paths`` ``(time, story)`` as the stories' drift in the regressions and features."""
        res, cfg = self.res, self.cfg
        self._path_features = {}
        for i, s in enumerate(res.stories):
            if cfg.training.reanalyse:  # HLA again along the path: half cycles, ke and k0
                story = reanalyse_story(s, paths[:, i], s.force, res.dt, cfg.hla, res.band_hz)
            else:
                story = dataclasses.replace(s, drift=paths[:, i])
            feats = half_cycle_features(story, cfg.training.n_segments, yield_ratio=cfg.hla.stiffness.yield_ratio)
            if self.identifiable[i] and (len(feats) < 3 or not np.isfinite(story.k0) or story.k0 <= 0):
                story, feats = s, self.features[i]  # the path lost the yielding half cycles: keep HLA's
            elif self.identifiable[i]:
                self.k0[i] = story.k0
            self.stories[i] = story
            self._path_features[i] = feats

    def _fit_k0(self, alpha, p, dy, de) -> None:
        """k0 of every identifiable story by least squares of the story law along its path
        against the measured force, the other parameters held (:mod:`hlaid.identify.loopfit`)."""
        for i, s in enumerate(self.stories):
            if not self.identifiable[i]:
                continue
            end = int(np.max(s.half_cycles.end)) + 1 if len(s.half_cycles) else s.drift.shape[0]
            fit = fit_story_loop(s.drift, s.force, self.res.dt, float(self.res.mass[i]),
                                 {"k0": self.k0[i], "alpha": alpha[i], "p": p[i], "dy": dy[i], "delta_eta": de[i]},
                                 free=("k0",), window=slice(0, end))
            self.k0[i] = fit.params["k0"]

    def _features(self, i: int):
        """Yielding half cycles and their segment slopes along story ``i``'s current path (HLA's
        before the first reconstruction)."""
        return self._path_features.get(i, self.features[i])

    def _story_paths(self) -> list:
        """Per story the :class:`StoryPath` of the path-driven training (None if not identifiable)."""
        res = self.res
        return story_paths(self.stories, [self._features(i) for i in range(res.n_stories)], mass=res.mass,
                           k0=self.k0, floor_acc=self.meas.floor_acc, noise_rms=self.noise, dt=res.dt,
                           cutoff_hz=res.band_hz[1], n_segments=self.cfg.training.n_segments,
                           identifiable=self.identifiable)

    @functools.cached_property
    def noise_histories(self) -> np.ndarray:
        """``(time, 256)`` low-passed unit white noise shared by every pass's training sets
        (:func:`hlaid.identify.pathtrain.noise_bank`)."""
        seed = 9_000_000 + self.cfg.training.seed
        return noise_bank(self.meas.n_samples, self.res.dt, self.res.band_hz[1], seed=seed)

    def _path_errors(self, est: Building, seed: int) -> np.ndarray | None:
        """``(history, time, story)`` simulated errors of the stories' current paths around
        ``est`` (``training.path_errors``), or None."""
        tc = self.cfg.training
        if tc.path_errors == 0:
            return None
        res = self.res
        rec = np.array([self.stories[i].drift is not res.stories[i].drift for i in range(res.n_stories)])
        t = time.perf_counter()
        bank = path_error_bank(res, self.ground, est, noise_rms=self.noise, n=tc.path_errors,
                               seed=7_000_000 + 100 * seed, reconstruct=rec, crossover_hz=tc.crossover_hz,
                               hla_config=self.cfg.hla)
        self.timings["path_errors"] = self.timings.get("path_errors", 0.0) + time.perf_counter() - t
        return bank if len(bank) else None

    def _ranges(self, stage: str, centre):
        """Per-story (alpha Bins, p Bins) of a pass: the coarse bins, or fine bins over the
        coarse bin holding the current value and its two neighbours."""
        b = self.cfg.bins
        out = []
        for i in range(self.res.n_stories):
            a_bins = Bins.regular(0.0, self.alpha_max[i], b.alpha_coarse)
            p_bins = Bins.regular(b.p_range[0], b.p_range[1], b.p_coarse)
            if stage == "fine":
                a_bins = a_bins.refine(int(a_bins.label(np.array([centre[0][i]]))[0]), b.alpha_fine,
                                       (0.0, self.alpha_max[i]))
                p_bins = p_bins.refine(int(p_bins.label(np.array([centre[1][i]]))[0]), b.p_fine, b.p_range)
            out.append((a_bins, p_bins))
        return out

    def _pass(self, est: Building, stage: str, it: int, centre):
        cfg = self.cfg
        bins = self._ranges(stage, centre)
        seed = cfg.training.seed + 1000 * it + (0 if stage == "coarse" else 500)
        if self.path_mode:
            paths = self._story_paths()
            measured = [None if sp is None else sp.measured_features()[None, :] for sp in paths]
            tp = path_pass(paths, est, bins, self.identifiable, cfg=cfg, stage=stage, seed=seed, cache=self.cache,
                           tb=self.tb, step=it + 1, chosen_C=self.chosen_C, path_errors=self._path_errors(est, seed),
                           noise=lambda: self.noise_histories)
        else:
            measured = [F.values for F in self.features]
            tp = train_pass(est, self.training_motion, bins, self.identifiable, noise=self.noise, cfg=cfg,
                            stage=stage, seed=seed, cache=self.cache, tb=self.tb, step=it + 1)
        if not tp.cached:
            self.timings[f"simulate_{stage}_{it + 1}"] = tp.seconds_simulate
        result = []
        for i in range(self.res.n_stories):
            entry = {}
            if self.identifiable[i]:
                for j, param in enumerate(PARAMS):
                    name = f"story{i + 1}_{param}"
                    st = tp.stats[name]
                    v = vote(machines_of(tp, name), cast(np.ndarray, measured[i]), bins[i][j], st.get("single", -1),
                             st.get("scaler"))  # an identifiable story has its measured features
                    entry[param] = pass_result(param, stage, bins[i][j], v, st, tp.cached, cfg.aggregate)
            result.append(entry)
        self.passes.append({"iteration": it + 1, "stage": stage,
                            "stories": [{k: v.to_dict() for k, v in e.items()} for e in result]})
        return result

    def _diagnostics(self, paper, final, reg, history, check, refine_info) -> dict:
        stories = []
        for i, s in enumerate(self.res.stories):
            d = {"story": i + 1, "identifiable": bool(self.identifiable[i]), "k0_hla": float(s.k0),
                 "yielded": bool(s.yielded), "n_half_cycles": len(s.half_cycles),
                 "n_yielding_half_cycles": len(self.features[i]), "alpha_max": float(self.alpha_max[i]),
                 "peak_drift": float(np.max(np.abs(s.drift))),
                 "paper_method": {k: float(getattr(paper, k)[i]) for k in ("k0", "alpha", "p", "dy", "delta_eta")},
                 "regressions": reg[i], "R_measured": float(check.r_measured[i]),
                 "R_true": None if check.r_true is None else float(check.r_true[i]),
                 "stiffness_error": float(check.stiffness_error[i])}
            if not self.identifiable[i]:
                d["reason"] = (f"story stayed elastic (peak drift {d['peak_drift']:.3g} mm, "
                               f"{len(self.features[i])} yielding half cycles): alpha, p and delta_eta are borrowed "
                               "from the identified stories and dy is set above the largest drift reached; they "
                               "are assumptions, not identified")
            stories.append(d)
        return {"stories": stories, "outer_iterations": history, "passes": self.passes, "refine": refine_info,
                "hla": {"band_hz": list(self.res.band_hz), "damping": self.res.damping,
                        "mass_normalised": self.res.mass_normalised},
                "replay": check.to_dict()}


def _rel_change(new, old) -> float:
    new, old = np.asarray(new, float), np.asarray(old, float)
    return float(np.max(np.abs(new - old) / np.maximum(np.abs(old), 1e-9)))


def identify_clone(measurement: Measurement, config: IdentifyConfig | None = None, *, tensorboard: str | None = None,
             cache_dir: str | None = None) -> IdentificationResult:
    """Identify a digital clone from a measurement, with no expert input.

    Parameters
    ----------
    measurement : ground and floor accelerations (masses optional: mass-normalised clone)
    config : settings (defaults: :class:`IdentifyConfig`)
    tensorboard : folder for TensorBoard logs (classifier accuracies, confusion matrices,
        example features, estimates per outer iteration)
    cache_dir : where trained classifiers are cached (default ``~/.cache/hlaid/svm``,
        ``HLAID_CACHE`` overrides; ``""`` disables the cache)

    Returns
    -------
    IdentificationResult
    """
    cfg = config or IdentifyConfig()
    cache = cache_dir if cache_dir is not None else cfg.cache_dir
    return _Identifier(measurement, cfg, tensorboard, cache).run()
