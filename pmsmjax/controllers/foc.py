"""Cascaded field-oriented control: d-axis reference -> speed loop -> current loop (the book, ch. 3).

Sampled-data, once per control period ``Ts``, on the estimator's angle and speed:

1. the d-axis reference: the scenario's ``i_d*`` (i_d = 0 control by default), or a
   [`AbstractDAxisReference`][pmsmjax.controllers.base.AbstractDAxisReference] block (MTPA, field weakening)
   working from last period's ``i_q*`` and voltage;
2. the speed loop ([`AbstractSpeedController`][pmsmjax.controllers.base.AbstractSpeedController]: the PI with
   active damping of [`speed_pi`][pmsmjax.controllers.speed_pi] by default, or sliding mode), every
   ``speed_divider`` periods with period ``speed_divider * Ts``, its output limited so that ``|i_dq*|`` stays
   inside ``current_limit``; in ``mode="current"`` the scenario's ``i_q*`` instead;
3. the current loop ([`AbstractCurrentController`][pmsmjax.controllers.base.AbstractCurrentController]: the dq
   PIs with decoupling and delay compensation of [`current_pi`][pmsmjax.controllers.current_pi] by default, or
   proportional-resonant in alpha-beta), limited to the modulator's linear range;
4. optionally, anticogging ([`anticogging`][pmsmjax.controllers.anticogging], not in the book): a q current
   over the rotor angle added to the current reference after the speed loop;
5. optionally, dead-time compensation ([`dead_time_compensation`][pmsmjax.controllers.dead_time_compensation],
   not in the book): the inverter's predicted voltage error added back to the command.
"""

from typing import Literal

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.anticogging import AnticoggingTable
from pmsmjax.controllers.base import (
    AbstractCurrentController,
    AbstractDAxisReference,
    AbstractSpeedController,
    CurrentLoopContext,
)
from pmsmjax.controllers.dead_time_compensation import DeadTimeCompensation
from pmsmjax.controllers.speed_cascade import AbstractSpeedCascade
from pmsmjax.frames.three_phase import park
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import ControlOutput, Estimate, References, Sample

ControlMode = Literal["speed", "current"]


class FOCState(eqx.Module):
    speed: object  # the speed block's state
    current: object  # the current block's state
    d_axis: object  # the d-axis reference block's state (None without one)
    u_dq_prev: Array  # (2,) V, last command (applied during the coming period when delayed)
    iq_ref: Array  # A, held between speed-loop updates
    counter: Array  # int32, periods since the last speed-loop update


