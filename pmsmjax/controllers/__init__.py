"""Controllers: the controller interfaces, discrete PI, design rules and cascaded FOC with its blocks."""

from .base import (
    AbstractController,
    AbstractCurrentController,
    AbstractDAxisReference,
    AbstractSpeedController,
    CurrentLoopContext,
)
from .design import (
    CurrentLoopGains,
    SpeedLoopGains,
    current_loop_imc,
    first_order_rise_time,
    speed_loop_active_damping,
)
from .foc import FOC, FOCState
from .pi import clip_magnitude, clip_symmetric, pi_update, realisable_reference_tracking

__all__ = [
    "FOC",
    "FOCState",
    "AbstractController",
    "AbstractCurrentController",
    "AbstractDAxisReference",
    "AbstractSpeedController",
    "CurrentLoopContext",
    "CurrentLoopGains",
    "SpeedLoopGains",
    "clip_magnitude",
    "clip_symmetric",
    "current_loop_imc",
    "first_order_rise_time",
    "pi_update",
    "realisable_reference_tracking",
    "speed_loop_active_damping",
]
