"""Field weakening by voltage feedback: an integrator on the voltage margin drives i_d negative.

Above base speed the back-EMF ``w_e psi_f`` approaches the inverter's voltage limit ``u_max``
(``U_dc/sqrt(3)`` for SVPWM) and the current loop saturates: the q current can no longer be forced in and
the speed stops rising. A negative d current lowers the stator flux ``L_d i_d + psi_f`` and with it the
voltage. The closed-loop voltage-feedback method (Kim and Sul, "Speed control of interior permanent magnet
synchronous motor drive for the flux weakening operation", IEEE Trans. Ind. Appl. 33(1), 43-48, 1997,
doi:10.1109/28.567075) finds that current without a motor model: integrate the voltage margin

    delta_i_d <- clip(delta_i_d + Ts k (m u_max - |u_dq|), i_d,min - i_d,base, 0)
    i_d*       = i_d,base + delta_i_d

with ``|u_dq|`` last period's voltage command (``CurrentLoopContext.u_dq_prev``), ``m < 1`` the margin kept
for the current loop's own transients, and ``i_d,base`` the MTPA current (or the scenario's ``i_d*``).
Below base speed the margin is positive and ``delta_i_d`` rests at 0 (the upper clip), so the block is
inactive; above it ``delta_i_d`` settles where ``|u_dq| = m u_max``. The operating point comes from the
measured voltage demand, not from a model of the voltage ellipse, so flux-linkage and DC-link errors do
not move it off the voltage limit (the model's R and L_d only schedule the gain); the FOC's current circle
(``i_q,max = sqrt(I^2 - i_d^2)``) then gives the q axis what the voltage leaves, so the operating point
sits on the intersection of the current circle and the voltage ellipse.

Gain schedule. The small-signal gain from ``i_d`` to ``|u_dq|`` is the d-axis impedance seen by the
voltage vector, about ``sqrt(R^2 + (w_e L_d)^2)`` (``d u_q/d i_d = w_e L_d`` dominates above base
speed). With ``k = alpha_fw / sqrt(R^2 + (w_e L_d)^2)`` the voltage loop is an integrator of bandwidth
``alpha_fw`` at every speed, with no division by zero at standstill. The voltage acts through the
current loop ``a_c/(s + a_c)``, so ``alpha_fw = a_c/3`` leaves a phase margin of about
``90 - atan(1/3) = 72`` degrees (less ``alpha_fw`` times the 1.5 Ts delay: 3 degrees); the book drive
reaches 2500 and 3000 r/min with any ``alpha_fw`` from 50 to 800 rad/s (a slower loop lets the current
loop touch the voltage limit more often on the way up).

Bounds (anti-windup by clipping the state): ``i_d* >= -min(I_max, psi_f/L_d)``. Beyond the characteristic
current ``psi_f/L_d`` the d flux would reverse, which lowers the voltage no further; the current limit
itself bounds it for the book motor (psi_f/L_d = 34.8 A > 15 A).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractDAxisReference, CurrentLoopContext
from pmsmjax.controllers.mtpa import mtpa_id_from_iq
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_positive, is_concrete


class VoltageFeedbackFieldWeakening(AbstractDAxisReference):
    """Closed-loop voltage-feedback field weakening (Kim and Sul 1997) on top of MTPA or the scenario's i_d*.

    **Arguments:**

    - `bandwidth`: voltage-loop bandwidth ``alpha_fw``, rad/s (default 350: about a_c/3 for the book
      drive's a_c = 1100 rad/s).
    - `voltage_margin`: ``m`` in (0, 1], the fraction of ``u_max`` the loop regulates ``|u_dq|`` to
      (default 0.95: 9 V of the book drive's 180 V kept for the current loop's transients).
    - `mtpa`: static; ``True`` (default) takes the base reference from MTPA on the controller's motor model
      (i_d = 0 for a surface machine), ``False`` from the scenario's ``i_d*``.

    State: ``delta_i_d``, A (<= 0).
    """

    bandwidth: Array = eqx.field(converter=as_float, default=350.0)
    voltage_margin: Array = eqx.field(converter=as_float, default=0.95)
    mtpa: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        check_positive("field-weakening bandwidth", self.bandwidth, "rad/s")
        check_positive("voltage_margin", self.voltage_margin, "(fraction of u_max)")
        if is_concrete(self.voltage_margin) and np.any(np.asarray(self.voltage_margin) > 1.0):
            raise ParameterError(
                f"voltage_margin must be in (0, 1] (a fraction of the voltage limit), got "
                f"{np.asarray(self.voltage_margin)}: e.g. 0.95 keeps 5 % for the current loop."
            )

    def init(self, dtype):
        return jnp.zeros((), dtype)

    def step(self, state, id_ref, iq_ref_prev, omega_e, ctx: CurrentLoopContext, current_limit):
        m = ctx.model
        base = mtpa_id_from_iq(m, iq_ref_prev) if self.mtpa else id_ref
        id_min = -jnp.minimum(current_limit, m.psi_f / m.L_d)
        return voltage_feedback_update(state, base, id_min, self.bandwidth, self.voltage_margin, omega_e, ctx)


def voltage_feedback_update(state, base, id_min, bandwidth, voltage_margin, omega_e, ctx: CurrentLoopContext):
    """One period of the voltage-margin integrator (module docstring): ``delta_i_d`` (A, <= 0) from the
    last command's magnitude, with the gain scheduled on the model's ``R``, ``L_d``; the reference
    ``base + delta_i_d`` kept at or above ``id_min`` (A). Returns ``(delta_i_d, i_d*)``."""
    m = ctx.model
    # |u_dq| guarded at 0 (the first period) so the gradient stays finite.
    u_sq = jnp.sum(ctx.u_dq_prev * ctx.u_dq_prev)
    nonzero = u_sq > 0
    u_mag = jnp.where(nonzero, jnp.sqrt(jnp.where(nonzero, u_sq, 1.0)), 0.0)
    margin = voltage_margin * ctx.u_max - u_mag  # V, positive with voltage to spare
    gain = bandwidth / jnp.sqrt(m.R**2 + (omega_e * m.L_d) ** 2)  # A/(V s)
    delta = state + ctx.Ts * gain * margin
    delta = jnp.minimum(jnp.maximum(delta, id_min - base), 0.0)
    return delta, base + delta


__all__ = ["VoltageFeedbackFieldWeakening", "voltage_feedback_update"]
