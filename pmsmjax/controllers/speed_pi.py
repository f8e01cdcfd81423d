"""Speed PI with active damping (BOOK.md chapter 3): ``i_q* = (Kp_w + Ki_w/s)(w* - w) - B_a w``.

Discrete, once per speed-loop period, with the output limited to ``+-iq_max`` and back-calculation
anti-windup (:func:`pmsmjax.controllers.pi.pi_update`). Gains from
:func:`pmsmjax.controllers.design.speed_loop_active_damping`.
"""

import jax.numpy as jnp

from .._types import Array
from .base import AbstractSpeedController
from .pi import clip_symmetric, pi_update


class SpeedLoopGains(AbstractSpeedController):
    """Speed PI: ``kp`` A/(rad/s), ``ki`` A/rad, active damping ``B_a`` A/(rad/s). State: the integral, A."""

    kp: Array
    ki: Array
    active_damping: Array

    def init(self, dtype):
        return jnp.zeros((), dtype)

    def step(self, state, speed_ref, omega_m, iq_max, Ts):
        return pi_update(
            self.kp,
            self.ki,
            state,
            speed_ref - omega_m,
            Ts,
            clip_symmetric(iq_max),
            feedforward=-self.active_damping * omega_m,
        )


__all__ = ["SpeedLoopGains"]
