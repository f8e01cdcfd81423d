"""Controllers: the controller interfaces, discrete PI, design rules and cascaded FOC with its blocks
(dq PI or proportional-resonant current loop)."""

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
from .pi import clip_magnitude, clip_symmetric, pi_update
from .pr import ProportionalResonant, ResonantCoefficients, pr_design, resonant_coefficients

__all__ = [
    "FOC",
    "FOCState",
    "AbstractController",
    "AbstractCurrentController",
    "AbstractDAxisReference",
    "AbstractSpeedController",
    "CurrentLoopContext",
    "CurrentLoopGains",
    "ProportionalResonant",
    "ResonantCoefficients",
    "SpeedLoopGains",
    "clip_magnitude",
    "clip_symmetric",
    "current_loop_imc",
    "first_order_rise_time",
    "pi_update",
    "pr_design",
    "resonant_coefficients",
    "speed_loop_active_damping",
]
