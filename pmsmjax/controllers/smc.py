"""Sliding-mode speed control with the exponential reaching law (the book, ch. 3).

**Theory.** With ``x1 = w* - w_m`` (rad/s), ``x2 = dx1/dt`` (rad/s^2), ``D = 1.5 p_n psi_f / J``
(rad/(A s^2)) and the mechanics ``J dw_m/dt = K_t i_q - T_L - B w_m``, a constant reference gives
``dx2/dt = -D di_q/dt + (dT_L/dt)/J - (B/J) x2``. On the sliding surface ``s = c x1 + x2 = 0``
(rad/s^2) the error obeys ``dx1/dt = -c x1``: a first-order decay with time constant ``1/c``, whatever the
(constant) load and friction. The exponential reaching law ``ds/dt = -eps sgn(s) - q s`` (Gao and Hung,
"Variable structure control of nonlinear systems: a new approach", IEEE Trans. Ind. Electron. 40(1),
45-55, 1993, doi:10.1109/41.184820) is obtained with ``D di_q*/dt = c x2 + eps sgn(s) + q s``, so

    i_q* = (1/D) int (c x2 + eps sgn(s) + q s) dt,

and then ``ds/dt = -eps sgn(s) - q s + d(t)`` with ``d = (dT_L/dt)/J - (B/J) x2``: the surface is
reached and kept while ``eps > |d|`` ([`smc_design`][pmsmjax.controllers.smc.smc_design] sizes eps from that
bound).

Units: ``c`` and ``q`` 1/s; ``eps`` rad/s^3 (it is a rate of change of ``s``, which is in rad/s^2);
``boundary`` rad/s^2 (units of ``s``).

**What the law is, linearly.** Because ``x2 = dx1/dt``, ``int c x2 dt = c x1`` and
``int q s dt = q x1 + q c int x1 dt``: ``i_q* = (1/D)[(c + q) x1 + q c int x1 dt + eps int sgn(s) dt]``, a
speed PI with ``Kp = (c + q)/D``, ``Ki = q c / D`` (closed-loop poles ``-c`` and ``-q`` with an ideal
current loop and no friction) plus the integrated switching term. So the speed derivative is needed only
inside the switching function; the rest of the law never differentiates the measured speed.

**Discrete implementation** (once per speed-loop period ``Ts``):

- ``x2[k] = (x1[k] - x1[k-1]) / Ts``: backward difference of the measured (or estimated) speed error.
  It is the derivative half a period late (50 us at 10 kHz, negligible beside the current loop's
  ``1/a_c`` = 0.9 ms), and it makes the integral telescope exactly (``sum Ts c x2 = c x1``), so the
  linear part above holds to rounding. Its cost is noise: white speed noise of standard deviation
  ``sigma`` (rad/s) becomes ``sqrt(2) sigma / Ts`` on ``x2`` and ``s`` (a 0.01 rad/s jitter at
  10 kHz is 141 rad/s^2 on ``s``); it reaches ``i_q*`` only through the switching function (the linear
  part integrates it back to ``(c + q) sigma / D``), so the sign law turns it into chattering and a
  boundary layer wider than that noise keeps it linear. A model-based estimate
  ``x2 = -(D i_q - B w / J)`` would be noise-free but ignores the unknown load: under ``T_L`` it is off
  by ``T_L / J`` and the switching integral then holds ``c x1 = T_L / J``, a steady speed error of
  ``T_L / (J c)`` (67 rad/s for 10 N m on the book motor at c = 50 1/s), so it is not used.
  ``x1[-1] = 0``: the drive starts from rest with ``w* = 0`` before ``t = 0``, so a reference step at
  ``t = 0`` enters as the derivative impulse it is (its integral is the ``(c + q) x1 / D`` kick).
- ``i_q*[k] = clip(i_q*[k-1] + Ts (c x2 + eps f(s) + q s) / D, -iq_max, iq_max)``. The integral *is*
  the output, so anti-windup is clamping the integral state itself at the limit (back-calculation with
  unit gain): the state never lies beyond ``iq_max`` and leaves the limit in the first period whose
  increment points inwards.

**Switching function** ``f`` (static ``switching``): ``"sign"`` (exact, the book's; chatters, and its
gradient is zero almost everywhere), ``"saturation"`` ``clip(s/boundary, -1, 1)`` or ``"tanh"``
``tanh(s/boundary)`` (boundary layers; smooth surrogate for gradients, selectable by a field). On the
book drive with the design rule the sign law's i_q* chatters as a 420 Hz triangle of +-0.7 A (it moves
``eps Ts / D`` = 0.11 A every period); with a 2500-line encoder's speed it also wanders, the speed
drifting over 979-1020 r/min at 1000 r/min, where the boundary layers hold it within 1 r/min
(tests/controllers/test_smc.py).

**Verification.** tests/controllers/test_smc.py: the book scenario, the fitted decay constant on the surface
against ``1/c``, chattering of the three switching functions, ``jax.grad`` against central differences.
"""

