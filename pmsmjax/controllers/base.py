"""Controller interfaces: the third block of the drive's sampled-data step ([`pmsmjax.drive`][pmsmjax.drive]).

A drive's controller ([`AbstractController`][pmsmjax.controllers.base.AbstractController]) reads only the
[`Sample`][pmsmjax.signals.Sample], the estimator's [`Estimate`][pmsmjax.signals.Estimate] and the references,
and returns a [`ControlOutput`][pmsmjax.signals.ControlOutput]. Whether that output is a stator-frame voltage
(to the modulator) or leg switch states (to the bridge directly) is the class constant ``command_kind``, so
the drive step has no runtime branch.

The cascaded controllers are built from smaller blocks with their own small state, so a method of the
book is one block swapped into the same cascade:

- [`AbstractSpeedController`][pmsmjax.controllers.base.AbstractSpeedController]: speed error ->
  torque-producing current ``i_q*`` (PI with active damping, sliding mode);
- [`AbstractCurrentController`][pmsmjax.controllers.base.AbstractCurrentController]: dq current reference ->
  stator-frame voltage (dq PI with decoupling, proportional-resonant in alpha-beta);
- [`AbstractDAxisReference`][pmsmjax.controllers.base.AbstractDAxisReference]: the d-axis current reference
  (from the scenario, MTPA, field weakening).
"""

import abc
from typing import ClassVar, NamedTuple

import equinox as eqx

from pmsmjax._types import Array
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.signals import CommandKind, ControlOutput, Estimate, References, Sample


class AbstractController(eqx.Module):
    """A drive controller: ``init(dtype) -> state``; ``step(...) -> (state, ControlOutput)``.

    ``step(state, sample, estimate, refs, Ts, u_max, delayed)``: `Ts` the control period, s (static);
    `u_max` the modulator's linear voltage limit, V; `delayed` (static) whether the command is applied
    one period after it is computed. ``current_limit`` (A, peak phase current) is read by the metrics and
    objectives that judge a run. ``speed``: the speed loop
    ([`AbstractSpeedController`][pmsmjax.controllers.base.AbstractSpeedController], in charge in speed mode),
    whose state the controller's state holds as its ``speed`` field.
    """

    command_kind: ClassVar[CommandKind] = "voltage"
    current_limit: eqx.AbstractVar[Array]
    speed: eqx.AbstractVar["AbstractSpeedController"]

    @abc.abstractmethod
    def init(self, dtype):
        """The controller's state before the first period (integrators and memories at zero).

        `dtype`: the floating dtype of the state's arrays (the drive's, float32 or float64). Returns a
        pytree (the concrete controller's own state type) that
        [`step`][pmsmjax.controllers.base.AbstractController.step] takes and returns.
        """

    @abc.abstractmethod
    def step(
        self, state, sample: Sample, estimate: Estimate, refs: References, Ts: float, u_max, delayed: bool
    ) -> tuple[object, ControlOutput]:
        """One control period: the command to apply from the measurements and the estimate.

        `state`: as returned by [`init`][pmsmjax.controllers.base.AbstractController.init] or the last step;
        `sample`: the period-start measurements; `estimate`: the estimator's angle (rad) and speed (rad/s) for
        this period; `refs`: speed (mechanical rad/s) and current (A) references; `Ts`: control period, s
        (static); `u_max`: the modulator's linear voltage limit, V; `delayed` (static): the command is applied
        one period after it is computed (a computational delay). Returns the new state and the
        [`ControlOutput`][pmsmjax.signals.ControlOutput] (a ``(2,)`` V stator-frame voltage or ``(n,)`` switch
        states by ``command_kind``, with the dq voltage command and current reference).
        """


