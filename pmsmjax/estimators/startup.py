"""Sensorless start from standstill: a current-controlled I/f start with hand-over to an observer
(the book, ch. 5, "start-up"; the I/f method of Fatu, Teodorescu, Boldea, Andreescu, Blaabjerg,
"I-F starting method with smooth transition to EMF based motion-sensorless vector control of PM
synchronous motor/generator", IEEE PESC 2008, doi:10.1109/PESC.2008.4592384).

A fundamental-model observer sees no back-EMF at standstill, so the drive starts open loop:

1. **I/f**: a reference frame turns with the ramp speed ``w_if(t) = min(accel t, w_h + w_b)`` (mechanical
   rad/s) and the controller holds the current ``i_dq* = (0, i_start)`` in that frame (current
   controlled, speed loop not in charge). The rotor follows: it settles at the load angle where
   ``1.5 p psi_f i_start cos(delta)`` balances load and inertia, so ``i_start`` must exceed the start-up
   torque over the torque constant with margin.
2. **Hand-over**: while ``w_if`` runs from the hand-over speed ``w_h`` to ``w_h + w_b`` the weight
   ``w = (w_if - w_h) / w_b`` blends linearly (a) the angle from the I/f angle to the observer's (along the
   shorter arc, so no jump of 2 pi), (b) the speed from ``w_if`` to the observer's, and (c) the current
   reference from the I/f current to the speed loop's output (in
   [`pmsmjax.controllers.FOC`][pmsmjax.controllers.foc.FOC], through
   ``Estimate.startup_weight``/``Estimate.startup_i_dq``). After that the observer is in charge.

The weight is a function of the ramp, i.e. of time only, so the sequence is continuous (no comparator)
and the whole start is differentiable w.r.t. every field. The observer runs from the first period on the
measured voltages and currents, so it has converged by the hand-over if ``w_h`` is high enough for its
back-EMF to be observable (about 10 % of rated speed for the book drive).
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import as_float
from pmsmjax.signals import Sample
from pmsmjax.spec.validation import check_positive


class StartupState(eqx.Module):
    observer: object  # the wrapped observer's state
    theta_if: Array  # rad, electrical angle of the I/f frame
    omega_if: Array  # rad/s, mechanical ramp speed


class StartupEstimator(AbstractEstimator):
    """I/f start-up around a sensorless observer (see the module docstring).

    **Arguments:**

    - `observer`: the observer that takes over (any
      [`AbstractEstimator`][pmsmjax.estimators.base.AbstractEstimator]).
    - `pole_pairs`: pole-pair number of the motor (I/f electrical angle = ``p`` times the mechanical ramp).
    - `i_start`: I/f current amplitude, A (on the I/f frame's q axis).
    - `accel`: ramp acceleration, mechanical rad/s^2.
    - `handover_speed`: mechanical speed where the blend to the observer starts, rad/s.
    - `blend_speed`: ramp-speed span of the blend, rad/s (the blend lasts ``blend_speed / accel`` s).
    """

    observer: AbstractEstimator
    pole_pairs: Array = eqx.field(converter=as_float)
    i_start: Array = eqx.field(converter=as_float)
    accel: Array = eqx.field(converter=as_float)
    handover_speed: Array = eqx.field(converter=as_float)
    blend_speed: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("StartupEstimator.pole_pairs", self.pole_pairs, "")
        check_positive("StartupEstimator.i_start (I/f current amplitude)", self.i_start, "A")
        check_positive("StartupEstimator.accel (I/f ramp acceleration)", self.accel, "rad/s^2")
        check_positive("StartupEstimator.handover_speed", self.handover_speed, "rad/s (mechanical)")
        check_positive("StartupEstimator.blend_speed", self.blend_speed, "rad/s (mechanical)")

    def check_period(self, Ts: float) -> None:
        self.observer.check_period(Ts)

    def init(self, sample: Sample) -> StartupState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        return StartupState(self.observer.init(sample), zero, zero)

    def weight(self, omega_if):
        """Observer weight in [0, 1] at ramp speed ``omega_if`` (mechanical rad/s)."""
        return jnp.clip((omega_if - self.handover_speed) / self.blend_speed, 0.0, 1.0)

    def step(self, state: StartupState, sample: Sample, Ts: float):
        obs_state, obs = self.observer.step(state.observer, sample, Ts)
        w = self.weight(state.omega_if)
        theta_if = state.theta_if
        # blend along the shorter arc: the I/f frame and the observer disagree by the load angle
        theta = wrap_angle(theta_if + w * wrap_angle(obs.theta_e - theta_if))
        omega = (1.0 - w) * state.omega_if + w * obs.omega_m
        i_dq_start = jnp.stack([jnp.zeros_like(self.i_start), self.i_start])
        omega_end = self.handover_speed + self.blend_speed
        omega_next = jnp.minimum(state.omega_if + self.accel * Ts, omega_end)
        # trapezoidal angle integration of the piecewise-linear ramp
        theta_next = wrap_angle(theta_if + self.pole_pairs * 0.5 * (state.omega_if + omega_next) * Ts)
        estimate = dataclasses.replace(
            obs, theta_e=theta, omega_m=omega, startup_weight=1.0 - w, startup_i_dq=i_dq_start
        )
        return StartupState(obs_state, theta_next, omega_next), estimate