from typing import Literal

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractSpeedController
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.spec.validation import (
    ParameterError,
    check_choice,
    check_nonnegative,
    check_positive,
    is_concrete,
)

Switching = Literal["sign", "saturation", "tanh"]
SWITCHING = ("sign", "saturation", "tanh")

__all__ = ["SlidingModeSpeed", "SlidingModeState", "Switching", "smc_design", "switching_function"]


def switching_function(s: Array, boundary: Array, kind: Switching) -> Array:
    """``sgn(s)``, ``clip(s/boundary, -1, 1)`` or ``tanh(s/boundary)`` (``boundary > 0``, units of s)."""
    check_choice("switching", kind, SWITCHING)
    if kind == "sign":
        return jnp.sign(s)
    if kind == "saturation":
        return jnp.clip(s / boundary, -1.0, 1.0)
    return jnp.tanh(s / boundary)


class SlidingModeState(eqx.Module):
    iq_ref: Array  # A, the integral (the limited output i_q*)
    x1_prev: Array  # rad/s, last period's speed error (for the backward difference)


class SlidingModeSpeed(AbstractSpeedController):
    """Sliding-mode speed controller with the exponential reaching law (see the module docstring).

    **Arguments:**

    - `c`: sliding-surface slope, 1/s (on the surface the speed error decays with time constant 1/c).
    - `eps`: constant reaching rate, rad/s^3 (switching gain; must exceed the disturbance bound on ds/dt).
    - `q`: exponential reaching rate, 1/s.
    - `torque_constant_over_inertia`: the controller's ``D = 1.5 p_n psi_f / J``, rad/(A s^2) (its own
      model value: it may differ from the plant's for mismatch studies).
    - `boundary`: boundary-layer width, rad/s^2 (units of s); ignored by ``switching="sign"``.
    - `switching`: ``"sign"`` (default, the book's), ``"saturation"`` or ``"tanh"`` (static).

    State: `SlidingModeState` (the integral i_q*, A; last speed error, rad/s).
    """

    c: Array = eqx.field(converter=as_float)
    eps: Array = eqx.field(converter=as_float)
    q: Array = eqx.field(converter=as_float)
    torque_constant_over_inertia: Array = eqx.field(converter=as_float)
    boundary: Array = eqx.field(converter=as_float)
    switching: Switching = eqx.field(static=True, default="sign")

    def __check_init__(self):
        check_choice("SlidingModeSpeed.switching", self.switching, SWITCHING)
        check_positive("SlidingModeSpeed.c (surface slope)", self.c, "1/s")
        check_nonnegative("SlidingModeSpeed.eps (constant reaching rate)", self.eps, "rad/s^3")
        check_nonnegative("SlidingModeSpeed.q (exponential reaching rate)", self.q, "1/s")
        check_positive(
            "SlidingModeSpeed.torque_constant_over_inertia (D = 1.5 p_n psi_f / J)",
            self.torque_constant_over_inertia,
            "rad/(A s^2)",
        )
        check_positive("SlidingModeSpeed.boundary (boundary-layer width)", self.boundary, "rad/s^2")

    def init(self, dtype):
        zero = jnp.zeros((), dtype)
        return SlidingModeState(zero, zero)

    def surface(self, x1: Array, x2: Array) -> Array:
        """``s = c x1 + x2``, rad/s^2."""
        return self.c * x1 + x2

    def step(self, state: SlidingModeState, speed_ref, omega_m, iq_max, Ts):
        x1 = speed_ref - omega_m
        x2 = (x1 - state.x1_prev) / Ts
        s = self.surface(x1, x2)
        # D di_q*/dt, rad/s^3: the reaching law solved for the current's rate of change.
        rate = self.c * x2 + self.eps * switching_function(s, self.boundary, self.switching) + self.q * s
        iq_ref = jnp.clip(state.iq_ref + Ts * rate / self.torque_constant_over_inertia, -iq_max, iq_max)
        return SlidingModeState(iq_ref, x1), iq_ref


