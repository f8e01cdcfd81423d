"""Speed PI with active damping (the book, ch. 3): ``i_q* = (Kp_w + Ki_w/s)(w* - w) - B_a w``.

Discrete, once per speed-loop period, with the output limited to ``+-iq_max`` and realisable-reference
anti-windup: back-calculation with tracking time constant ``T_t = Kp_w/Ki_w``
([`pmsmjax.controllers.pi.realisable_reference_tracking`][pmsmjax.controllers.pi.realisable_reference_tracking]).
With the active-damping term this is the 2DOF PI of Harnefors et al. (motulator's ``SpeedController``:
``k_t = Kp_w`` on the error, ``B_a`` on the speed alone, integral ``u_i += Ts (Ki_w/Kp_w)(i_q* - v)`` with
``v`` the output less ``k_t e``). Unsaturated, the anti-windup term is zero and the loop is exactly the linear
design ``beta/(s + beta)``.

Why not the per-period reset (tracking gain 1, the plain back-calculation of
[`pmsmjax.controllers.pi.pi_update`][pmsmjax.controllers.pi.pi_update]): it resets the integral to
``limit - Kp_w e + B_a w`` every period, so while the motor accelerates at the limit the next unsaturated
output is ``limit - (Kp_w + B_a) dw + Ts Ki_w e`` with ``dw`` the speed gained in one period. With the design
rule (``Kp_w ~ B_a ~ beta J/K_t``, ``dw ~ K_t I_max Ts/J``) this falls below the limit as soon as
``e < 2 I_max K_t/(beta J)``: 219 rad/s for the book drive, so a 1500 r/min (157 rad/s) step left the
15 A limit 1.3 ms after the step (11.7 A at 10 ms) and rose 10-90 % in 55 ms. Tracking with
``T_t = Kp_w/Ki_w`` = 1/beta keeps the integral from following the falling proportional and damping terms
period by period: the same step holds 15 A until the linear demand meets the limit
(tests/controllers/test_speed_loop_saturation.py).
"""

from typing import Literal

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractSpeedController
from pmsmjax.controllers.pi import clip_symmetric, pi_update, realisable_reference_tracking
from pmsmjax.controllers.speed_filters import SpeedLoopFilters
from pmsmjax.spec.validation import check_choice

AntiWindup = Literal["realisable_reference", "reset"]


class SpeedLoopGains(AbstractSpeedController):
    """Speed PI: ``kp`` A/(rad/s), ``ki`` A/rad, active damping ``B_a`` A/(rad/s). State: the integral, A.

    `anti_windup` (static): ``"realisable_reference"`` (default, tracking time constant ``kp/ki``) or
    ``"reset"`` (tracking gain 1 per period: the integral reset onto the limit each period; kept to
    reproduce the earlier behaviour and to compare).

    `filters`: a low-pass on the speed feedback and a notch on the output
    ([`SpeedLoopFilters`][pmsmjax.controllers.speed_filters.SpeedLoopFilters], for a compliant shaft); the
    state is then ``(integral, filter state)`` and the notched output is limited to ``+-iq_max`` again.
    None (default): no filters, the state the integral alone.
    """

    kp: Array
    ki: Array
    active_damping: Array
    anti_windup: AntiWindup = eqx.field(static=True, default="realisable_reference")
    filters: SpeedLoopFilters | None = None

    def __check_init__(self):
        check_choice("anti_windup", self.anti_windup, ("realisable_reference", "reset"))

    def init(self, dtype):
        if self.filters is None:
            return jnp.zeros((), dtype)
        return jnp.zeros((), dtype), self.filters.init(dtype)

    def step(self, state, speed_ref, omega_m, iq_max, Ts):
        if self.filters is None:
            return self._pi(state, speed_ref, omega_m, iq_max, Ts)
        integral, filter_state = state
        filter_state, omega_seen = self.filters.feedback(filter_state, omega_m, Ts)
        integral, i_ref = self._pi(integral, speed_ref, omega_seen, iq_max, Ts)
        filter_state, i_ref = self.filters.reference(filter_state, i_ref, Ts)
        return (integral, filter_state), jnp.clip(i_ref, -iq_max, iq_max)

    def _pi(self, state, speed_ref, omega_m, iq_max, Ts):
        return pi_update(
            self.kp,
            self.ki,
            state,
            speed_ref - omega_m,
            Ts,
            clip_symmetric(iq_max),
            feedforward=-self.active_damping * omega_m,
            tracking=(
                realisable_reference_tracking(self.kp, self.ki, Ts)
                if self.anti_windup == "realisable_reference"
                else 1.0
            ),
        )

    def steady_state(self, state, omega_m):
        """The integral holding the active-damping term ``B_a w`` (A): its no-load steady state at ``omega_m``
        (rad/s). From a zero integral the damping term alone would brake a machine started at speed."""
        if self.filters is None:
            return jnp.asarray(self.active_damping * omega_m, state.dtype)
        integral, filter_state = state
        held = jnp.asarray(self.active_damping * omega_m, integral.dtype)
        return held, self.filters.steady_state(filter_state, omega_m)


__all__ = ["SpeedLoopGains"]