class AbstractFOC(AbstractSpeedCascade):
    """The fields, state and current-loop context of a cascaded FOC, three-phase
    ([`FOC`][pmsmjax.controllers.foc.FOC]) or multi-phase
    ([`MultiPhaseFOC`][pmsmjax.controllers.multiphase.MultiPhaseFOC]); the arguments are
    [`FOC`][pmsmjax.controllers.foc.FOC]'s but ``dead_time_compensation``. A subclass gives the ``current``
    block's type; ``step`` runs the cascade (d-axis reference, speed loop, current loop) on the currents
    of ``measured_currents``, and ``corrected_command`` may add to the current loop's command.
    """

    model: PMSMParameters
    speed: AbstractSpeedController
    current: eqx.Module  # the current block; a subclass names its type
    current_limit: Array = eqx.field(converter=as_float)
    d_axis: AbstractDAxisReference | None = None
    mode: ControlMode = eqx.field(static=True, default="speed")
    speed_divider: int = eqx.field(static=True, default=1)
    decoupling: bool = eqx.field(static=True, default=True)
    delay_compensation: bool = eqx.field(static=True, default=True)

    def init(self, dtype=None) -> FOCState:
        dtype = self.state_dtype(dtype)
        d_axis = None if self.d_axis is None else self.d_axis.init(dtype)
        return FOCState(
            self.speed.init(dtype),
            self.current.init(dtype),
            d_axis,
            jnp.zeros(2, dtype),
            jnp.zeros((), dtype),
            jnp.zeros((), jnp.int32),
        )

    def context(self, state: FOCState, Ts, u_max, delayed) -> CurrentLoopContext:
        """The current loop's [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext] for this
        period."""
        return CurrentLoopContext(
            self.model, Ts, u_max, delayed, state.u_dq_prev, self.decoupling, self.delay_compensation
        )

    def measured_currents(self, sample: Sample) -> Array:
        """The measured currents the ``current`` block takes: the stator-frame ``sample.i_ab`` (2,) A here;
        the multi-phase cascade's block takes the ``(n,)`` phase currents."""
        return sample.i_ab

    def corrected_command(
        self, u, i_dq_ref, sample: Sample, estimate: Estimate, omega_e, Ts, delayed
    ) -> Array:
        """The current block's command ``u`` (V) as applied: here unchanged (FOC adds its dead-time
        compensation)."""
        return u

    def feed_forward(self, i_dq_ref, estimate: Estimate) -> Array:
        """The current reference ``i_dq_ref`` ((2,) A) the current block follows: here unchanged (FOC adds
        its anticogging current)."""
        return i_dq_ref

    def step(
        self, state: FOCState, sample: Sample, estimate: Estimate, refs: References, Ts, u_max, delayed
    ) -> tuple[FOCState, ControlOutput]:
        omega_e = self.model.pole_pairs * estimate.omega_m
        ctx = self.context(state, Ts, u_max, delayed)
        speed_state, d_axis_state, iq_ref, counter, i_dq_ref = cascade_references(
            self, state, estimate, refs, ctx
        )
        i_dq_ref = self.feed_forward(i_dq_ref, estimate)
        current_state, u, u_dq = self.current.step(
            state.current, i_dq_ref, self.measured_currents(sample), estimate.theta_e, omega_e, ctx
        )
        u = self.corrected_command(u, i_dq_ref, sample, estimate, omega_e, Ts, delayed)
        new_state = FOCState(speed_state, current_state, d_axis_state, u_dq, iq_ref, counter)
        return new_state, ControlOutput(u, u_dq, i_dq_ref)


class FOC(AbstractFOC):
    """Cascaded field-oriented controller (i_d = 0 by default).

    **Arguments:**

    - `model`: the controller's motor model (decoupling, prediction, MTPA); may differ from the plant.
    - `speed`: the speed block, e.g. [`SpeedLoopGains`][pmsmjax.controllers.speed_pi.SpeedLoopGains] (kp
      A/(rad/s), ki A/rad, active damping A/(rad/s)) or a sliding-mode speed controller.
    - `current`: the current block, e.g. [`CurrentLoopGains`][pmsmjax.controllers.current_pi.CurrentLoopGains]
      (kp V/A, ki V/(A s) per axis) or a proportional-resonant controller.
    - `current_limit`: peak phase-current limit, A (|i_dq*| is kept inside this circle).
    - `d_axis`: a d-axis reference block (MTPA, field weakening); ``None`` takes the scenario's ``i_d*``.
    - `mode`: ``"speed"`` (cascade) or ``"current"`` (current references come from the scenario).
    - `speed_divider`: the speed loop runs every this many control periods.
    - `decoupling`: apply the dq decoupling feed-forward (dq PI current loop).
    - `delay_compensation`: with a computational delay, run the current loop on the current predicted
      for the next sampling instant (see [`current_pi`][pmsmjax.controllers.current_pi]).
    - `dead_time_compensation`: a
      [`DeadTimeCompensation`][pmsmjax.controllers.dead_time_compensation.DeadTimeCompensation] with the
      controller's estimate of the inverter's dead time and device drop, its voltage added to the current
      loop's command (which the loop's own state, ``u_dq_prev``, does not include: it is the voltage the
      machine should see); ``None`` (default, as in the book): none.
    - `anticogging`: an [`AnticoggingTable`][pmsmjax.controllers.anticogging.AnticoggingTable], its q
      current at the estimated angle added to the current reference after the speed loop; ``None``
      (default): none.
    """

    current: AbstractCurrentController
    dead_time_compensation: DeadTimeCompensation | None = None
    anticogging: AnticoggingTable | None = None

    def feed_forward(self, i_dq_ref, estimate: Estimate) -> Array:
        """``i_dq_ref`` ((2,) A) plus the anticogging q current at the estimated angle, if any."""
        if self.anticogging is None:
            return i_dq_ref
        return i_dq_ref.at[1].add(self.anticogging.current(estimate.theta_e))

    def corrected_command(
        self, u, i_dq_ref, sample: Sample, estimate: Estimate, omega_e, Ts, delayed
    ) -> Array:
        """The current loop's stator-frame command ``u`` (V) plus the dead-time compensation's voltage, if
        any."""
        if self.dead_time_compensation is None:
            return u
        return u + self.dead_time_compensation.voltage_ab(
            i_dq_ref, park(sample.i_ab, estimate.theta_e), estimate.theta_e, omega_e, sample.u_dc, Ts, delayed
        )


