"""The speed-loop part every cascaded controller shares: its checks, its held update, its default design.

A speed cascade ([`AbstractSpeedCascade`][pmsmjax.controllers.speed_cascade.AbstractSpeedCascade]: FOC, the
multi-phase FOC, hysteresis current control, the two DTCs) carries a speed block ``speed``
([`AbstractSpeedController`][pmsmjax.controllers.base.AbstractSpeedController]), a peak phase-current limit
``current_limit`` (A), a static ``mode`` (``"speed"``, the cascade, or the mode in which the scenario's
references drive the inner loop) and a static ``speed_divider``: in speed mode the speed block runs every
``speed_divider`` periods with period ``speed_divider * Ts`` and its output is held in between
([`held_speed_step`][pmsmjax.controllers.speed_cascade.AbstractSpeedCascade.held_speed_step]). The
controller's state has the speed block's state as ``speed`` and the periods since its last update as
``counter`` (int32).

[`AbstractDesignedSpeedCascade`][pmsmjax.controllers.speed_cascade.AbstractDesignedSpeedCascade] holds those
fields (and the controller's ``model``) for the controllers whose constructor designs the default speed block
(the PI with active damping at ``speed_bandwidth`` rad/s) when none is given.
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractController, AbstractSpeedController
from pmsmjax.controllers.design import speed_loop_active_damping
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.spec.validation import check_choice, check_divider, check_positive

__all__ = ["AbstractDesignedSpeedCascade", "AbstractSpeedCascade"]


class AbstractSpeedCascade(AbstractController):
    """A controller with a speed loop run every ``speed_divider`` periods (module docstring).

    Its fields ``speed``, ``current_limit`` (A), ``mode`` (static) and ``speed_divider`` (static) are
    checked here: the limit > 0, the mode one of ``modes``, the divider an int >= 1 (counted in
    ``divider_unit``).
    """

    mode: eqx.AbstractVar[str]
    speed_divider: eqx.AbstractVar[int]
    #: The allowed ``mode`` values: the cascade (``"speed"``) first, then the one fed by the scenario.
    modes: ClassVar[tuple[str, ...]] = ("speed", "current")
    #: What one ``speed_divider`` step counts, in the error message ("control periods").
    divider_unit: ClassVar[str] = "control periods"

    def __check_init__(self):
        check_positive(f"{type(self).__name__}.current_limit", self.current_limit, "A")
        check_choice("mode", self.mode, self.modes)
        check_divider("speed_divider", self.speed_divider, self.divider_unit)

    def state_dtype(self, dtype=None):
        """The state's floating dtype: ``dtype``, or that of ``current_limit`` when ``None``."""
        return self.current_limit.dtype if dtype is None else dtype

    def held_speed_step(self, state, held: Array, speed_ref, omega_m, limit, Ts, gain=None):
        """The speed block's step every ``speed_divider`` periods, its output held in between.

        Args:
            state: The controller's state (its ``speed`` and ``counter``).
            held: The output held since the last update (the state's reference), units of the output.
            speed_ref: Mechanical speed reference, rad/s.
            omega_m: Estimated mechanical speed, rad/s.
            limit: The speed block's output limit, A.
            Ts: Control period, s (static); the speed block runs with ``speed_divider * Ts``.
            gain: ``None``, or a factor the block's output is scaled by (``K_t``, N m/A: a torque).

        Returns:
            ``(speed state, output, counter)``: the new speed-block state, the output (the block's, times
            ``gain``) and the new counter.
        """
        new_speed_state, out = self.speed.step(
            state.speed, speed_ref, omega_m, limit, Ts * self.speed_divider
        )
        if gain is not None:
            out = gain * out
        if self.speed_divider == 1:
            return new_speed_state, out, state.counter
        update = state.counter == 0
        speed_state = jax.tree.map(lambda a, b: jnp.where(update, a, b), new_speed_state, state.speed)
        return speed_state, jnp.where(update, out, held), (state.counter + 1) % self.speed_divider


class AbstractDesignedSpeedCascade(AbstractSpeedCascade):
    """A speed cascade that holds the speed-loop fields and designs its default speed block.

    Args:
        model: The controller's motor model (the default speed design among others).
        current_limit: Peak phase-current limit, A.
        speed: The speed block; ``None`` takes the PI with active damping of
            [`speed_loop_active_damping`][pmsmjax.controllers.design.speed_loop_active_damping] for
            ``model`` at ``speed_bandwidth``.
        mode: ``"speed"`` (cascade) or the controller's other mode (static).
        speed_divider: The speed loop runs every this many periods (static).
        speed_bandwidth: rad/s, only to design the default speed block.
    """

    model: PMSMParameters
    speed: AbstractSpeedController
    current_limit: Array
    mode: str = eqx.field(static=True)
    speed_divider: int = eqx.field(static=True)

    def __init__(
        self, model: PMSMParameters, current_limit, speed, mode: str, speed_divider: int, speed_bandwidth
    ):
        self.model = model
        self.speed = speed_loop_active_damping(model, speed_bandwidth) if speed is None else speed
        self.current_limit = as_float(current_limit)
        self.mode = mode
        self.speed_divider = speed_divider
