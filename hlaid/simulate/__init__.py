"""Simulation: the compiled batch simulator, the story law along a drift path, torchdiffeq replay."""

from .batch import BACKENDS, HISTORY_FIELDS, STATUS, SimulationResult, simulate_response
from .odeint import SOLVERS, integrate_module, replay, replay_module
from .path import PathResponse, drive_story

__all__ = ["simulate_response", "SimulationResult", "BACKENDS", "HISTORY_FIELDS", "STATUS", "replay", "replay_module",
           "integrate_module", "SOLVERS", "drive_story", "PathResponse"]
