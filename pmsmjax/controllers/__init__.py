"""Controllers: discrete PI, design rules and cascaded FOC."""

from .design import (
    CurrentLoopGains,
    SpeedLoopGains,
    current_loop_imc,
    first_order_rise_time,
    speed_loop_active_damping,
)
from .foc import FOC, FOCOutput, FOCState, Measurement, References
from .pi import clip_magnitude, clip_symmetric, pi_update

__all__ = [
    "FOC",
    "FOCOutput",
    "FOCState",
    "CurrentLoopGains",
    "Measurement",
    "References",
    "SpeedLoopGains",
    "clip_magnitude",
    "clip_symmetric",
    "current_loop_imc",
    "first_order_rise_time",
    "pi_update",
    "speed_loop_active_damping",
]