def smc_design(
    motor: PMSMParameters,
    time_constant_s=0.02,
    *,
    reaching_ratio=5.0,
    load_torque_rate_nm_s=1000.0,
    current_limit_a=15.0,
    current_bandwidth_rad_s=1100.0,
    Ts=1e-4,
    margin=1.2,
    switching: Switching = "sign",
) -> SlidingModeSpeed:
    """Sliding-mode speed gains from the motor, the surface time constant and the disturbance bound.

    **Arguments:**

    - `motor`: the controller's motor model (``D = K_t / J``; ``B / J`` for the friction bound).
    - `time_constant_s`: time constant of the error decay on the surface, s: ``c = 1 / time_constant_s``.
      Default 20 ms (c = 50 1/s, the book PI's speed bandwidth, so the two blocks compare at equal speed).
      Sliding needs ``D i_q = c x1 + T_L / J`` inside the limit: ``|x1| < (D i_max - T_L/J) / c``
      (110 rad/s unloaded on the book drive: the 1000 r/min = 104.7 rad/s step slides just inside it).
    - `reaching_ratio`: ``q = reaching_ratio * c``, 1/s. ``q`` is the second closed-loop pole (see the
      module docstring): a few times ``c`` so ``s`` reaches zero before ``x1`` has moved much
      (time-scale separation), and below half the current-loop bandwidth (refused otherwise).
    - `load_torque_rate_nm_s`: the worst ``|dT_L/dt|`` to reject while sliding, N m/s (default: 10 N m
      applied over 10 ms). A true step has no bound: it throws ``s`` off by ``dT_L / J`` and the reaching
      law brings it back in ``(1/q) ln(1 + q |ds| / eps)``.
    - `current_limit_a`: ``i_max``, A, bounding ``|x2| <= D i_max`` in the friction term.
    - `current_bandwidth_rad_s`: the current loop's bandwidth ``a_c``, rad/s (boundary layer, check on q).
    - `Ts`: speed-loop period, s (check ``q Ts < 1``).
    - `margin`: ``eps`` is this factor above the disturbance bound.
    - `switching`: the switching function (static).

    **Rules.** ``eps = margin ((dT_L/dt)_max / J + (B/J) D i_max)``: the bound on ``|d|`` in
    ``ds/dt = -eps sgn(s) - q s + d`` (the sliding condition ``s ds/dt < 0``). The boundary layer makes the
    switching term linear, an extra reaching rate ``eps / boundary``; ``boundary = eps / (a_c/2 - q)`` puts
    the total rate ``q + eps/boundary`` at ``a_c / 2``, where the reaching dynamics filtered by the
    current loop ``a_c/(p + a_c)`` is damped at ``zeta = 0.5 sqrt(a_c / rate) = 0.71``. Discrete
    stability of the reaching law (Gao, Wang and Homaifa, "Discrete-time variable structure control
    systems", IEEE Trans. Ind. Electron. 42(2), 117-122, 1995) needs ``q Ts < 1``; ``a_c Ts / 2 < 1``
    holds for any current loop that runs at that rate.
    """
    check_positive("time_constant_s (sliding-surface time constant)", time_constant_s, "s")
    for name, value, unit in (
        ("reaching_ratio", reaching_ratio, ""),
        ("current_limit_a", current_limit_a, "A"),
        ("current_bandwidth_rad_s", current_bandwidth_rad_s, "rad/s"),
        ("Ts (speed-loop period)", Ts, "s"),
        ("margin", margin, ""),
    ):
        check_positive(name, value, unit)
    check_nonnegative("load_torque_rate_nm_s", load_torque_rate_nm_s, "N m/s")
    dtype = motor.R.dtype
    D = motor.torque_constant / motor.J
    c = jnp.asarray(1.0 / time_constant_s, dtype)
    q = reaching_ratio * c
    a_c = jnp.asarray(current_bandwidth_rad_s, dtype)
    if all(is_concrete(x) for x in (q, a_c)):
        if float(jnp.max(q)) >= 0.5 * float(jnp.min(a_c)):
            raise ParameterError(
                f"reaching rate q = {float(jnp.max(q)):g} 1/s must be below half the current-loop bandwidth "
                f"({0.5 * float(jnp.min(a_c)):g} 1/s): lengthen time_constant_s or lower reaching_ratio."
            )
        if float(jnp.max(q)) * Ts >= 1.0:
            raise ParameterError(
                f"q Ts = {float(jnp.max(q)) * Ts:.2f} >= 1: the discrete reaching law overshoots the "
                f"surface; choose q < {1.0 / Ts:g} 1/s."
            )
    friction = motor.B / motor.J * D * current_limit_a
    eps = margin * (load_torque_rate_nm_s / motor.J + friction)
    boundary = eps / (0.5 * a_c - q)
    return SlidingModeSpeed(c, eps, q, D, boundary, switching)
