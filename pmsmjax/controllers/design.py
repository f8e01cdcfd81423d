"""Design rules for the FOC loops, as functions of the motor parameters (the book, ch. 3).

- Current loop, internal-model design with decoupling feed-forward: ``Kp_d = a_c L_d``,
  ``Kp_q = a_c L_q``, ``Ki = a_c R``. The PI zero cancels the winding pole ``R/L``, leaving the closed
  loop ``a_c/(s + a_c)``: 10-90 % rise time ``ln 9 / a_c``.
- Speed loop with active damping: ``i_q* = (Kp_w + Ki_w/s)(w* - w) - B_a w`` with
  ``Kp_w = beta J / K_t``, ``Ki_w = beta Kp_w``, ``B_a = (beta J - B)/K_t``, ``K_t = 1.5 p_n psi_f``.
  With an ideal current loop the speed closed loop is ``beta/(s + beta)``.
"""

import math

import jax.numpy as jnp

from pmsmjax.controllers.current_pi import CurrentLoopGains
from pmsmjax.controllers.speed_pi import SpeedLoopGains
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.spec.validation import check_positive

__all__ = [
    "CurrentLoopGains",
    "SpeedLoopGains",
    "current_loop_imc",
    "first_order_rise_time",
    "speed_loop_active_damping",
]


def current_loop_imc(motor: PMSMParameters, bandwidth_rad_s=1100.0) -> CurrentLoopGains:
    """Internal-model current PI gains for closed-loop bandwidth ``a_c`` (rad/s)."""
    check_positive("current-loop bandwidth a_c", bandwidth_rad_s, "rad/s")
    a_c = jnp.asarray(bandwidth_rad_s, motor.R.dtype)
    return CurrentLoopGains(a_c * motor.L_d, a_c * motor.L_q, a_c * motor.R, a_c * motor.R)


def speed_loop_active_damping(
    motor: PMSMParameters, bandwidth_rad_s=50.0, anti_windup: str = "realisable_reference"
) -> SpeedLoopGains:
    """Speed PI with active damping for closed-loop bandwidth ``beta`` (rad/s).

    `anti_windup`: see [`SpeedLoopGains`][pmsmjax.controllers.speed_pi.SpeedLoopGains] (it acts only while the
    output is limited).
    """
    check_positive("speed-loop bandwidth beta", bandwidth_rad_s, "rad/s")
    beta = jnp.asarray(bandwidth_rad_s, motor.R.dtype)
    k_t = motor.torque_constant
    kp = beta * motor.J / k_t
    return SpeedLoopGains(kp, beta * kp, (beta * motor.J - motor.B) / k_t, anti_windup)


def first_order_rise_time(bandwidth_rad_s) -> float:
    """10-90 % rise time (s) of ``a/(s + a)``: ``ln 9 / a``."""
    return math.log(9.0) / float(bandwidth_rad_s)
