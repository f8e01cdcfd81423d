"""pmsmjax: a differentiable, batched simulator of permanent-magnet synchronous motor drives in JAX.

Quick start::

    import pmsmjax
    drive = pmsmjax.presets.book_drive()
    scenario = pmsmjax.presets.book_scenario()
    trace = pmsmjax.simulate(drive, scenario)
"""

from . import controllers, frames, inverters, logs, machines, metrics, presets, replay, scenarios
from .drive import Drive, DriveState, PeriodInputs
from .scenarios import Profile, Scenario, stack_scenarios
from .simulate import simulate
from .trace import Trace
from .validation import ParameterError

__version__ = "0.1.0"

__all__ = [
    "Drive",
    "DriveState",
    "ParameterError",
    "PeriodInputs",
    "Profile",
    "Scenario",
    "Trace",
    "controllers",
    "frames",
    "inverters",
    "logs",
    "machines",
    "metrics",
    "presets",
    "replay",
    "scenarios",
    "simulate",
    "stack_scenarios",
]
