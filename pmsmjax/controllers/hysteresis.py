"""Hysteresis (bang-bang) current control with a speed loop (the book, ch. 3).

Per comparator sample (the drive's period ``Ts``, typically 5-20 us), on the estimator's angle:

1. the d-axis reference: the scenario's ``i_d*`` (i_d = 0 control) or an
   [`AbstractDAxisReference`][pmsmjax.controllers.base.AbstractDAxisReference] block;
2. the speed loop ([`AbstractSpeedController`][pmsmjax.controllers.base.AbstractSpeedController], the PI with
   active damping by default) every ``speed_divider`` samples, with period ``speed_divider * Ts`` (10 with a
   10 us sample gives the book's 10 kHz speed loop), its output limited to the current circle; in
   ``mode="current"`` the scenario's ``i_q*``;
3. the reference phase currents ``i_abc* = dq_to_abc(i_dq*, theta_e_est)`` and, per phase ``x``, the
   error ``e_x = i_x* - i_x`` on the sampled currents and the comparator with full band ``h``::

       s_x = 1        if e_x >  h/2
       s_x = 0        if e_x < -h/2
       s_x = s_x,prev otherwise (hold)

   The previous switch states are the controller's state, so the hold is exact. The switch states go to
   the bridge directly (``command_kind = "switches"``, no modulator) and are held until the next sample,
   so the switching frequency is variable and at most ``1/(2 Ts)`` per leg.

Sampled, not analog. The comparator only sees the current at the samples, so the current overshoots the
band by up to one sample's change, ``Ts |di/dt|``; and with an isolated star point the phases interact
(a leg's voltage depends on the other legs' states), so a phase error can reach the full band ``h``
before the other legs react (D. M. Brod and D. W. Novotny, "Current control of VSI-PWM inverters", IEEE
Trans. Ind. Appl. IA-21(3), 562-570, 1985). The sampled error bound is therefore ``h + Ts |di/dt|``, not
``h/2 + Ts |di/dt|``, wherever ``U_dc/3`` exceeds the back-EMF and the reference's ``L di*/dt``;
tests/controllers/test_hysteresis.py derives it and measures both.

Gradients. The exact comparator is piecewise constant, so its derivative with
respect to the band or to anything upstream is zero almost everywhere. ``comparator="smooth"`` replaces
the two thresholds by sigmoids of width ``smooth_width_a`` (A)::

    p_hi = sigmoid((e - h/2)/w),   p_lo = sigmoid((-e - h/2)/w),   s = p_hi + (1 - p_hi - p_lo) s_prev

which is the exact law as ``w -> 0`` and stays in [0, 1] for every ``w`` (``p_hi + p_lo < 1`` because the
two arguments sum to ``-h/w < 0``). A fractional ``s`` acts as a leg duty on the averaged bridge, so the
surrogate settles on fractional duties (the "equivalent control" of the switching loop) instead of
switching: it reproduces the slow behaviour but not the ripple. Measured on the book scenario (0.5 A
band, 10 us, ``w`` = 0.05 A): speed within 0.17 rad/s of the exact run and the speed ITAE within 0.6 %,
but the phase-current error RMS 0.16 A instead of 0.23 A and no switching (every state fractional). Use
it for gradients of speed and tracking objectives, not of switching frequency or ripple; re-evaluate a
result tuned on it with ``comparator="exact"``.
"""

from typing import ClassVar, Literal

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import (
    AbstractDAxisReference,
    AbstractSpeedController,
    CurrentLoopContext,
)
from pmsmjax.controllers.foc import ControlMode, cascade_references
from pmsmjax.controllers.speed_cascade import AbstractDesignedSpeedCascade
from pmsmjax.frames.three_phase import abc_to_alpha_beta, dq_to_abc, park
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import CommandKind, ControlOutput, Estimate, References, Sample
from pmsmjax.spec.validation import ParameterError, check_choice, check_positive

ComparatorKind = Literal["exact", "smooth"]

__all__ = ["ComparatorKind", "HysteresisCurrentControl", "HysteresisState", "hysteresis_comparator"]


def hysteresis_comparator(error_a, band_a, previous, comparator: ComparatorKind = "exact", width_a=None):
    """Two-level hysteresis comparator, per element.

    **Arguments:**

    - `error_a`: ``(n,)`` current errors ``i* - i``, A.
    - `band_a`: full band width ``h``, A (switch high above ``+h/2``, low below ``-h/2``).
    - `previous`: ``(n,)`` previous switch states in [0, 1] (held inside the band).
    - `comparator`: ``"exact"`` or ``"smooth"`` (sigmoid surrogate of width `width_a`, A; module docstring).

    **Returns:** ``(n,)`` switch states, 0 or 1 (exact) or in (0, 1) (smooth).
    """
    half = 0.5 * band_a
    if comparator == "exact":
        one, zero = jnp.ones_like(previous), jnp.zeros_like(previous)
        return jnp.where(error_a > half, one, jnp.where(error_a < -half, zero, previous))
    p_hi = jax.nn.sigmoid((error_a - half) / width_a)
    p_lo = jax.nn.sigmoid((-error_a - half) / width_a)
    return p_hi + (1.0 - p_hi - p_lo) * previous


