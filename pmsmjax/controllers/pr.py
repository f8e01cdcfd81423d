"""Proportional-resonant (PR) current control in the stationary frame (the book, ch. 3).

**Theory.** One scalar filter per stationary axis (alpha and beta alike) acts on the current error
``e = i_ab* - i_ab``::

    G(s) = Kp + 2 Kr w_c (s cos(phi) - w_0 sin(phi)) / (s^2 + 2 w_c s + w_0^2)

with the resonance ``w_0`` the estimated electrical speed ``w_e`` (so the coefficients change every
period) and ``phi`` an optional phase lead (below); ``phi = 0`` is the book's form
``Kp + 2 Kr w_c s / (s^2 + 2 w_c s + w_0^2)``. At ``s = j w_0`` the resonant term equals ``Kr e^{j phi}``.

A real-coefficient filter applied to both axes multiplies a positive-sequence vector ``x_a + j x_b``
rotating at ``w`` by ``G(j w)``. Near the resonance, ``w = w_0 + delta`` with ``|delta| << w_0``::

    2 Kr w_c s / (s^2 + 2 w_c s + w_0^2) ~= Kr w_c / (w_c + j delta)

which seen from the rotor frame (``s' = j delta``) is the leaky integrator ``Kr w_c / (s' + w_c)``. The
PR is therefore the stationary-frame equivalent of a synchronous-frame PI ``Kp + Ki/s'`` with
``Ki = Kr w_c`` whose integrator leaks at ``w_c``. (Zmood & Holmes 2003, IEEE TPEL 18(3), 814-822: the
ideal resonator ``2 Ki s / (s^2 + w_0^2) = Ki/(s - j w_0) + Ki/(s + j w_0)``, the ``w_c -> 0`` limit, is
the synchronous PI ``Ki/s'`` for the positive sequence plus its mirror for the negative sequence; the
synchronous PI moved to the stationary frame would need the cross-axis terms that the PR drops. The
``w_c`` form is their "non-ideal" resonator; tests/controllers/test_pr.py checks the equivalence to 1 %.)
Consequences:

- the gain at ``w_0`` is ``Kp + Kr``, finite: the steady-state error is about
  ``|u_unmodelled| / |Kp + Kr|``, where ``u_unmodelled`` is the steady voltage the feed-forward does not
  supply (tests/controllers/test_pr.py checks the measured error against the exact discrete prediction);
- with ``Kr w_c = Ki`` held (the design rule [`pr_design`][pmsmjax.controllers.pr.pr_design]) the gain at a
  frequency mismatch ``delta`` is ``Ki / |w_c + j delta|``: for ``|delta| > w_c`` it does not depend on
  ``w_c``. ``w_c`` raises the peak's width only when ``Kr`` is held instead; with the design rule it sets how
  fast the resonator forgets (time constant ``1/w_c``) and the finite peak ``Kp + Ki/w_c``.

**Angles.** The reference ``i_ab* = inverse_park(i_dq*, theta_e)`` uses the angle at the sampling
instant, because it is compared with the current sampled at that instant; advancing it would make the
resonator drive the sampled current onto the advanced reference, a steady d-axis error of
``i_q sin(w_e t_lead)``. The command acts on average ``t_lead`` after the sample (1.5 Ts with a
computational delay: one period of delay plus half a period of PWM hold; 0.5 Ts without), a lag of
``w_0 t_lead`` at the resonance. With ``phase_lead=True`` (default) ``phi = w_0 t_lead`` makes the resonant
term lead by exactly that (Yepes et al. 2010, delay compensation of resonant controllers), so the loop
phase near the resonance is that of the delay-free plant. The proportional path is left uncompensated
(a real-coefficient proportional gain cannot lead; the same 1.5 Ts act on the dq PI without prediction).

**Feed-forward.** With ``back_emf_feedforward=True`` (default, as the dq PI's decoupling has it) the
back-EMF ``w_e psi_f`` on the estimated q axis, rotated to alpha-beta at the angle where the command
acts (``theta_e + w_e t_lead``), is added to the output. Without it the resonator must supply the whole
76 V back-EMF at 1000 r/min through its finite gain ``Kp + Kr``: about 4x the steady-state error.

**Anti-windup.** The voltage vector is limited to ``ctx.u_max`` (magnitude, direction kept). The excess
``u - v`` is fed back into the resonators' input, ``e_r = e + (u - v)/Kp``: back-calculation with the
tracking time constant equal to the equivalent PI's integral time ``Kp/Ki`` (Astrom & Hagglund's rule
``T_t = T_i``; the resonator integrates near ``w_0`` at rate ``Kr w_c = Ki``). Feeding the input keeps the
two resonator states a consistent (in-quadrature) pair, which freezing them would not.

**Discretisations** (static ``discretisation``), both exact at ``w_0``, coefficients recomputed each
period ([`resonant_coefficients`][pmsmjax.controllers.pr.resonant_coefficients]). The resonant term in
two-integrator state-space form::

    x1' = 2 Kr w_c e - 2 w_c x1 - w_0 x2,   x2' = w_0 x1,   y_r = cos(phi) x1 - sin(phi) x2

- ``"tustin-prewarp"`` (default): the bilinear transform with the prewarped step
  ``T = 2 tan(w_0 Ts/2) / w_0`` (``s -> (2/T)(z - 1)/(z + 1)``) in scipy's generalised-bilinear
  state-space realisation. The discrete response at ``z = exp(j w Ts)`` is exactly
  ``G(j (2/T) tan(w Ts/2))``: equal to ``G(j w_0)`` at ``w_0``. Its state is ``(I - A T/2) x - (T/2) B e``
  of the continuous state ``x`` (scipy's realisation of the trapezoidal rule): within ``O(w_0 T)`` of
  it, so the coefficients may change every period as ``w_0`` moves without the state losing its
  meaning, as a direct-form biquad's delayed outputs would.
- ``"sogi"``: the two-integrator form of Yepes et al. 2011 (forward Euler on the direct integrator,
  backward Euler on the feedback one; no division, no feed-through), with the feedback gain
  ``w^ = (2/Ts) sin(w_0 Ts/2)`` that puts the poles' angle at ``w_0 Ts`` exactly. Its ``x1`` then has gain
  exactly ``Kr`` at ``w_0``; the quadrature state is centred by half a sample,
  ``(x2 - Ts w^ x1/2) / cos(w_0 Ts/2)``, so that the output also has phase ``phi`` there.

**Measured** (``python -m benchmarks.bench_pr``, float64, book drive): book scenario rise 42.4 ms (dq PI
41.9), dip 242.7 r/min (243.5), recovery to 10 r/min 117 ms (117), ITAE 0.3605 (0.3598); fundamental
error at 1000 r/min, 10 N m 0.45 % (1.80 % without feed-forward; 1.10 % with w_c = 5). A current step
0 -> 5 A at 1000 r/min: rise 1.6 ms, overshoot 2.5 % (3.4 % without the phase lead; at 2000 r/min 5.4 %
against 8.4 %), within 2 % after 18 ms with a 1.6 A excursion of i_d, where the decoupled, predictive dq
PI takes 3.5 ms and 0.04 A. The PR leaves the rotor-frame coupling ``j w_0 L`` in the loop (its
synchronous equivalent is a PI without decoupling, whose zero at ``-R/L`` misses the pole at
``-R/L - j w_0``): a slow closed-loop pole near ``-141 + 46j`` rad/s at 1000 r/min.

References: D. N. Zmood, D. G. Holmes, "Stationary frame current regulation of PWM inverters with zero
steady-state error", IEEE TPEL 18(3), 2003. A. G. Yepes et al., "Effects of discretization methods on
the performance of resonant controllers", IEEE TPEL 25(7), 2010; "High-performance digital resonant
controllers implemented with two integrators", IEEE TPEL 26(2), 2011.
"""

