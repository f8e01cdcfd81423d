"""Controllers: the controller interfaces, discrete PI, design rules, cascaded FOC with its blocks (PI and
sliding-mode speed loops; dq PI or proportional-resonant current loops; MTPA and field weakening), and
hysteresis current control; switching-table and sliding-mode direct torque control; the six- and
five-phase cascade (VSD, double dq, PR current loops)."""

from pmsmjax.controllers.base import (
    AbstractController,
    AbstractCurrentController,
    AbstractDAxisReference,
    AbstractSpeedController,
    CurrentLoopContext,
)
from pmsmjax.controllers.design import (
    CurrentLoopGains,
    SpeedLoopGains,
    current_loop_imc,
    first_order_rise_time,
    speed_loop_active_damping,
)
from pmsmjax.controllers.dtc import SwitchingTableDTC, torque_current_limit
from pmsmjax.controllers.field_weakening import VoltageFeedbackFieldWeakening
from pmsmjax.controllers.foc import FOC, FOCState
from pmsmjax.controllers.hysteresis import HysteresisCurrentControl, HysteresisState, hysteresis_comparator
from pmsmjax.controllers.mtpa import MTPA, mtpa_id_from_iq, mtpa_id_from_magnitude
from pmsmjax.controllers.multiphase import (
    DoubleDQCurrentPI,
    MultiPhaseFOC,
    VSDCurrentControl,
    ZCurrentPI,
    ZProportionalResonant,
    double_dq_design,
    pr_current_design,
    vsd_current_design,
    z_current_imc,
    z_pr_design,
)
from pmsmjax.controllers.pi import clip_magnitude, clip_symmetric, pi_update, realisable_reference_tracking
from pmsmjax.controllers.pr import (
    ProportionalResonant,
    ResonantCoefficients,
    pr_design,
    resonant_coefficients,
)
from pmsmjax.controllers.smc import SlidingModeSpeed, SlidingModeState, smc_design, switching_function
from pmsmjax.controllers.smc_dtc import SlidingModeDTC, smc_dtc_design

__all__ = [
    "FOC",
    "FOCState",
    "HysteresisCurrentControl",
    "HysteresisState",
    "MTPA",
    "VoltageFeedbackFieldWeakening",
    "AbstractController",
    "AbstractCurrentController",
    "AbstractDAxisReference",
    "AbstractSpeedController",
    "CurrentLoopContext",
    "CurrentLoopGains",
    "SlidingModeSpeed",
    "SlidingModeState",
    "ProportionalResonant",
    "ResonantCoefficients",
    "SpeedLoopGains",
    "clip_magnitude",
    "clip_symmetric",
    "current_loop_imc",
    "first_order_rise_time",
    "hysteresis_comparator",
    "mtpa_id_from_iq",
    "mtpa_id_from_magnitude",
    "pi_update",
    "realisable_reference_tracking",
    "smc_design",
    "pr_design",
    "resonant_coefficients",
    "speed_loop_active_damping",
    "switching_function",
    "SwitchingTableDTC",
    "SlidingModeDTC",
    "smc_dtc_design",
    "torque_current_limit",
    "DoubleDQCurrentPI",
    "MultiPhaseFOC",
    "VSDCurrentControl",
    "ZCurrentPI",
    "ZProportionalResonant",
    "double_dq_design",
    "pr_current_design",
    "vsd_current_design",
    "z_current_imc",
    "z_pr_design",
]