def cascade_references(controller, state: FOCState, estimate: Estimate, refs: References, ctx):
    """Steps 1-2 of the cascade (d-axis reference, speed loop) of ``controller`` (a
    [`FOC`][pmsmjax.controllers.foc.FOC], or an
    [`AbstractSpeedCascade`][pmsmjax.controllers.speed_cascade.AbstractSpeedCascade] with a ``model`` and a
    ``d_axis`` and a state with `FOCState`'s ``speed``, ``d_axis``, ``iq_ref`` and ``counter``, such as the
    multi-phase
    [`pmsmjax.controllers.multiphase.MultiPhaseFOC`][pmsmjax.controllers.multiphase.MultiPhaseFOC] and
    [`pmsmjax.controllers.hysteresis.HysteresisCurrentControl`][pmsmjax.controllers.hysteresis.HysteresisCurrentControl]).

    During a sensorless start (``estimate.startup_weight`` set) the start-up current is blended in.

    **Returns:** ``(speed_state, d_axis_state, iq_ref, counter, i_dq_ref (2,) A)``.
    """
    c = controller
    omega_e = c.model.pole_pairs * estimate.omega_m
    Ts = ctx.Ts
    d_axis_state, id_ref = state.d_axis, refs.id_ref
    if c.d_axis is not None:
        d_axis_state, id_ref = c.d_axis.step(
            state.d_axis, id_ref, state.iq_ref, omega_e, ctx, c.current_limit
        )
    id_ref = jnp.clip(id_ref, -c.current_limit, c.current_limit)
    iq_max_sq = c.current_limit**2 - id_ref**2
    iq_max = jnp.sqrt(jnp.where(iq_max_sq > 0, iq_max_sq, 1.0)) * (iq_max_sq > 0)

    if c.mode == "speed":
        speed_state, iq_ref, counter = c.held_speed_step(
            state, state.iq_ref, refs.speed_ref, estimate.omega_m, iq_max, Ts
        )
    else:
        speed_state, counter = state.speed, state.counter
        iq_ref = jnp.clip(refs.iq_ref, -iq_max, iq_max)
    # the speed loop's break point (a loop-response measurement): after the speed controller and its
    # held state, before the current loop
    perturbed = iq_ref if refs.iq_ref_perturbation is None else iq_ref + refs.iq_ref_perturbation
    i_dq_ref = jnp.stack([id_ref, perturbed])
    if estimate.startup_weight is not None:
        # sensorless start (I/f): the start-up block holds the current, then hands over smoothly
        w = estimate.startup_weight
        i_dq_ref = w * estimate.startup_i_dq + (1.0 - w) * i_dq_ref
    return speed_state, d_axis_state, iq_ref, counter, i_dq_ref
