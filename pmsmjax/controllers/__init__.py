"""Controllers: the controller interfaces, discrete PI, design rules, cascaded FOC and its blocks (MTPA, field
weakening)."""

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
from .field_weakening import VoltageFeedbackFieldWeakening
from .foc import FOC, FOCState
from .mtpa import MTPA, mtpa_id_from_iq, mtpa_id_from_magnitude
from .pi import clip_magnitude, clip_symmetric, pi_update, realisable_reference_tracking

__all__ = [
    "FOC",
    "FOCState",
    "MTPA",
    "VoltageFeedbackFieldWeakening",
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
    "mtpa_id_from_iq",
    "mtpa_id_from_magnitude",
    "pi_update",
    "realisable_reference_tracking",
    "speed_loop_active_damping",
]