from typing import Literal, NamedTuple

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractCurrentController, CurrentLoopContext
from pmsmjax.controllers.current_pi import angle_lead
from pmsmjax.controllers.pi import clip_magnitude
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.spec.validation import ParameterError, check_choice, check_nonnegative, check_positive

Discretisation = Literal["tustin-prewarp", "sogi"]
DISCRETISATIONS = ("tustin-prewarp", "sogi")

__all__ = [
    "DISCRETISATIONS",
    "ProportionalResonant",
    "ResonantCoefficients",
    "pr_design",
    "resonant_coefficients",
]


class ResonantCoefficients(NamedTuple):
    """One period's discrete resonator: ``x_{k+1} = Ad x_k + Bd e_k``, ``y_k = Cd . x_k + Dd e_k``.

    `Ad (..., 2, 2)`, `Bd (..., 2)` V/A, `Cd (..., 2)`, `Dd (...)` V/A; states in V.
    """

    Ad: Array
    Bd: Array
    Cd: Array
    Dd: Array


def _tan_ratio(x):
    """``tan(x)/x`` with its limit 1 at ``x = 0`` (double-where: finite gradient there)."""
    small = jnp.abs(x) < 1e-4
    safe = jnp.where(small, 1.0, x)
    return jnp.where(small, 1.0 + x * x / 3.0, jnp.tan(safe) / safe)