class AbstractSpeedController(eqx.Module):
    """Speed loop: ``step(state, speed_ref, omega_m, iq_max, Ts) -> (state, iq_ref)``.

    `speed_ref`, `omega_m`: mechanical rad/s; `iq_max`: the output limit, A (the current circle less the
    d-axis reference); `Ts`: the speed loop's own period, s. ``init(dtype)`` gives the zero state.
    """

    @abc.abstractmethod
    def init(self, dtype):
        """The speed loop's zero state (integrator, filter memories) with arrays of floating `dtype`."""

    @abc.abstractmethod
    def step(self, state, speed_ref, omega_m, iq_max, Ts) -> tuple[object, Array]:
        """One speed-loop period: the torque-producing current reference.

        `speed_ref`, `omega_m`: reference and estimated mechanical speed, rad/s; `iq_max`: the output's
        magnitude limit, A; `Ts`: the speed loop's period, s (a multiple of the control period). Returns
        the new state and ``i_q*`` (scalar, A, within ``[-iq_max, iq_max]``).
        """

    def steady_state(self, state, omega_m):
        """The loop's state in its no-load steady state at mechanical speed ``omega_m`` (rad/s), from its
        zero state ``state``: where a run started at speed begins. Here ``state`` unchanged; a loop whose
        feedforward needs an integral to balance it (the PI's active damping) overrides it."""
        return state


class CurrentLoopContext(NamedTuple):
    """What a current loop may use besides its own state (built inside the traced step).

    - `model`: the controller's motor model (may differ from the plant).
    - `Ts`: control period, s. `u_max`: voltage-vector limit, V.
    - `delayed`: the command acts one period after it is computed (static).
    - `u_dq_prev`: ``(2,)`` last period's voltage command in the rotor frame, V (applied during the
      coming period when delayed).
    - `decoupling`, `delay_compensation`: the cascade's options (static); a loop may ignore them.
    """

    model: PMSMParameters
    Ts: float
    u_max: Array
    delayed: bool
    u_dq_prev: Array
    decoupling: bool
    delay_compensation: bool


class AbstractCurrentController(eqx.Module):
    """Current loop: ``step(state, i_dq_ref, i_ab, theta_e, omega_e, ctx) -> (state, u_ab, u_dq)``.

    `i_dq_ref (2,)` A; `i_ab (2,)` measured stationary-frame currents, A; `theta_e` the estimated angle,
    rad; `omega_e` the estimated electrical speed, rad/s; `ctx` a
    [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext]. Returns the stator-frame voltage
    command ``u_ab (2,)`` V (with the angle lead that the PWM hold and the delay need) and the same command in
    the estimated rotor frame ``u_dq (2,)`` V.
    """

    @abc.abstractmethod
    def init(self, dtype):
        """The current loop's zero state (integrators, resonators, last command) of floating `dtype`."""

    @abc.abstractmethod
    def step(self, state, i_dq_ref, i_ab, theta_e, omega_e, ctx: CurrentLoopContext):
        """One current-loop period: the voltage command that drives ``i_ab`` to ``i_dq_ref``.

        `i_dq_ref`: ``(2,)`` dq current reference, A; `i_ab`: ``(2,)`` measured stationary-frame currents,
        A; `theta_e`: estimated electrical angle, rad; `omega_e`: estimated electrical speed, rad/s; `ctx`:
        the cascade's [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext]. Returns
        ``(state, u_ab (2,) V, u_dq (2,) V)``: the stationary-frame command (with the angle lead of the PWM
        hold and delay) and the same command in the estimated rotor frame, within ``ctx.u_max``.
        """


class AbstractDAxisReference(eqx.Module):
    """d-axis current reference, computed before the speed loop from last period's values.

    ``step(state, id_ref, iq_ref_prev, omega_e, ctx, current_limit) -> (state, id_ref)``:
    `id_ref` the scenario's reference, A; `iq_ref_prev` last period's ``i_q*``, A; `omega_e` electrical
    speed, rad/s; `ctx` a [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext] (last voltage
    command, limit); `current_limit` A. MTPA and field weakening use last period's ``i_q*``: one period of
    lag, far below the speed loop's bandwidth.
    """

    @abc.abstractmethod
    def init(self, dtype):
        """The block's zero state (a field-weakening integrator, or ``None``) of floating `dtype`."""

    @abc.abstractmethod
    def step(self, state, id_ref, iq_ref_prev, omega_e, ctx: CurrentLoopContext, current_limit):
        """One period: the d-axis current reference.

        `id_ref`: the scenario's d-axis reference, A; `iq_ref_prev`: last period's ``i_q*``, A; `omega_e`:
        estimated electrical speed, rad/s; `ctx`: the cascade's
        [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext]; `current_limit`: peak
        phase-current limit, A. Returns the new state and ``i_d*`` (scalar, A).
        """
