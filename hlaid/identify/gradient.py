"""Output-error least squares through the differentiable torch model (a baseline identifier).

:class:`GradientIdentifier` fits the story parameters ``k0, alpha, p, dy, delta_eta`` so that
the absolute floor accelerations of :class:`hlaid.model.BoucWenBuilding` match the measured
ones, by gradient descent with gradients from backpropagation through a fixed-step RK4 over
``BoucWenBuilding.rates`` (the single model definition).

How it is made affordable (eager torch costs ~0.25 ms per right-hand-side call whatever the
batch size, ~1 ms with its backward pass):

* **Segments in the batch (truncated backpropagation).** The fit window is cut into short
  segments (``segment_s``). The compiled batch simulator (:func:`hlaid.simulate.simulate`,
  no gradients, milliseconds) gives the state at every segment start for the current
  parameters; torch then integrates every segment of every start *in one batch*, so one
  epoch costs ``segment_s / step`` sequential RK4 steps instead of ``window / step``. The
  stitched response is the full-record response (the two integrators agree to ~1e-10);
  only the gradient is truncated: the dependence of a segment's initial state on the
  parameters is left out. The fixed point is unchanged on noise-free data (zero residual,
  zero gradient); with noise it is a multiple-shooting estimator whose segments are tied to
  the simulated states. The polish stage uses longer segments, so less is truncated.
* **Several starts in the same batch** (``n_starts``): 8-16 starts cost about one.
* **Coarse then fine integration.** The search runs one RK4 step per sample (``substeps``);
  the polish stage, on the best start only, uses ``polish_substeps`` (4, as the synthetic
  data and the other identifiers), so the coarse stage's integration bias is removed.
* **The strong-motion window** (``arias``) only: the weak start and the free-vibration tail
  carry little information per second of integration.

The loss is the mean squared difference of the band-passed (``band_hz``, zero-phase
Butterworth of order 4 applied as ``|H(f)|^2`` in the frequency domain, identical on model
and data) floor accelerations, each channel divided by its measured RMS; the ground input
is low-passed at ``band_hz[1]`` as in :func:`hlaid.identify.refine_replay`.

Constraints by reparameterisation (:mod:`hlaid.identify._space`): log for ``k0`` and
``dy``, sigmoid for ``alpha`` in (0, 1), ``1 + softplus`` for ``p``, softplus for
``delta_eta``. Masses come from the measurement (mass ratios as HLA when unknown), damping
is 5 % Rayleigh (assumed, like the other identifiers), P-Delta as the measurement says.
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch
import torch.autograd.forward_ad as fwAD
from scipy import signal

from .. import _progress
from ..clone import Clone
from ..errors import InputError, NotIdentifiableError
from ..hla import hla
from ..hla.preprocess import _sos
from ..measurement import Measurement
from ..model import BoucWenBuilding
from ..simulate import simulate
from . import _space as sp
from .estimators import BaseIdentifier
from .tb import TBLogger

INITS = ("hla", "ranges")
"""Where the starting ``k0`` comes from: ``"hla"`` (hysteresis loop analysis of the
measurement; ``dy`` starts are then fractions of HLA's peak drifts) or ``"ranges"`` (log-uniform
in ``k0_range``, ``dy`` uniform in ``dy_range`` [mm])."""


def zero_phase_gain(n: int, dt: float, band_hz, order: int = 4) -> np.ndarray:
    """``|H(f)|^2`` of the Butterworth band-pass (low-pass when ``band_hz[0]`` is 0) at the
    ``rfft`` frequencies of ``n`` samples: the gain of forward-backward filtering."""
    sos = _sos(band_hz, order, dt, "bandpass")
    f = np.fft.rfftfreq(n, dt)
    _, h = signal.sosfreqz(sos, worN=f, fs=1.0 / dt)
    return np.abs(h) ** 2


def filtered(x: torch.Tensor, gain: torch.Tensor) -> torch.Tensor:
    """Zero-phase filter of ``x`` ``(batch, time, channel)`` along time, zero-padded to the
    length ``gain`` was made for (a symmetric linear operator, differentiable)."""
    n = 2 * (gain.shape[0] - 1)
    X = torch.fft.rfft(x, n=n, dim=1)
    return torch.fft.irfft(X * gain[None, :, None], n=n, dim=1)[:, : x.shape[1]]


def arias_window(acc: np.ndarray, dt: float, arias, tail_s: float = 2.0, lead_s: float = 1.0) -> tuple[int, int]:
    """Sample range ``[i0, i1)`` from ``lead_s`` before the ``arias[0]`` Arias fraction to
    ``tail_s`` after the ``arias[1]`` fraction."""
    e = np.cumsum(np.asarray(acc) ** 2)
    i0 = max(0, int(np.searchsorted(e, arias[0] * e[-1])) - int(round(lead_s / dt)))
    i1 = min(acc.shape[0], int(np.searchsorted(e, arias[1] * e[-1])) + int(round(tail_s / dt)) + 1)
    return i0, i1


class _Problem:
    """The data of one fit and the batched, segmented forward model."""

    def __init__(self, meas: Measurement, known: sp.KnownPart, band_hz, window: tuple[int, int]):
        self.meas, self.known = meas, known
        self.dt = meas.dt
        self.ground = sp.measured_ground(meas, band_hz)
        self.i0, self.i1 = window
        n = self.i1 - self.i0
        self.nfft = 1 << int(math.ceil(math.log2(2 * n)))
        hi = min(band_hz[1], 0.45 / self.dt)
        self.gain = torch.as_tensor(zero_phase_gain(self.nfft, self.dt, (band_hz[0], hi)))
        meas_acc = torch.as_tensor(np.asarray(meas.floor_acc)[self.i0:self.i1])[None]
        self.target = filtered(meas_acc, self.gain)[0]
        self.scale = self.target.pow(2).mean(dim=0).sqrt().clamp_min(1e-12)
        self.ag = torch.as_tensor(self.ground.acc)

    def segments(self, segment_s: float) -> tuple[np.ndarray, int]:
        """Segment start samples and the samples per segment covering the window."""
        S = max(2, int(round(segment_s / self.dt)))
        n_seg = int(math.ceil((self.i1 - self.i0) / S))
        starts = self.i0 + S * np.arange(n_seg)
        return starts, S

    def start_states(self, values: dict[str, np.ndarray], starts: np.ndarray, substeps: int):
        """States ``(batch, segment, 4*story)`` at the segment starts (compiled simulator) and
        ``(batch,)`` whether each simulation stayed finite."""
        B = values["k0"].shape[0]
        buildings = [self.known.building({k: v[b] for k, v in values.items()}) for b in range(B)]
        end = int(starts[-1]) + 1
        g = self.ground
        motion = type(g)(dt=g.dt, acc=g.acc[:end], name=g.name)
        r = simulate(buildings, motion, substeps=substeps)
        a = np.stack([b.alpha for b in buildings])[:, None]
        k0 = np.stack([b.k0 for b in buildings])[:, None]
        e = r.energy / ((1.0 - a) * k0)
        states = np.concatenate([r.disp, r.vel, r.z, e], axis=-1)[:, starts]
        ok = (r.status == 0) & np.isfinite(states).all(axis=(1, 2))
        return np.nan_to_num(states), ok

    def accelerations(self, values: dict[str, torch.Tensor], y0, starts: np.ndarray, S: int,
                      substeps: int, with_end: bool = False):
        """Absolute floor accelerations ``(batch, window, story)`` of every start, from its
        segments integrated as one batch (differentiable in ``values`` and ``y0``).

        ``y0`` is ``(batch, segment, 4*story)``; with ``with_end`` the states at the end of
        every segment (the next one's start), ``(batch, segment, 4*story)``, are returned too.
        """
        B, n_seg = y0.shape[:2]
        rep = {k: v.repeat_interleave(n_seg, dim=0) for k, v in values.items()}
        model = BoucWenBuilding(self.known.tensors(rep))
        idx = torch.as_tensor(starts)[:, None] + torch.arange(S + 1)[None]
        idx = idx.clamp_max(self.ag.shape[0] - 1)
        g = self.ag[idx].repeat(B, 1)  # (B*n_seg, S+1)
        y = torch.as_tensor(y0).reshape(B * n_seg, -1)
        h = self.dt / substeps
        states = [y]
        for k in range(S if with_end else S - 1):
            lo, da = g[:, k], g[:, k + 1] - g[:, k]
            for s in range(substeps):
                k1 = model.rates(y, lo + da * (s / substeps))
                k2 = model.rates(y + 0.5 * h * k1, lo + da * ((s + 0.5) / substeps))
                k3 = model.rates(y + 0.5 * h * k2, lo + da * ((s + 0.5) / substeps))
                k4 = model.rates(y + h * k3, lo + da * ((s + 1.0) / substeps))
                y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            states.append(y)
        acc = model.responses(torch.stack(states[:S], dim=1))["acc"]  # (B*n_seg, S, story)
        acc = acc.reshape(B, n_seg * S, -1)[:, : self.i1 - self.i0]
        return (acc, y.reshape(B, n_seg, -1)) if with_end else acc

    def residuals(self, acc: torch.Tensor) -> torch.Tensor:
        """``(batch, window*story)`` normalised residuals of the filtered accelerations, scaled
        so that their mean square is the loss."""
        r = (filtered(acc, self.gain) - self.target[None]) / self.scale
        return r.reshape(r.shape[0], -1)

    def losses(self, acc: torch.Tensor) -> torch.Tensor:
        """``(batch,)`` mean squared normalised residual of the filtered accelerations."""
        return self.residuals(acc).pow(2).mean(dim=1)


class GradientIdentifier(BaseIdentifier):
    """Least squares on the measured floor accelerations through the differentiable model,
    several starts, Adam (see the module docstring for the method and its speed-ups).

    Parameters
    ----------
    n_starts : starting points, integrated together as one batch
    init : ``"hla"`` or ``"ranges"`` (see :data:`INITS`)
    epochs : Adam epochs of the multi-start search (coarse integration)
    lr : Adam learning rate of the search in the unconstrained coordinates (decays to 1/10)
    substeps : RK4 steps per sample in the search
    segment_s : segment length of the search [s]
    polish_epochs, polish_lr, polish_substeps, polish_segment_s : the same for the polish of
        the best start
    arias : Arias-intensity fractions bounding the fit window (1 s before, 2 s after)
    band_hz : band of the compared accelerations [Hz]
    damping_ratio : Rayleigh damping assumed (modes 1 and 2)
    alpha_range, p_range, delta_eta_range : ranges of the random starts
    dy_range : ``dy`` starts: fractions of HLA's peak drift (init "hla") or mm (init "ranges")
    k0_range : ``k0`` starts [N/mm, or N/mm per t when masses are unknown] (init "ranges")
    random_state : seed of the starts
    tensorboard : folder for TensorBoard logs (loss per epoch) or None

    Attributes
    ----------
    clone_ : the identified clone; fit_seconds_ : wall time;
    loss_history_ : (epoch, start) search losses, then the polish losses of the best start;
    start_losses_ : (start,) search loss of every start at the end of the search
    """

    def __init__(self, *, n_starts: int = 8, init: str = "hla", epochs: int = 150, lr: float = 0.05,
                 substeps: int = 1, segment_s: float = 0.25, polish_epochs: int = 40, polish_lr: float = 0.01,
                 polish_substeps: int = 4, polish_segment_s: float = 0.5, arias=(0.01, 0.95),
                 band_hz=(0.1, 20.0), damping_ratio: float = 0.05, alpha_range=(0.02, 0.5), p_range=(1.0, 3.0),
                 dy_range=(0.1, 0.6), delta_eta_range=(0.0, 2.0), k0_range=(1e3, 1e5), random_state: int = 0,
                 tensorboard: str | None = None):
        self.n_starts = n_starts
        self.init = init
        self.epochs = epochs
        self.lr = lr
        self.substeps = substeps
        self.segment_s = segment_s
        self.polish_epochs = polish_epochs
        self.polish_lr = polish_lr
        self.polish_substeps = polish_substeps
        self.polish_segment_s = polish_segment_s
        self.arias = arias
        self.band_hz = band_hz
        self.damping_ratio = damping_ratio
        self.alpha_range = alpha_range
        self.p_range = p_range
        self.dy_range = dy_range
        self.delta_eta_range = delta_eta_range
        self.k0_range = k0_range
        self.random_state = random_state
        self.tensorboard = tensorboard

    # ------------------------------------------------------------------ fit
    def _check(self) -> None:
        if self.init not in INITS:
            raise InputError(f"init = {self.init!r}; expected one of {list(INITS)}")
        if int(self.n_starts) < 1 or int(self.epochs) < 0 or int(self.polish_epochs) < 0:
            raise InputError("n_starts must be >= 1 and epochs, polish_epochs >= 0")
        if int(self.substeps) < 1 or int(self.polish_substeps) < 1:
            raise InputError("substeps and polish_substeps must be >= 1")
        if not (self.segment_s > 0 and self.polish_segment_s > 0):
            raise InputError("segment_s and polish_segment_s must be > 0 [s]")

    def _starting_points(self, meas: Measurement, known: sp.KnownPart, rng):
        if self.init == "hla":
            res = hla(meas)
            k0 = res.k0
            drift = np.array([np.max(np.abs(s.drift)) for s in res.stories])
            return sp.draw_starts(int(self.n_starts), k0=k0, dy_scale=drift, rng=rng, alpha_range=self.alpha_range,
                                  p_range=self.p_range, dy_range=self.dy_range,
                                  delta_eta_range=self.delta_eta_range)
        lo, hi = self.k0_range
        n = known.n_stories
        k0 = np.exp(rng.uniform(np.log(lo), np.log(hi), size=(int(self.n_starts), n)))
        k0[0] = np.sqrt(lo * hi)
        v = sp.draw_starts(int(self.n_starts), k0=np.ones(n), dy_scale=np.ones(n), rng=rng,
                           alpha_range=self.alpha_range, p_range=self.p_range, dy_range=self.dy_range,
                           delta_eta_range=self.delta_eta_range)
        v["k0"] = k0
        return v

    def fit(self, measurement: Measurement) -> "GradientIdentifier":
        """Identify the clone from ``measurement`` (floor and ground accelerations)."""
        self._check()
        t0 = time.perf_counter()
        meas = measurement
        rng = np.random.default_rng(self.random_state)
        known = sp.known_part(meas, self.damping_ratio)
        start = self._starting_points(meas, known, rng)
        k0_ref = np.median(start["k0"], axis=0)
        dy_ref = np.median(start["dy"], axis=0)
        window = arias_window(sp.measured_ground(meas, self.band_hz).acc, meas.dt, self.arias)
        prob = _Problem(meas, known, self.band_hz, window)
        tb = TBLogger(self.tensorboard)
        theta0 = torch.as_tensor(sp.to_unconstrained(start, k0_ref, dy_ref))
        _progress.info(f"[gradient] {self.n_starts} starts, window {window[0] * meas.dt:.1f}-"
                       f"{window[1] * meas.dt:.1f} s, {self.epochs} search + {self.polish_epochs} polish epochs")
        theta, hist = self._adam(prob, theta0, k0_ref, dy_ref, int(self.epochs), self.lr, int(self.substeps),
                                 self.segment_s, tb, "search")
        last = hist[-1] if hist else self._evaluate(prob, theta, k0_ref, dy_ref, int(self.substeps), self.segment_s)
        self.start_losses_ = np.asarray(last)
        best = int(np.nanargmin(np.where(np.isfinite(last), last, np.inf))) if np.isfinite(last).any() else -1
        if best < 0:
            raise NotIdentifiableError("every start diverged; the record or the ranges do not suit this identifier",
                                       source=meas.source or None)
        theta_b, hist_b = self._adam(prob, theta[best:best + 1], k0_ref, dy_ref, int(self.polish_epochs),
                                     self.polish_lr, int(self.polish_substeps), self.polish_segment_s, tb, "polish")
        final = self._evaluate(prob, theta_b, k0_ref, dy_ref, int(self.polish_substeps), self.polish_segment_s)
        tb.close()
        values = sp.values_numpy(sp.from_unconstrained(theta_b, k0_ref, dy_ref))
        building = known.building({k: v[0] for k, v in values.items()})
        self.loss_history_ = [list(h) for h in hist] + [list(h) for h in hist_b]
        self.fit_seconds_ = time.perf_counter() - t0
        diagnostics = {"method": "gradient", "loss_final": float(final[0]), "best_start": best,
                       "start_losses": self.start_losses_.tolist(), "window_s": [window[0] * meas.dt,
                                                                                 window[1] * meas.dt]}
        provenance = {"identifier": repr(self), "source": meas.source, "seconds": self.fit_seconds_}
        self.clone_ = Clone(building=building, mass_normalised=known.mass_normalised, diagnostics=diagnostics,
                            provenance=provenance)
        return self

    def _evaluate(self, prob: _Problem, theta, k0_ref, dy_ref, substeps, segment_s) -> np.ndarray:
        starts, S = prob.segments(segment_s)
        with torch.no_grad():
            values = sp.from_unconstrained(theta, k0_ref, dy_ref)
            y0, ok = prob.start_states(sp.values_numpy(values), starts, substeps)
            loss = prob.losses(prob.accelerations(values, y0, starts, S, substeps)).numpy()
        return np.where(ok, loss, np.nan)

    def _adam(self, prob: _Problem, theta0, k0_ref, dy_ref, epochs: int, lr: float, substeps: int,
              segment_s: float, tb: TBLogger, stage: str):
        """Adam on every start at once (each start's loss only depends on its coordinates)."""
        theta = theta0.detach().clone().requires_grad_(True)
        if epochs == 0:
            return theta.detach(), []
        opt = torch.optim.Adam([theta], lr=lr)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs, eta_min=0.1 * lr)
        starts, S = prob.segments(segment_s)
        hist = []
        for epoch in range(epochs):
            values = sp.from_unconstrained(theta, k0_ref, dy_ref)
            y0, ok = prob.start_states(sp.values_numpy(values), starts, substeps)
            loss = prob.losses(prob.accelerations(values, y0, starts, S, substeps))
            loss = torch.where(torch.as_tensor(ok) & torch.isfinite(loss), loss, torch.zeros_like(loss))
            opt.zero_grad()
            loss.sum().backward()
            with torch.no_grad():
                theta.grad.nan_to_num_(0.0)
            lv = np.where(ok, loss.detach().numpy(), np.nan)
            hist.append(lv)
            opt.step()
            sched.step()
            with torch.no_grad():  # a diverged start restarts from the current best one, jittered
                bad = ~torch.as_tensor(ok)
                if bad.any() and ok.any():
                    b = int(np.nanargmin(lv))
                    theta[bad] = theta[b] + 0.05 * torch.randn_like(theta[bad])
            if np.isfinite(lv).any():
                tb.scalar(f"gradient/{stage}/best_loss", float(np.nanmin(lv)), epoch)
            if epoch % 10 == 0 or epoch == epochs - 1:
                _progress.debug(f"[gradient] {stage} epoch {epoch + 1}/{epochs}: best loss {np.nanmin(lv):.4g}")
        return theta.detach(), hist

    def _residuals_and_jacobian(self, prob: _Problem, theta, k0_ref, dy_ref, substeps, segment_s, carried):
        """Residuals ``(batch, N)``, their Jacobian ``(batch, N, P)`` in the unconstrained
        coordinates and ``(batch,)`` finite flags, by forward-mode AD with the ``P`` tangent
        directions as extra batch rows (one pass; the batch is nearly free in eager torch).

        ``carried`` ``(batch, P, segment, 4*story)`` are state sensitivities at the segment
        *ends* from the previous pass; they seed the next segment's start, so sensitivities
        cross segment boundaries one segment per pass (waveform relaxation) and become the
        full-trajectory Jacobian as the iterates settle. Returns the new ends too.
        """
        B, F, n = theta.shape
        P = F * n
        starts, S = prob.segments(segment_s)
        with torch.no_grad():
            values = sp.from_unconstrained(theta, k0_ref, dy_ref)
            y0, ok = prob.start_states(sp.values_numpy(values), starts, substeps)
            rep = theta.repeat_interleave(P, dim=0)
            tangent = torch.eye(P, dtype=theta.dtype).reshape(P, F, n).repeat(B, 1, 1)
            y0_tan = torch.nn.functional.pad(carried[:, :, :-1], (0, 0, 1, 0))  # (B, P, n_seg, 4n)
            with fwAD.dual_level():
                v = sp.from_unconstrained(fwAD.make_dual(rep, tangent), k0_ref, dy_ref)
                y0d = fwAD.make_dual(torch.as_tensor(np.repeat(y0, P, axis=0)), y0_tan.reshape(B * P, *y0.shape[1:]))
                acc, end = prob.accelerations(v, y0d, starts, S, substeps, with_end=True)
                r = prob.residuals(acc)
                primal, tan = fwAD.unpack_dual(r)
                end_tan = fwAD.unpack_dual(end).tangent
        r = primal.reshape(B, P, -1)[:, 0]
        J = tan.reshape(B, P, -1).transpose(1, 2)
        ends = end_tan.reshape(B, P, *end_tan.shape[1:])
        ok = ok & torch.isfinite(r).all(dim=1).numpy() & torch.isfinite(J).all(dim=(1, 2)).numpy()
        return r, J, ok, torch.nan_to_num(ends)

    def _levenberg_marquardt(self, prob: _Problem, theta0, k0_ref, dy_ref, iterations: int, substeps: int,
                             segment_s: float, tb: TBLogger, stage: str, tol: float = 1e-9):
        """Levenberg-Marquardt (Marquardt's diagonal scaling) on every start at once, with
        forward-mode Jacobians; a start stops when its loss changes by less than ``tol``
        (relative) twice in a row."""
        theta = theta0.detach().clone()
        B, F, n = theta.shape
        starts, _ = prob.segments(segment_s)
        carried = torch.zeros(B, F * n, len(starts), 4 * n, dtype=theta.dtype)
        r, J, ok, carried = self._residuals_and_jacobian(prob, theta, k0_ref, dy_ref, substeps, segment_s, carried)
        N = r.shape[1]
        inf = torch.full((B,), torch.inf, dtype=r.dtype)
        loss = torch.where(torch.as_tensor(ok), r.pow(2).mean(dim=1), inf)
        lam = torch.full((B,), 1e-3, dtype=r.dtype)
        quiet = torch.zeros(B, dtype=torch.long)
        hist = [loss.numpy().copy()]
        for it in range(iterations):
            active = torch.isfinite(loss) & (quiet < 2)
            if not active.any():
                break
            A = J.transpose(1, 2) @ J / N
            g = J.transpose(1, 2) @ r[..., None] / N
            D = torch.diag_embed(torch.diagonal(A, dim1=1, dim2=2).clamp_min(1e-12))
            delta = torch.linalg.solve(A + lam[:, None, None] * D, -g)[..., 0].clamp(-1.0, 1.0)
            delta[~active] = 0.0
            trial = theta + delta.reshape(theta.shape)
            r2, J2, ok2, carried = self._residuals_and_jacobian(prob, trial, k0_ref, dy_ref, substeps, segment_s,
                                                                carried)
            loss2 = torch.where(torch.as_tensor(ok2), r2.pow(2).mean(dim=1), inf)
            better = active & (loss2 < loss)
            change = torch.where(better, (loss - loss2) / loss.clamp_min(1e-300), torch.zeros_like(loss))
            quiet = torch.where(better & (change > tol), torch.zeros_like(quiet), quiet + active.long())
            theta[better], r[better], J[better], loss[better] = trial[better], r2[better], J2[better], loss2[better]
            lam = torch.where(better, lam / 3.0, lam * 4.0).clamp(1e-9, 1e9)
            hist.append(loss.numpy().copy())
            if torch.isfinite(loss).any():
                tb.scalar(f"gradient/{stage}/best_loss", float(loss[torch.isfinite(loss)].min()), it)
            _progress.debug(f"[gradient] {stage} iteration {it + 1}/{iterations}: losses {loss.numpy()}")
        return theta, hist
