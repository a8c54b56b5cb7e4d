"""Output-error least squares through the differentiable torch model (a baseline identifier).

:class:`GradientIdentifier` fits the story parameters ``k0, alpha, p, dy, delta_eta`` so that
the absolute floor accelerations of :class:`hlaid.model.BoucWenBuilding` match the measured
ones. Derivatives come from automatic differentiation through a fixed-step RK4 over
``BoucWenBuilding.rates`` (the single model definition); the optimiser is Levenberg-Marquardt
(Gauss-Newton with Marquardt's damping), the standard for least squares.

Method, and what makes it affordable (eager torch costs ~0.25 ms per right-hand-side call
whatever the batch size, so the batch carries everything that can run side by side):

1. **Screened starts.** ``n_candidates`` random parameter sets (``k0`` within
   ``+-k0_spread`` of HLA's, the others from the ranges) are screened by the compiled batch
   simulator (:func:`hlaid.simulate.simulate_response`, forward only, ~1 s for 256); the
   ``n_starts`` with the lowest loss start the descent, and the lowest final loss is kept.
   The output-error loss has local minima in which unscreened random starts can all settle;
   screening puts the starts in the basin of the global one.
2. **Jacobians by forward-mode AD, tangents in the batch.** The ``P = 5 x story`` tangent
   directions are extra batch rows of one dual-number pass (``torch.autograd.forward_ad``),
   so a Jacobian costs one pass, not ``P`` (``torch.func.vmap`` of ``jvp`` is 1.6x slower).
3. **Segments in the batch.** The fit window is cut into segments of ``segment_s``; the
   compiled simulator gives every segment's initial state at the current parameters and
   torch integrates all segments of all starts as one batch, so a pass costs ``segment_s``
   of sequential steps rather than the whole window. The stitched response *is* the
   full-record response (the two integrators agree to 1e-8): residuals and losses are
   exact. State sensitivities at a segment's end seed the next segment's start in the next
   pass (waveform relaxation), so the Jacobian crosses segment boundaries and becomes the
   full-trajectory Jacobian as the iterates settle (``tests/test_identifiers.py`` checks both
   against finite differences). Without the carried seeds the Jacobian is truncated and the
   descent stalls short of the optimum; with them the best start converges in 10-17
   iterations. The segment length hardly changes the number of iterations, so the default
   is short (0.25 s: the least CPU time).
4. **One RK4 step per sample** (``substeps=1``): at 200 Hz its accelerations differ from the
   16-sub-step integration by 2e-4 (relative RMS), far below the 1 % target (the recovered
   parameters are within 0.13 % of the truth); starts that are done leave the batch.
5. **The strong-motion window** (``arias``): the weak start and the free-vibration tail
   carry little information per second of integration. The response before the window
   starts is simulated, but its parameter sensitivity at the window start is left out (the
   ground has delivered 1 % of its Arias intensity 1 s later).
6. **One thread** during ``fit``: intra-op threads on these small tensors only contend
   (see ``hlaid/_threads.py``).

Levenberg-Marquardt rather than a first-order optimiser: Gauss-Newton steps converge in tens
of iterations where Adam on truncated reverse-mode gradients needs hundreds of epochs, and
forward mode gives the Jacobian at the price of about three gradients.

The loss is the mean squared difference of the band-passed floor accelerations, each
channel divided by its measured RMS (as :func:`hlaid.identify.refine_replay`; the zero-phase
band-pass is applied as the Butterworth ``|H(f)|^2`` in the frequency domain, identically
to model and data, so it is differentiable); the ground input is the measured one low-passed
at ``band_hz[1]``. Constraints by reparameterisation (:mod:`hlaid.baselines._space`): log for
``k0`` and ``dy``, sigmoid for ``alpha`` in (0, 1), ``1 + softplus`` for ``p``, softplus for
``delta_eta``. Masses come from the measurement (mass ratios as HLA when unknown), damping is
5 % Rayleigh (assumed, like the other identifiers), P-Delta as the measurement says.
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch
import torch.autograd.forward_ad as fwAD
from scipy import signal

from .. import _progress
from .._threads import one_thread
from ..clone import Clone
from ..errors import InputError, NotIdentifiableError
from ..estimators import BaseIdentifier
from ..identify.tb import TBLogger
from ..measurement import Measurement, measured_ground
from ..model import BoucWenBuilding
from ..signal import arias_window, butter_sos, cap_corner
from ..simulate import simulate_response
from . import _space as sp

INITS = ("hla", "ranges")
"""Where the starting ``k0`` comes from: ``"hla"`` (hysteresis loop analysis of the
measurement, then ``+-k0_spread``; ``dy`` starts are fractions of HLA's peak drifts) or
``"ranges"`` (log-uniform in ``k0_range``; ``dy`` uniform in ``dy_range`` [mm])."""


def zero_phase_gain(n: int, dt: float, band_hz, order: int = 4) -> np.ndarray:
    """``|H(f)|^2`` of the Butterworth band-pass (low-pass when ``band_hz[0]`` is 0) at the
    ``rfft`` frequencies of ``n`` samples: the gain of forward-backward filtering."""
    sos = butter_sos(band_hz, dt, order)
    _, h = signal.sosfreqz(sos, worN=np.fft.rfftfreq(n, dt), fs=1.0 / dt)
    return np.abs(h) ** 2


def filtered(x: torch.Tensor, gain: torch.Tensor) -> torch.Tensor:
    """Zero-phase filter of ``x`` ``(batch, time, channel)`` along time, zero-padded to the
    length ``gain`` was made for: a symmetric linear operator, differentiable."""
    n = 2 * (gain.shape[0] - 1)
    X = torch.fft.rfft(x, n=n, dim=1)
    return torch.fft.irfft(X * gain[None, :, None], n=n, dim=1)[:, : x.shape[1]]


class OutputErrorProblem:
    """The data of one fit and the segmented, batched forward model.

    Parameters
    ----------
    meas : the measurement; known : masses, P-Delta, damping
    band_hz : band of the compared accelerations [Hz]
    window : ``[i0, i1)`` samples over which accelerations are compared
    segment_s : segment length [s]; substeps : RK4 steps per sample
    """

    def __init__(self, meas: Measurement, known: sp.KnownPart, band_hz, window: tuple[int, int],
                 segment_s: float = 1.0, substeps: int = 1):
        self.known, self.dt, self.substeps = known, meas.dt, int(substeps)
        self.ground = measured_ground(meas, cap_corner(band_hz[1], meas.dt))
        self.ag = torch.as_tensor(self.ground.acc.copy())
        self.i0, self.i1 = window
        n = self.i1 - self.i0
        hi = cap_corner(band_hz[1], self.dt)
        nfft = 1 << math.ceil(math.log2(2 * n))
        self.gain = torch.as_tensor(zero_phase_gain(nfft, self.dt, (band_hz[0], hi)))
        self.target = filtered(torch.as_tensor(np.array(meas.floor_acc[self.i0:self.i1]))[None], self.gain)[0]
        self.scale = self.target.pow(2).mean(dim=0).sqrt().clamp_min(1e-12)
        self.S = max(2, round(segment_s / self.dt))
        self.starts = self.i0 + self.S * np.arange(math.ceil(n / self.S))

    @property
    def n_segments(self) -> int:
        return int(self.starts.shape[0])

    def _simulate(self, values: dict[str, np.ndarray], end: int):
        B = values["k0"].shape[0]
        buildings = [self.known.building({k: v[b] for k, v in values.items()}) for b in range(B)]
        g = self.ground
        return simulate_response(buildings, type(g)(dt=g.dt, acc=g.acc[:end], name=g.name), substeps=self.substeps)

    def start_states(self, values: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """States ``(batch, segment, 4*story)`` at the segment starts (compiled simulator) and
        ``(batch,)`` whether each simulation stayed finite."""
        r = self._simulate(values, int(self.starts[-1]) + 1)
        e = r.energy / ((1.0 - values["alpha"]) * values["k0"])[:, None]
        states = np.concatenate([r.disp, r.vel, r.z, e], axis=-1)[:, self.starts]
        ok = (r.status == 0) & np.isfinite(states).all(axis=(1, 2))
        return np.nan_to_num(states), ok

    def screen(self, values: dict[str, np.ndarray]) -> np.ndarray:
        """``(batch,)`` losses of candidate parameter sets ``(batch, story)`` by the compiled
        simulator alone (no derivatives); NaN where a simulation diverged."""
        r = self._simulate(values, self.i1)
        with torch.no_grad():
            loss = self.losses(torch.as_tensor(np.nan_to_num(r.acc[:, self.i0:self.i1])))
        return np.where(r.status == 0, loss.numpy(), np.nan)

    def accelerations(self, values: dict[str, torch.Tensor], y0: torch.Tensor):
        """Absolute floor accelerations ``(batch, window, story)`` and the states at every
        segment's end ``(batch, segment, 4*story)``, all segments integrated as one batch.

        ``values`` are ``(batch, story)`` story values, ``y0`` ``(batch, segment, 4*story)``
        segment initial states; differentiable in both.
        """
        B, n_seg = y0.shape[:2]
        S, m = self.S, self.substeps
        rep = {k: v.repeat_interleave(n_seg, dim=0) for k, v in values.items()}
        model = BoucWenBuilding(self.known.tensors(rep))
        idx = (torch.as_tensor(self.starts)[:, None] + torch.arange(S + 1)[None]).clamp_max(self.ag.shape[0] - 1)
        g = self.ag[idx].repeat(B, 1)  # (B*n_seg, S+1)
        y = y0.reshape(B * n_seg, -1)
        states = [y]
        for k in range(S):
            y = model.rk4_sample(y, g[:, k], g[:, k + 1], self.dt, m)
            states.append(y)
        acc = model.responses(torch.stack(states[:S], dim=1))["acc"]  # (B*n_seg, S, story)
        return acc.reshape(B, n_seg * S, -1)[:, : self.i1 - self.i0], y.reshape(B, n_seg, -1)

    def residuals(self, acc: torch.Tensor) -> torch.Tensor:
        """``(batch, window*story)`` normalised residuals of the filtered accelerations."""
        r = (filtered(acc, self.gain) - self.target[None]) / self.scale
        return r.reshape(r.shape[0], -1)

    def losses(self, acc: torch.Tensor) -> torch.Tensor:
        """``(batch,)`` loss: the mean squared normalised residual."""
        return self.residuals(acc).pow(2).mean(dim=1)

    def jacobian(self, theta: torch.Tensor, k0_ref, dy_ref, carried: torch.Tensor):
        """Residuals ``(batch, N)``, their Jacobian ``(batch, N, P)`` in the unconstrained
        coordinates ``theta`` ``(batch, 5, story)``, ``(batch,)`` finite flags, and the state
        sensitivities at the segment ends ``(batch, P, segment, 4*story)``.

        One forward-mode pass with the ``P`` tangent directions as extra batch rows.
        ``carried`` are the previous pass's segment-end sensitivities: they seed the
        sensitivity at the next segment's start (zeros: truncated at every segment).
        """
        B, F, n = theta.shape
        P = F * n
        with torch.no_grad():
            values = sp.from_unconstrained(theta, k0_ref, dy_ref)
            y0, ok = self.start_states(sp.values_numpy(values))
            tangent = torch.eye(P, dtype=theta.dtype).reshape(P, F, n).repeat(B, 1, 1)
            seed = torch.nn.functional.pad(carried[:, :, :-1], (0, 0, 1, 0)).reshape(B * P, *y0.shape[1:])
            with fwAD.dual_level():
                v = sp.from_unconstrained(fwAD.make_dual(theta.repeat_interleave(P, dim=0), tangent), k0_ref, dy_ref)
                y0d = fwAD.make_dual(torch.as_tensor(np.repeat(y0, P, axis=0)), seed)
                acc, end = self.accelerations(v, y0d)
                res, jac = fwAD.unpack_dual(self.residuals(acc))
                end_tan = fwAD.unpack_dual(end).tangent
        r = res.reshape(B, P, -1)[:, 0]
        J = jac.reshape(B, P, -1).transpose(1, 2)
        ok = ok & torch.isfinite(r).all(dim=1).numpy() & torch.isfinite(J).all(dim=(1, 2)).numpy()
        return r, J, ok, torch.nan_to_num(end_tan.reshape(B, P, *end_tan.shape[1:]))


def levenberg_marquardt(problem: OutputErrorProblem, theta0: torch.Tensor, k0_ref, dy_ref, *, iterations: int,
                        tol: float = 1e-3, tb: TBLogger | None = None, bar: _progress.Stage | None = None):
    """Levenberg-Marquardt (Marquardt's diagonal scaling) on every start of ``theta0``
    ``(start, 5, story)`` at once, one Jacobian pass per iteration.

    After two rejected steps in a row a start's next pass re-evaluates its Jacobian where it
    stands (the carried sensitivities have moved on by then) instead of trying a step. A start
    is done when the Gauss-Newton step predicts a relative loss decrease below ``tol``, when
    two accepted steps in a row lowered it by less than ``tol``, or when its damping
    saturates; done starts leave the batch and the run stops once the best start is done.
    Returns the coordinates, the ``(iteration, start)`` loss history and the number of passes
    (``bar``: a progress stage counting the iterations).
    """
    theta = theta0.detach().clone()
    B, F, n = theta.shape
    carried = torch.zeros(B, F * n, problem.n_segments, 4 * n, dtype=theta.dtype)
    r, J, ok, carried = problem.jacobian(theta, k0_ref, dy_ref, carried)
    N = r.shape[1]
    loss = torch.where(torch.as_tensor(ok), r.pow(2).mean(dim=1), torch.inf)
    lam = torch.full((B,), 1e-3, dtype=theta.dtype)
    quiet = torch.zeros(B, dtype=torch.long)
    rejected = torch.zeros(B, dtype=torch.long)
    done = ~torch.isfinite(loss)
    hist, passes = [loss.numpy().copy()], 1
    for it in range(iterations):
        A = J.transpose(1, 2) @ J / N
        g = (J.transpose(1, 2) @ r[..., None] / N)[..., 0]
        scale = torch.diagonal(A, dim1=1, dim2=2).clamp_min(1e-12)
        gn = torch.linalg.solve(A + 1e-10 * torch.diag_embed(scale), -g[..., None])[..., 0]
        predicted = -(g * gn).sum(dim=1) / loss.clamp_min(1e-300)  # Gauss-Newton decrease / loss
        done |= (predicted < tol) | (quiet >= 2) | (lam >= 1e8)
        best = int(torch.argmin(loss))
        if done[best]:
            break
        a = torch.nonzero(~done)[:, 0]
        delta = torch.linalg.solve(A[a] + lam[a, None, None] * torch.diag_embed(scale[a]), -g[a, :, None])[..., 0]
        refresh = rejected[a] >= 2
        delta[refresh] = 0.0
        trial = theta[a] + delta.clamp(-1.0, 1.0).reshape(-1, F, n)
        r2, J2, ok2, carried[a] = problem.jacobian(trial, k0_ref, dy_ref, carried[a])
        passes += 1
        loss2 = torch.where(torch.as_tensor(ok2), r2.pow(2).mean(dim=1), torch.inf)
        better = (loss2 < loss[a]) & ~refresh
        keep = better | (refresh & torch.isfinite(loss2))
        change = (loss[a] - loss2) / loss[a].clamp_min(1e-300)
        quiet[a] = torch.where(better, torch.where(change > tol, 0, quiet[a] + 1), quiet[a])
        rejected[a] = torch.where(better | refresh, 0, rejected[a] + 1)
        k = a[keep]
        theta[k], r[k], J[k], loss[k] = trial[keep], r2[keep], J2[keep], loss2[keep]
        lam[a] = torch.where(better, lam[a] / 3.0, torch.where(refresh, lam[a], lam[a] * 4.0)).clamp(1e-9, 1e9)
        hist.append(loss.numpy().copy())
        if bar is not None:
            bar.update(1, note=f"best loss {float(loss.min()):.4g}, {int((~done).sum())} start(s) still descending")
        if tb is not None and torch.isfinite(loss).any():
            tb.scalar("gradient/best_loss", float(loss.min()), it + 1)
        _progress.debug(f"[gradient] iteration {it + 1}: losses {np.array2string(loss.numpy(), precision=4)}, "
                        f"predicted {np.array2string(predicted.numpy(), precision=2)}")
    return theta, np.array(hist), passes


class GradientIdentifier(BaseIdentifier):
    """Least squares on the measured floor accelerations through the differentiable model:
    screened random starts, then Levenberg-Marquardt with forward-mode AD Jacobians (see the
    module docstring for the method and its speed-ups).

    Parameters
    ----------
    n_candidates : random parameter sets screened by the compiled simulator
    n_starts : the best screened candidates that start the descent (one batch)
    init : ``"hla"`` or ``"ranges"`` (see :data:`INITS`)
    max_iterations : Levenberg-Marquardt iterations (one Jacobian pass each)
    segment_s : segment length [s]
    substeps : RK4 steps per sample
    arias : Arias-intensity fractions bounding the fit window (1 s before, 2 s after)
    band_hz : band of the compared accelerations [Hz]
    damping_ratio : Rayleigh damping assumed (modes 1 and 2)
    alpha_range, p_range, delta_eta_range : ranges of the random candidates
    dy_range : ``dy`` candidates: fractions of HLA's peak drift (init "hla") or mm ("ranges")
    k0_spread : ``k0`` candidates within ``x/(1 + k0_spread)`` of HLA's (init "hla")
    k0_range : ``k0`` candidates [N/mm, or N/mm per t of relative mass] (init "ranges")
    tol : relative loss decrease under which a start is done
    random_state : seed of the candidates
    tensorboard : folder for TensorBoard logs (best loss per iteration) or None

    Attributes
    ----------
    clone_ : the identified clone; fit_seconds_ : wall time
    loss_history_ : (iteration + 1, start) losses of the descent
    start_losses_ : (start,) final loss of every start (the lowest is kept)
    """

    def __init__(self, *, n_candidates: int = 256, n_starts: int = 6, init: str = "hla", max_iterations: int = 30,
                 segment_s: float = 0.25, substeps: int = 1, arias=(0.01, 0.95), band_hz=(0.1, 20.0),
                 damping_ratio: float = 0.05, alpha_range=(0.02, 0.5), p_range=(1.0, 3.0), dy_range=(0.1, 0.6),
                 delta_eta_range=(0.0, 2.0), k0_spread: float = 0.2, k0_range=(1e3, 1e5), tol: float = 1e-3,
                 random_state: int = 0, tensorboard: str | None = None):
        self.n_candidates = n_candidates
        self.n_starts = n_starts
        self.init = init
        self.max_iterations = max_iterations
        self.segment_s = segment_s
        self.substeps = substeps
        self.arias = arias
        self.band_hz = band_hz
        self.damping_ratio = damping_ratio
        self.alpha_range = alpha_range
        self.p_range = p_range
        self.dy_range = dy_range
        self.delta_eta_range = delta_eta_range
        self.k0_spread = k0_spread
        self.k0_range = k0_range
        self.tol = tol
        self.random_state = random_state
        self.tensorboard = tensorboard

    def _check(self) -> None:
        if self.init not in INITS:
            raise InputError(f"init = {self.init!r}; expected one of {list(INITS)}")
        if not 1 <= int(self.n_starts) <= int(self.n_candidates):
            raise InputError(f"n_starts = {self.n_starts}, n_candidates = {self.n_candidates}; expected "
                             "1 <= n_starts <= n_candidates")
        if int(self.max_iterations) < 0 or int(self.substeps) < 1 or not self.segment_s > 0:
            raise InputError("max_iterations must be >= 0, substeps >= 1 and segment_s > 0 [s]")

    def _candidates(self, meas: Measurement, known: sp.KnownPart, rng) -> dict[str, np.ndarray]:
        kw = {"rng": rng, "alpha_range": self.alpha_range, "p_range": self.p_range, "dy_range": self.dy_range,
                  "delta_eta_range": self.delta_eta_range}
        n = int(self.n_candidates)
        if self.init == "hla":
            k0, drift = sp.hla_scales(meas)
            return sp.draw_starts(n, k0=k0, dy_scale=drift, k0_spread=self.k0_spread, **kw)
        lo, hi = self.k0_range
        v = sp.draw_starts(n, k0=np.ones(known.n_stories), dy_scale=np.ones(known.n_stories), **kw)
        v["k0"] = np.exp(rng.uniform(np.log(lo), np.log(hi), size=v["k0"].shape))
        v["k0"][0] = np.sqrt(lo * hi)
        return v

    def fit(self, measurement: Measurement) -> GradientIdentifier:
        """Identify the clone from ``measurement`` (ground and floor accelerations)."""
        self._check()
        meas = measurement
        t0 = time.perf_counter()
        with one_thread():  # tiny tensors: intra-op threads only add contention
            known = sp.known_part(meas, self.damping_ratio)
            cand = self._candidates(meas, known, np.random.default_rng(self.random_state))
            window = arias_window(measured_ground(meas, cap_corner(self.band_hz[1], meas.dt)).acc, meas.dt, self.arias)
            prob = OutputErrorProblem(meas, known, self.band_hz, window, self.segment_s, self.substeps)
            with _progress.stage(f"[gradient] screening {self.n_candidates} candidates"):
                screened = prob.screen(cand)
            if not np.isfinite(screened).any():
                raise NotIdentifiableError("every candidate diverged; the record or the ranges do not suit the "
                                           "gradient identifier", source=meas.source or None)
            order = np.argsort(np.where(np.isfinite(screened), screened, np.inf))[: int(self.n_starts)]
            k0_ref, dy_ref = np.median(cand["k0"], axis=0), np.median(cand["dy"], axis=0)
            theta0 = torch.as_tensor(sp.to_unconstrained({k: v[order] for k, v in cand.items()}, k0_ref, dy_ref))
            _progress.info(f"[gradient] {self.n_candidates} candidates screened; {len(order)} starts, window "
                           f"{window[0] * meas.dt:.1f}-{window[1] * meas.dt:.1f} s, {prob.n_segments} segments")
            tb = TBLogger(self.tensorboard)
            with _progress.stage(f"[gradient] Levenberg-Marquardt from {len(order)} starts", int(self.max_iterations),
                                 unit="iterations") as bar:
                theta, hist, passes = levenberg_marquardt(prob, theta0, k0_ref, dy_ref, tol=self.tol, tb=tb, bar=bar,
                                                          iterations=int(self.max_iterations))
                bar.done(f"best loss {float(np.nanmin(hist[-1])):.4g}")
            tb.close()
        final = hist[-1]
        best = int(np.argmin(np.where(np.isfinite(final), final, np.inf)))
        values = sp.values_numpy(sp.from_unconstrained(theta[best:best + 1], k0_ref, dy_ref))
        building = known.building({k: v[0] for k, v in values.items()})
        self.loss_history_ = hist
        self.start_losses_ = final
        self.fit_seconds_ = time.perf_counter() - t0
        diagnostics = {"method": "gradient (Levenberg-Marquardt, forward-mode AD)", "loss": float(final[best]),
                       "best_start": best, "start_losses": final.tolist(), "screened_losses": screened[order].tolist(),
                       "iterations": len(hist) - 1, "jacobian_passes": passes,
                       "window_s": [window[0] * meas.dt, window[1] * meas.dt]}
        provenance = {"identifier": repr(self), "source": meas.source, "seconds": self.fit_seconds_}
        self.clone_ = Clone(building=building, mass_normalised=known.mass_normalised, diagnostics=diagnostics,
                            provenance=provenance)
        return self
