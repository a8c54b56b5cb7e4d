"""Simulated measurements (docs/DESIGN.md section 4): the building's response at the measurement
rate, with white Gaussian noise of ``noise_rms`` x channel RMS added to every channel."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import InputError
from .measurement import Measurement, Truth
from .model import Building
from .model.state import BuildingState, at_rest, settle_time
from .motions import GroundMotion
from .simulate import simulate_response
from .specs import MeasurementSpec, SimulationConfig, load_simulation_config


def add_noise(x: np.ndarray, noise_rms: float, rng: np.random.Generator) -> np.ndarray:
    """``x`` plus white Gaussian noise with std ``noise_rms * RMS`` of each channel (column)."""
    x = np.asarray(x, dtype=np.float64)
    rms = np.sqrt(np.mean(x**2, axis=0))
    return x + rng.standard_normal(x.shape) * (noise_rms * rms)


def simulate_measurement(building: Building, motion: GroundMotion, *, rate_hz: float | None = 200.0,
                         noise_rms: float = 0.10, seed: int | None = 0, substeps: int = 4,
                         y0: np.ndarray | None = None) -> Measurement:
    """Simulate what accelerometers on the ground and every floor would record.

    Parameters
    ----------
    building : the structure (its parameters become the measurement's truth)
    motion : ground acceleration [mm/s^2]; resampled to ``rate_hz`` first (None keeps its rate)
    noise_rms : noise std as a fraction of each channel's RMS (0.10 is the paper's 10 %)
    seed : seed of the noise generator
    substeps : RK4 sub-steps per sample
    y0 : ``(4*story,)`` the state the building starts in (:meth:`BuildingState.vector
        <hlaid.model.state.BuildingState.vector>`; None: at rest)

    Returns
    -------
    Measurement with noisy ``ground_acc`` and ``floor_acc`` and the noise-free truth.
    """
    if noise_rms < 0:
        raise InputError(f"noise_rms = {noise_rms}; expected >= 0")
    gm = motion.resampled(rate_hz) if rate_hz else motion
    r = simulate_response(building, gm, substeps=substeps, y0=y0)
    if r.status[0] != 0:
        raise InputError(f"the simulation diverged under {motion.name or motion.source}")
    assert (r.disp is not None and r.drift is not None and r.force is not None and r.z is not None
            and r.eta is not None and r.acc is not None)  # simulate keeps the histories by default
    rng = np.random.default_rng(seed)
    truth = Truth(building=building, disp=r.disp[0], drift=r.drift[0], force=r.force[0], z=r.z[0], eta=r.eta[0])
    ground = add_noise(gm.acc[:, None], noise_rms, rng)[:, 0]
    floors = add_noise(r.acc[0], noise_rms, rng)
    return Measurement(dt=gm.dt, ground_acc=ground, floor_acc=floors, mass=np.array(building.mass),
                       height=None if building.height is None else np.array(building.height),
                       pdelta=building.pdelta_active, truth=truth, noise_rms=noise_rms,
                       name=f"{building.name or 'building'}-{gm.name}", source=f"simulated:{gm.name}")


def simulate_events(building: Building, motions: Sequence[GroundMotion], *, rate_hz: float | None = 200.0,
                    noise_rms: float = 0.10, seed: int = 0, substeps: int = 4
                    ) -> tuple[list[Measurement], list[BuildingState]]:
    """Records of one building's successive earthquakes: each event starts in the state the
    previous one left the building in, once it came to rest (:func:`~hlaid.model.state.settle_time`
    of free vibration).

    Returns the measurements (noise seeds ``seed, seed + 1, ...``) and the true state after each.
    """
    meas: list[Measurement] = []
    states: list[BuildingState] = []
    y0 = None
    tail = settle_time(building)
    n = building.n_stories
    for k, motion in enumerate(motions):
        m = simulate_measurement(building, motion, rate_hz=rate_hz, noise_rms=noise_rms, seed=seed + k,
                                 substeps=substeps, y0=y0)
        gm = motion.resampled(rate_hz) if rate_hz else motion
        r = simulate_response(building, gm, substeps=substeps, y0=y0, free_vibration=tail, outputs="peaks")
        y0 = at_rest(r.final_state[0], n)
        meas.append(dataclasses.replace(m, name=f"event{k + 1}-{motion.name}"))
        states.append(BuildingState.from_vector(y0, events=tuple(x.name for x in meas)))
    return meas, states


def measurement_from_config(cfg: SimulationConfig, *, base_dir: str | Path | None = None,
                            seed: int | None = None, source: str | None = None) -> Measurement:
    """Run the simulation a :class:`SimulationConfig` describes."""
    building = cfg.building.build(source=source)
    motion = cfg.motion.load(base_dir)
    m = cfg.measurement
    return simulate_measurement(building, motion, rate_hz=m.rate_hz, noise_rms=m.noise_rms,
                                seed=cfg.seed if seed is None else seed, substeps=m.substeps)


__all__ = ["add_noise", "simulate_measurement", "simulate_events", "measurement_from_config", "MeasurementSpec",
           "SimulationConfig", "load_simulation_config"]