class HysteresisState(eqx.Module):
    speed: object  # the speed block's state
    d_axis: object  # the d-axis reference block's state (None without one)
    switches: Array  # (n,) switch states chosen at the last sample (held inside the band)
    iq_ref: Array  # A, held between speed-loop updates
    counter: Array  # int32, samples since the last speed-loop update


class HysteresisCurrentControl(AbstractDesignedSpeedCascade):
    """Hysteresis current control of the phase currents under a speed loop (command: switch states).

    **Arguments:**

    - `model`: the controller's motor model: the default speed-loop design, the pole pairs, and the
      d-axis block's context. The comparator itself uses no model.
    - `band_a`: full hysteresis band ``h``, A (array leaf: tunable, vmappable).
    - `current_limit`: peak phase-current limit, A (``|i_dq*|`` is kept inside this circle).
    - `speed`: the speed block; ``None`` takes the PI with active damping of
      [`speed_loop_active_damping`][pmsmjax.controllers.design.speed_loop_active_damping] for ``model`` at
      `speed_bandwidth`.
    - `d_axis`: a d-axis reference block (MTPA, field weakening); ``None`` takes the scenario's ``i_d*``.
    - `mode`: ``"speed"`` (cascade) or ``"current"`` (``i_dq*`` from the scenario).
    - `speed_divider`: the speed loop runs every this many comparator samples (static).
    - `comparator`: ``"exact"`` (default) or ``"smooth"`` (sigmoid surrogate for gradients; static).
    - `smooth_width_a`: the surrogate's sigmoid width, A (unused by the exact comparator).
    - `speed_bandwidth`: rad/s, only to design the default speed block.
    """

    command_kind: ClassVar[CommandKind] = "switches"
    divider_unit: ClassVar[str] = "comparator samples"

    band_a: Array
    smooth_width_a: Array
    d_axis: AbstractDAxisReference | None
    comparator: ComparatorKind = eqx.field(static=True)

    def __init__(
        self,
        model: PMSMParameters,
        band_a,
        current_limit,
        speed: AbstractSpeedController | None = None,
        d_axis: AbstractDAxisReference | None = None,
        *,
        mode: ControlMode = "speed",
        speed_divider: int = 1,
        comparator: ComparatorKind = "exact",
        smooth_width_a=0.05,
        speed_bandwidth=50.0,
    ):
        super().__init__(model, current_limit, speed, mode, speed_divider, speed_bandwidth)
        self.band_a = as_float(band_a)
        self.smooth_width_a = as_float(smooth_width_a)
        self.d_axis = d_axis
        self.comparator = comparator

    def __check_init__(self):
        check_positive("band_a (hysteresis band, full width)", self.band_a, "A")
        check_positive("smooth_width_a (sigmoid comparator width)", self.smooth_width_a, "A")
        check_choice("comparator", self.comparator, ("exact", "smooth"))

    def init(self, dtype=None) -> HysteresisState:
        dtype = self.state_dtype(dtype)
        d_axis = None if self.d_axis is None else self.d_axis.init(dtype)
        # All legs low: the zero vector, so a drive at rest with zero references applies no voltage.
        return HysteresisState(
            self.speed.init(dtype),
            d_axis,
            jnp.zeros(3, dtype),
            jnp.zeros((), dtype),
            jnp.zeros((), jnp.int32),
        )

    def step(
        self, state: HysteresisState, sample: Sample, estimate: Estimate, refs: References, Ts, u_max, delayed
    ) -> tuple[HysteresisState, ControlOutput]:
        if sample.i_phase.shape[-1] != 3:
            raise ParameterError(
                f"HysteresisCurrentControl drives three legs; the machine has {sample.i_phase.shape[-1]}."
            )
        # The voltage the legs applied over the last sample, in the estimated rotor frame: a hexagon vertex,
        # not a smooth command (field weakening should filter it).
        u_dq_last = park(sample.u_ab_last, estimate.theta_e)
        ctx = CurrentLoopContext(self.model, Ts, u_max, delayed, u_dq_last, False, False)
        # d-axis reference and speed loop: the FOC cascade's steps 1-2
        speed_state, d_axis_state, iq_ref, counter, i_dq_ref = cascade_references(
            self, state, estimate, refs, ctx
        )

        i_abc_ref = dq_to_abc(i_dq_ref, estimate.theta_e)
        switches = hysteresis_comparator(
            i_abc_ref - sample.i_phase, self.band_a, state.switches, self.comparator, self.smooth_width_a
        )
        # The voltage of the chosen states (isolated star point: the common-mode part is removed).
        u_ab = abc_to_alpha_beta(sample.u_dc * (switches - jnp.mean(switches)))
        u_dq = park(u_ab, estimate.theta_e)
        new_state = HysteresisState(speed_state, d_axis_state, switches, iq_ref, counter)
        return new_state, ControlOutput(switches, u_dq, i_dq_ref)
