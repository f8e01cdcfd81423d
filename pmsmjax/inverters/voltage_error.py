"""The inverter's voltage error, period-averaged: dead time and device drops of a two-level leg.

Centre-aligned PWM (the gate edges of [`pmsmjax.inverters.switching`][pmsmjax.inverters.switching]). After
each gate edge both switches of a leg are off for the dead time ``t_d`` and the freewheeling diode chosen by
the phase current sets the pole: for ``i_x > 0`` the lower diode, so the upper switch's turn-on edge comes
``t_d`` late and the leg loses ``U_dc t_d`` volt-seconds per period; for ``i_x < 0`` the upper diode, so its
turn-off edge comes ``t_d`` late and the leg gains as much. The conducting switch or diode also lowers the
pole by its drop ``V_f`` in the direction of the current. Per period ``Ts`` the average pole voltage error of
leg x is then (Holtz, "Pulsewidth modulation for electronic power conversion", Proc. IEEE 82(8), 1994,
doi:10.1109/5.301684, section on dead-time effects; Murai et al., IEEE Trans. Ind. Appl. 23(5), 1987,
doi:10.1109/TIA.1987.4505004)::

    e_x = -(U_dc t_d / Ts + V_f) sgn(i_x)

with the dead window limited to the pulse it eats: the loss for ``i_x > 0`` is at most the high time
``d_x Ts`` (a narrower pulse vanishes), the gain for ``i_x < 0`` at most the low time ``(1 - d_x) Ts``,
and a leg held at ``d_x = 0`` or ``1`` has no edges and no dead time (the switching bridge's rule).

What is neglected: the current ripple, beyond the smoothed sign below (a current that changes sign inside
the period splits the error between the two diodes); the switches' own turn-on and turn-off delays; a
drop that differs between switch and diode or grows with the current (one constant ``V_f`` for both, as
[`SwitchingBridge`][pmsmjax.inverters.switching.SwitchingBridge] has it, so the drop's average does not depend
on the duty); the parasitic capacitances that slow the pole's swing at small currents.

Sign. ``sgn(i)`` is replaced by ``tanh(i / i_eps)`` so that the model is differentiable in the current
(gradients flow through it). ``i_eps`` stands for the current ripple: near a zero crossing the real
error moves between its two values over about the ripple's amplitude (largest at mid modulation, well
under a volt-second estimate ``U_dc Ts / (8 L)`` near standstill, where all legs switch nearly together).
[`CURRENT_LIMIT_SHARE`][pmsmjax.inverters.voltage_error.CURRENT_LIMIT_SHARE] of the current limit is the drive
file's default.

The same error, predicted by the controller from its own estimates of ``t_d`` and ``V_f``, is what
dead-time compensation adds back
([`pmsmjax.controllers.dead_time_compensation`][pmsmjax.controllers.dead_time_compensation]).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_nonnegative, check_positive, is_concrete

__all__ = ["VoltageError", "smooth_sign", "check_dead_time", "CURRENT_LIMIT_SHARE"]

#: The sign's current scale ``i_eps`` as a share of the drive's current limit (drive files): 2 %, "a few
#: per cent" of the limit, of the order of the PWM current ripple of the example drives.
CURRENT_LIMIT_SHARE = 0.02


def smooth_sign(current: Array, current_scale: Array) -> Array:
    """``tanh(i / i_eps)``: the sign of ``current``, smoothed over ``current_scale``.

    Args:
        current: Current, A (any shape).
        current_scale: ``i_eps``, A.
    """
    return jnp.tanh(current / current_scale)


def check_dead_time(dead_time, Ts: float, name: str) -> None:
    """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] unless ``dead_time`` (s, any shape) is
    below half the PWM period ``Ts`` (s): both edges of one pulse must fit. `name`: how to call it."""
    if not is_concrete(dead_time):
        return
    t_d = float(np.max(np.asarray(jax.device_get(dead_time))))  # NumPy: no tracer inside a jit
    if t_d >= 0.5 * Ts:
        raise ParameterError(
            f"{name} = {t_d:g} s is not below half the PWM period Ts/2 = {0.5 * Ts:g} s: a typical dead "
            "time is 0.5-3 us (in s: 2e-6 for 2 us)."
        )


class VoltageError(eqx.Module):
    """Period-average pole-voltage error of two-level legs from dead time and device drops (module
    docstring). All array leaves: vmappable and differentiable.

    Args:
        dead_time: ``t_d``, s (>= 0).
        device_drop: ``V_f``, V (>= 0).
        current_scale: ``i_eps`` of the smoothed sign, A (> 0).
    """

    dead_time: Array
    device_drop: Array
    current_scale: Array

    def __init__(self, dead_time=0.0, device_drop=0.0, current_scale=0.05):
        self.dead_time = as_float(dead_time)
        self.device_drop = as_float(device_drop)
        self.current_scale = as_float(current_scale)

    def __check_init__(self):
        check_nonnegative("dead_time", self.dead_time, "s")
        check_nonnegative("device_drop", self.device_drop, "V")
        check_positive("current_scale (the current sign's smoothing)", self.current_scale, "A")

    def pole_error(self, i_phase: Array, duties: Array, u_dc: Array, Ts) -> Array:
        """Period-average pole-voltage errors of the legs (common mode included: the caller removes it as the
        isolated neutral does).

        Args:
            i_phase: ``(n,)`` phase currents, A.
            duties: ``(n,)`` leg duties.
            u_dc: DC voltage, V.
            Ts: PWM period, s.

        Returns:
            ``(n,)`` errors, V.
        """
        sign = smooth_sign(i_phase, self.current_scale)
        switching = (duties > 0.0) & (duties < 1.0)  # a clamped leg has no edges
        t_d = jnp.where(switching, self.dead_time, 0.0)
        lost = jnp.minimum(t_d, duties * Ts)  # i > 0: the turn-on edge is late, the pulse shrinks
        gained = jnp.minimum(t_d, (1.0 - duties) * Ts)  # i < 0: the turn-off edge is late
        dead = 0.5 * (1.0 + sign) * lost - 0.5 * (1.0 - sign) * gained
        return -(u_dc / Ts) * dead - self.device_drop * sign