def resonant_coefficients(
    omega_0, w_c, kr, Ts: float, phi, discretisation: Discretisation = "tustin-prewarp"
) -> ResonantCoefficients:
    """Discrete coefficients of ``2 Kr w_c (s cos(phi) - w_0 sin(phi)) / (s^2 + 2 w_c s + w_0^2)``.

    **Arguments:** `omega_0` resonance, rad/s (``|omega_0| Ts < pi``); `w_c` rad/s; `kr` V/A; `Ts` the
    sampling period, s; `phi` phase lead at the resonance, rad; `discretisation` (module docstring).
    """
    w0, wc, kr, phi = (jnp.asarray(a) for a in (omega_0, w_c, kr, phi))
    c, s = jnp.cos(phi), jnp.sin(phi)
    one, zero = jnp.ones_like(w0 * wc), jnp.zeros_like(w0 * wc)
    if discretisation == "tustin-prewarp":
        # Bilinear with the prewarped step T; generalised-bilinear realisation (as scipy's cont2discrete):
        # M = I - (T/2) A, Ad = M^-1 (I + (T/2) A), Bd = M^-1 B T, Cd = C M^-1, Dd = C Bd / 2.
        T = Ts * _tan_ratio(0.5 * w0 * Ts)
        h = 0.5 * w0 * T
        det = 1.0 + wc * T + h * h
        m_inv = (
            jnp.stack([jnp.stack([one, -h], -1), jnp.stack([h, 1.0 + wc * T], -1)], -2) / det[..., None, None]
        )
        plus = jnp.stack([jnp.stack([1.0 - wc * T, -h], -1), jnp.stack([h, one], -1)], -2)
        # Products of 2x2 matrices as broadcast sums, not dot ops: XLA:CPU fuses these into the step,
        # where tiny dots each cost a library call (the PR drive's per-period cost, bench_controllers).
        Ad = jnp.sum(m_inv[..., :, :, None] * plus[..., None, :, :], axis=-2)
        Bd = m_inv[..., :, 0] * (2.0 * kr * wc * T)[..., None]
        C = jnp.stack([c * one, -s * one], -1)
        Cd = jnp.sum(C[..., :, None] * m_inv, axis=-2)
        Dd = 0.5 * jnp.sum(C * Bd, -1)
    elif discretisation == "sogi":
        # x1+ = x1 + Ts (2 Kr w_c e - 2 w_c x1 - w^ x2); x2+ = x2 + Ts w^ x1+ (forward then backward Euler).
        g = 2.0 * jnp.sin(0.5 * w0 * Ts)  # = Ts w^
        a11 = 1.0 - 2.0 * wc * Ts
        Ad = jnp.stack([jnp.stack([a11, -g], -1), jnp.stack([g * a11, 1.0 - g * g], -1)], -2)
        b1 = 2.0 * kr * wc * Ts
        Bd = jnp.stack([b1, g * b1], -1)
        half = 0.5 * w0 * Ts
        Cd = jnp.stack([c + s * jnp.tan(half), -s / jnp.cos(half)], -1)
        Dd = zero
    else:
        raise ParameterError(f"discretisation must be one of {DISCRETISATIONS}, got {discretisation!r}.")
    return ResonantCoefficients(Ad, Bd, Cd, Dd)


class ProportionalResonant(AbstractCurrentController):
    """Proportional-resonant current controller in alpha-beta (module docstring: theory and choices).

    **Arguments:**

    - `kp`: proportional gain, V/A.
    - `kr`: resonant gain, V/A (the resonant term's gain at ``w_0``).
    - `w_c`: resonator damping (half the -3 dB width of the resonant peak), rad/s.
    - `discretisation`: ``"tustin-prewarp"`` (default) or ``"sogi"`` (static).
    - `phase_lead`: lead the resonant term by ``w_0 t_lead`` to compensate the command's delay (static,
      default True).
    - `back_emf_feedforward`: add ``w_e psi_f`` on the estimated q axis (static, default True).
    - `anti_windup`: back-calculation of the limiter's excess into the resonators (static, default True;
      False only to show what it prevents).

    State: ``(2, 2)`` resonator states, V (rows alpha, beta; columns the two integrators).
    ``step`` returns ``(state, u_ab, u_dq)``: the limited stator-frame command ``u_ab (2,)`` V and the same
    command in the rotor frame where it acts, ``park(u_ab, theta_e + w_e t_lead)``, V, the convention
    of the dq PI (whose ``u_dq`` is inverse-Parked with that lead).
    """

    kp: Array = eqx.field(converter=as_float)
    kr: Array = eqx.field(converter=as_float)
    w_c: Array = eqx.field(converter=as_float)
    discretisation: Discretisation = eqx.field(static=True, default="tustin-prewarp")
    phase_lead: bool = eqx.field(static=True, default=True)
    back_emf_feedforward: bool = eqx.field(static=True, default=True)
    anti_windup: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        check_positive("ProportionalResonant.kp", self.kp, "V/A")
        check_nonnegative("ProportionalResonant.kr", self.kr, "V/A")
        check_positive(
            "ProportionalResonant.w_c",
            self.w_c,
            "rad/s",
            "give the resonator damping in rad/s (a few rad/s; 0 is the ideal resonator, which this form "
            "cannot express because its resonant gain is 2 Kr w_c)",
        )
        check_choice("ProportionalResonant.discretisation", self.discretisation, DISCRETISATIONS)

    def lead_time(self, Ts: float, delayed: bool) -> float:
        """Time (s) from the sample to the middle of the period the command acts in."""
        return angle_lead(Ts, delayed)

    def coefficients(self, omega_0, Ts: float, delayed: bool) -> ResonantCoefficients:
        """This controller's discrete resonator at resonance ``omega_0`` (rad/s)."""
        phi = omega_0 * self.lead_time(Ts, delayed) if self.phase_lead else jnp.zeros_like(omega_0)
        return resonant_coefficients(omega_0, self.w_c, self.kr, Ts, phi, self.discretisation)

    def init(self, dtype):
        return jnp.zeros((2, 2), dtype)

    def step(self, state, i_dq_ref, i_ab, theta_e, omega_e, ctx: CurrentLoopContext):
        co = self.coefficients(omega_e, ctx.Ts, ctx.delayed)
        error = inverse_park(i_dq_ref, theta_e) - i_ab  # both at the sampling instant
        theta_act = theta_e + omega_e * self.lead_time(ctx.Ts, ctx.delayed)
        resonant = jnp.sum(state * co.Cd, axis=-1) + co.Dd * error
        if self.back_emf_feedforward:
            ff = inverse_park(jnp.stack([jnp.zeros_like(omega_e), omega_e * ctx.model.psi_f]), theta_act)
        else:
            ff = jnp.zeros(2, error.dtype)
        v = self.kp * error + resonant + ff
        u_ab = clip_magnitude(ctx.u_max)(v)
        # Back-calculation: the limiter's excess enters the resonators' input (tracking time Kp/Ki).
        error_r = error + (u_ab - v) / self.kp if self.anti_windup else error
        new_state = jnp.sum(state[:, None, :] * co.Ad, axis=-1) + error_r[:, None] * co.Bd
        return new_state, u_ab, park(u_ab, theta_act)


def pr_design(motor: PMSMParameters, bandwidth_rad_s=1100.0, w_c=2.0, **options) -> ProportionalResonant:
    """PR gains equivalent to the internal-model dq PI of bandwidth ``a_c`` (rad/s).

    ``Kp = a_c L`` with ``L = (L_d + L_q)/2`` (the stationary-frame mean inductance; ``L_d = L_q`` for the
    book's surface machine, where this is the PI's ``Kp``), and ``Kr = a_c R / w_c`` so that the resonant
    path's integral action near ``w_0``, ``Kr w_c``, equals the PI's ``Ki = a_c R`` (module docstring:
    the PR is the stationary-frame synchronous PI with a leak ``w_c``; Zmood & Holmes 2003). ``w_c``
    (rad/s, default 2) sets the finite resonant peak ``Kp + Ki/w_c``: with the back-EMF feed-forward the
    remaining steady voltage at 1000 r/min and 9.9 A is about 24 V, so the fundamental error is about
    24 V / 533 V/A = 0.045 A, 0.45 % (w_c = 5 would give 1.1 %). ``options`` go to
    [`ProportionalResonant`][pmsmjax.controllers.pr.ProportionalResonant] (``discretisation``, ``phase_lead``,
    ``back_emf_feedforward``).
    """
    check_positive("current-loop bandwidth a_c", bandwidth_rad_s, "rad/s")
    check_positive("resonator damping w_c", w_c, "rad/s")
    a_c = jnp.asarray(bandwidth_rad_s, motor.R.dtype)
    w_c = jnp.asarray(w_c, motor.R.dtype)
    return ProportionalResonant(
        kp=a_c * 0.5 * (motor.L_d + motor.L_q), kr=a_c * motor.R / w_c, w_c=w_c, **options
    )
