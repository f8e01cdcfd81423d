"""Vector control of the multi-phase PMSM: the dual three-phase machine (the book, ch. 9) and the
five-phase machine (ch. 10), the FOC cascade with an n-phase current loop.

[`MultiPhaseFOC`][pmsmjax.controllers.multiphase.MultiPhaseFOC] is the cascade of
[`FOC`][pmsmjax.controllers.foc.FOC] (the same d-axis reference and speed loop,
[`cascade_references`][pmsmjax.controllers.foc.cascade_references]) whose current loop reads all six phase
currents and commands the four-vector ``[u_alpha, u_beta, u_z1, u_z2]`` (V) that the six-phase modulators take
([`pmsmjax.inverters.multiphase_svpwm`][pmsmjax.inverters.multiphase_svpwm]). Its current blocks
([`AbstractMultiPhaseCurrentController`][pmsmjax.controllers.multiphase.AbstractMultiPhaseCurrentController]):

- [`VSDCurrentControl`][pmsmjax.controllers.multiphase.VSDCurrentControl]: the fundamental (alpha-beta -> dq)
  loop is any three-phase current block (the dq PI of [`current_pi`][pmsmjax.controllers.current_pi], the PR
  of [`pr`][pmsmjax.controllers.pr]) on the VSD alpha-beta currents, plus a z1-z2 block on the z1-z2 currents
  ``vsd(i_phase)[2:4]``. With ``z=None`` the z1-z2 voltage is zero: the **conventional** scheme (z open loop;
  any unbalance or inverter non-ideality drives z1-z2 currents limited only by ``R + j w L_ls``). With
  [`ZCurrentPI`][pmsmjax.controllers.multiphase.ZCurrentPI] it is the **VSD** scheme; with
  [`ZProportionalResonant`][pmsmjax.controllers.multiphase.ZProportionalResonant] (and the PR fundamental
  block) the **stationary-frame PR** scheme.
- [`DoubleDQCurrentPI`][pmsmjax.controllers.multiphase.DoubleDQCurrentPI]: the **double dq** scheme: four PIs
  on ``[i_d1, i_q1, i_d2, i_q2]`` (each set's own Park,
  [`pmsmjax.frames.multiphase.double_dq`][pmsmjax.frames.multiphase.double_dq]) with cross-coupling
  compensation.

**z1-z2 PI frame.** Unbalance between the two sets (unequal resistances, gains, dead times) puts a
fundamental-frequency current in z1-z2 that rotates *backwards* (``conj(i_ab1 - i_ab2)/2``). In the frame
rotating at ``-w_e`` ([`z_to_counter_rotating`][pmsmjax.frames.multiphase.z_to_counter_rotating]) it is
constant, so a PI there removes it with zero steady-state error (Che et al., "Current control methods for an
asymmetrical six-phase induction motor drive", IEEE TPEL 29(1), 2014). Its plant in that frame is
``u' = R i' + L_ls di'/dt - j w_e L_ls i'``: internal-model gains ``Kp = a_z L_ls``, ``Ki = a_z R`` and
the decoupling ``-j w_e L_ls i'``, the same structure as the dq loop.

**Equivalence (book 9.5).** By the linear relation ``[dq, z'] = M [dq1, dq2]``
([`DOUBLE_DQ_TO_VSD`][pmsmjax.frames.multiphase.DOUBLE_DQ_TO_VSD]), the VSD scheme with dq gains
``(Kp_dq, Ki)`` and z' gains ``(Kp_z, Ki)`` *is* a double-dq controller whose set-k output is
``((Kp_dq + Kp_z)/2) e_k + ((Kp_dq - Kp_z)/2) e_other + integral + decoupling``. With the internal-model
gains the self gain is ``a_c (L_d + L_ls)/2 = a_c L_self`` (the set's own inductance: the double-dq loop's
own design) and the cross gain ``a_c (L_d - L_ls)/2 = a_c M`` is the cross-coupling compensation: the
mutual voltage ``M di_other/dt`` with the other loop's demand ``di_other/dt = a_c e_other``. The speed
voltages ``w_e psi_k`` of each set, mutual flux included, are the decoupling.
[`double_dq_design`][pmsmjax.controllers.multiphase_design.double_dq_design] builds that controller;
tests/controllers/test_multiphase_control.py shows both give the same response (and that without the
cross-coupling compensation they do not).

**Prediction and integral action in z1-z2.** With a computational delay the loops act on the current
predicted one period ahead by the controller's model (delay compensation, as
[`current_pi`][pmsmjax.controllers.current_pi]). Any voltage the model lacks biases that prediction by
``Ts u_unmodelled / L``; through the small leakage ``L_ls`` it is large (``Ts/L_ls = 0.76 A/V`` on the
six-phase preset): with the integral on the predicted current, a PI holds the *predicted* current at zero and
leaves the measured one off by that bias (on the preset with set UVW's resistance 1.5 times ABC's at 1000
r/min and 10 N m: 0.83 A of z1-z2 current left from the 1.97 A of open-loop z1-z2). So the z1-z2 PI integrates
the *measured* current (its proportional path and decoupling use the prediction): zero steady-state error for
any constant z1-z2 disturbance. The double-dq scheme integrates the same thing in its coordinates: the
measured difference between the sets and the predicted mean (the dq loop of the VSD scheme,
[`CurrentLoopGains`][pmsmjax.controllers.current_pi.CurrentLoopGains], integrates its prediction, as for three
phases).

**Five phases (the book, ch. 10).** The same cascade drives the five-phase machine: the VSD current block
takes the winding ``layout`` ([`FIVE_PHASE`][pmsmjax.frames.multiphase.FIVE_PHASE]: the second plane is x-y),
and the x-y PI's frame is a static choice, ``rotation``: the frame at ``rotation theta_e``. Six phases use
``-1`` (the counter-rotating frame above); five phases ``+3``, the third-harmonic synchronous frame, in
which the x-y disturbances of a five-phase drive are constant: a third-harmonic back-EMF
(``psi_f3 e^{j 3 th}``, [`pmsmjax.machines.pmsm_multiphase`][pmsmjax.machines.pmsm_multiphase]) and the third
harmonic of dead-time voltage errors (phase harmonic 3 maps into x-y). In the frame at ``r theta_e`` the plant
is ``u' = R i' + L_ls di'/dt + j r w_e L_ls i'``: the same internal-model gains, decoupling
``j r w_e L_ls i'``. [`MultiPhaseFOC`][pmsmjax.controllers.multiphase.MultiPhaseFOC] checks that the model's
phase count is the current block's layout's.

Voltage limits: the dq (or each set's dq) command is limited to the modulator's linear limit ``u_max``;
the z1-z2 command to ``z_limit_fraction u_max`` (it shares the DC link with the fundamental; small z1-z2
voltages suffice, the subspace's impedance being only ``R + j w L_ls``).
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import (
    AbstractCurrentController,
)
from pmsmjax.controllers.current_pi import angle_lead
from pmsmjax.controllers.foc import AbstractFOC
from pmsmjax.controllers.pi import clip_magnitude
from pmsmjax.controllers.pr import (
    DISCRETISATIONS,
    Discretisation,
    resonant_coefficients,
)
from pmsmjax.frames.multiphase import (
    SIX_PHASE,
    PhaseLayout,
    double_dq,
    double_dq_to_vsd,
    vsd,
    z_from_counter_rotating,
    z_to_counter_rotating,
)
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.machines.motor import as_float
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm6 import double_dq_current_rate, double_dq_flux
from pmsmjax.signals import Sample
from pmsmjax.spec.validation import (
    ParameterError,
    check_choice,
    check_nonnegative,
    check_positive,
)

__all__ = [
    "AbstractMultiPhaseCurrentController",
    "AbstractZCurrentController",
    "DoubleDQCurrentPI",
    "MultiPhaseFOC",
    "VSDCurrentControl",
    "ZCurrentPI",
    "ZProportionalResonant",
]


# --- interfaces -------------------------------------------------------------------------------------
class AbstractZCurrentController(eqx.Module):
    """z1-z2 current loop (reference 0): ``step(state, i_z, theta_e, omega_e, ctx) -> (state, u_z)``.

    `i_z (2,)` A: measured stationary z1-z2 currents; `theta_e` rad, `omega_e` rad/s: the estimate; `ctx`:
    the cascade's [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext] (``ctx.model`` a
    multi-phase [`MultiPhaseParameters`][pmsmjax.machines.multiphase_motor.MultiPhaseParameters]). Returns the
    stationary z1-z2 voltage command ``u_z (2,)`` V.
    """

    @abc.abstractmethod
    def init(self, dtype):
        """The z1-z2 loop's zero state (integrator or resonators, last command) of floating `dtype`."""

    @abc.abstractmethod
    def step(self, state, i_z, theta_e, omega_e, ctx):
        """One period: the z1-z2 voltage that drives the measured z1-z2 currents to zero.

        `i_z`: ``(2,)`` measured stationary z1-z2 (five phases: x-y) currents, A; `theta_e`: estimated
        electrical angle, rad; `omega_e`: estimated electrical speed, rad/s; `ctx`: the cascade's
        [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext]. Returns the new state and the
        stationary command ``u_z (2,)`` V, within the block's fraction of ``ctx.u_max``.
        """


class AbstractMultiPhaseCurrentController(eqx.Module):
    """Multi-phase current loop: ``step(state, i_dq_ref, i_phase, theta_e, omega_e, ctx)
    -> (state, u_vsd (4,), u_dq (2,))``.

    `i_dq_ref (2,)` A (the dq reference of the fundamental subspace; z1-z2 reference 0); `i_phase (n,)` A
    sampled phase currents; returns the stationary command ``[u_alpha, u_beta, u_z1, u_z2]`` V (with
    the angle lead that the PWM hold and the delay need) and its fundamental part in the rotor frame.
    ``layout``: the winding the loop serves ([`SIX_PHASE`][pmsmjax.frames.multiphase.SIX_PHASE],
    ``FIVE_PHASE``), whose phase count the cascade checks against its motor model's.
    """

    layout: eqx.AbstractVar[PhaseLayout]

    @abc.abstractmethod
    def init(self, dtype):
        """The current loop's zero state (every sub-block's integrators and memories) of floating `dtype`."""

    @abc.abstractmethod
    def step(self, state, i_dq_ref, i_phase, theta_e, omega_e, ctx):
        """One period: the multi-phase voltage command from the phase currents.

        `i_dq_ref`: ``(2,)`` fundamental dq current reference, A (the other planes' reference is 0);
        `i_phase`: ``(n,)`` sampled phase currents, A; `theta_e`: estimated electrical angle, rad;
        `omega_e`: estimated electrical speed, rad/s; `ctx`: the cascade's
        [`CurrentLoopContext`][pmsmjax.controllers.base.CurrentLoopContext]. Returns ``(state, u_vsd (4,) V,
        u_dq (2,) V)``: the stationary command ``[u_alpha, u_beta, u_z1, u_z2]`` (with the angle lead of the
        PWM hold and delay) and its fundamental part in the estimated rotor frame.
        """


# --- the controller ---------------------------------------------------------------------------------
class MultiPhaseFOC(AbstractFOC):
    """Cascaded FOC of the six- and five-phase machines (module docstring). The arguments are those of
    [`FOC`][pmsmjax.controllers.foc.FOC], with `current` a multi-phase current block and `model` the
    [`MultiPhaseParameters`][pmsmjax.machines.multiphase_motor.MultiPhaseParameters] of the block's phase
    count. Command: ``(4,)`` [u_alpha, u_beta, u_z1, u_z2] (five phases: [u_alpha, u_beta, u_x, u_y]), V."""

    model: MultiPhaseParameters
    current: AbstractMultiPhaseCurrentController

    def __check_init__(self):
        layout = self.current.layout
        if self.model.n_phases != layout.n:
            word = {5: "five", 6: "six"}.get(layout.n, f"{layout.n}")
            raise ParameterError(
                f"MultiPhaseFOC with a {word}-phase current block needs a {word}-phase motor model "
                f"(MultiPhaseParameters with n_phases = {layout.n}), got {type(self.model).__name__}: use "
                f"pmsmjax.presets.{word}_phase.{word}_phase_motor()."
            )

    def measured_currents(self, sample: Sample) -> Array:
        """The ``(n,)`` sampled phase currents, A: the multi-phase current block splits them itself."""
        return sample.i_phase


# --- VSD: fundamental block + z1-z2 block -----------------------------------------------------------
class VSDCurrentControl(AbstractMultiPhaseCurrentController):
    """VSD current control: `dq` a three-phase current block on the alpha-beta subspace, `z` a block on the
    second plane (six phases: z1-z2; five phases: x-y) or ``None`` (conventional control: that voltage 0).
    `layout` (static, default six phases): the winding whose VSD splits the phase currents; it must have
    two planes. State ``(dq state, z state)``."""

    dq: AbstractCurrentController
    z: AbstractZCurrentController | None = None
    layout: PhaseLayout = eqx.field(static=True, default=SIX_PHASE)

    def __check_init__(self):
        if self.layout.n_planes != 2:
            raise ParameterError(
                f"VSDCurrentControl controls two planes (alpha-beta and one more); the layout "
                f"{self.layout.name!r} has {self.layout.n_planes}."
            )

    def init(self, dtype):
        return (self.dq.init(dtype), None if self.z is None else self.z.init(dtype))

    def step(self, state, i_dq_ref, i_phase, theta_e, omega_e, ctx):
        i_vsd = vsd(i_phase, self.layout)
        dq_state, u_ab, u_dq = self.dq.step(state[0], i_dq_ref, i_vsd[:2], theta_e, omega_e, ctx)
        if self.z is None:
            z_state, u_z = None, jnp.zeros(2, u_ab.dtype)
        else:
            z_state, u_z = self.z.step(state[1], i_vsd[2:4], theta_e, omega_e, ctx)
        return (dq_state, z_state), jnp.concatenate([u_ab, u_z]), u_dq


class ZCurrentPI(AbstractZCurrentController):
    """z1-z2 PI in the frame rotating at ``-w_e`` (module docstring), with decoupling and, with a
    computational delay, prediction of the current one period ahead (as
    [`current_pi`][pmsmjax.controllers.current_pi]).

    **Arguments:** `kp` V/A, `ki` V/(A s); `z_limit_fraction` (static): the command is limited to this
    fraction of the modulator's linear limit; `rotation` (static int, default -1): the PI's frame is at
    ``rotation theta_e`` (-1: counter-rotating, six phases; +3: five phases' x-y, module docstring). State
    ``(integral (2,) V, last command (2,) V)`` in that frame.
    """

    kp: Array = eqx.field(converter=as_float)
    ki: Array = eqx.field(converter=as_float)
    z_limit_fraction: float = eqx.field(static=True, default=0.2)
    rotation: int = eqx.field(static=True, default=-1)

    def __check_init__(self):
        check_positive("ZCurrentPI.kp", self.kp, "V/A")
        check_nonnegative("ZCurrentPI.ki", self.ki, "V/(A s)")
        if not 0.0 < self.z_limit_fraction <= 1.0:
            raise ParameterError(f"z_limit_fraction must lie in (0, 1], got {self.z_limit_fraction}.")
        if not isinstance(self.rotation, int):
            raise ParameterError(
                f"ZCurrentPI.rotation must be an int (frame at rotation theta_e), got {self.rotation!r}."
            )

    def init(self, dtype):
        return (jnp.zeros(2, dtype), jnp.zeros(2, dtype))

    def _to_frame(self, x, theta_e):
        # -1 keeps the six-phase functions (and their arithmetic) exactly.
        if self.rotation == -1:
            return z_to_counter_rotating(x, theta_e)
        return park(x, self.rotation * theta_e)

    def _from_frame(self, x, theta_e):
        if self.rotation == -1:
            return z_from_counter_rotating(x, theta_e)
        return inverse_park(x, self.rotation * theta_e)

    def step(self, state, i_z, theta_e, omega_e, ctx):
        m = ctx.model
        integral, u_prev = state
        i_c = self._to_frame(i_z, theta_e)
        if ctx.delayed and ctx.delay_compensation:
            # d i'/dt = (u' - R i')/L_ls - j r w_e i' (the frame's own rotation; r = -1: + j w_e i').
            if self.rotation == -1:
                rotation = omega_e * jnp.stack([-i_c[1], i_c[0]])
            else:
                rotation = -self.rotation * omega_e * jnp.stack([-i_c[1], i_c[0]])
            i_ctrl = i_c + ctx.Ts * ((u_prev - m.R * i_c) / m.L_ls + rotation)
        else:
            i_ctrl = i_c
        if ctx.decoupling and self.rotation == -1:
            ff = omega_e * m.L_ls * jnp.stack([i_ctrl[1], -i_ctrl[0]])  # cancels -j w_e L_ls i'
        elif ctx.decoupling:
            ff = self.rotation * omega_e * m.L_ls * jnp.stack([-i_ctrl[1], i_ctrl[0]])  # j r w_e L_ls i'
        else:
            ff = jnp.zeros(2, i_c.dtype)
        # Proportional path on the predicted current, integral on the measured one (module docstring).
        v = self.kp * (-i_ctrl) + integral + ff
        u_c = clip_magnitude(self.z_limit_fraction * ctx.u_max)(v)
        integral = integral + ctx.Ts * self.ki * (-i_c) + (u_c - v)
        u_z = self._from_frame(u_c, theta_e + omega_e * angle_lead(ctx.Ts, ctx.delayed))
        return (integral, u_c), u_z


class ZProportionalResonant(AbstractZCurrentController):
    """z1-z2 proportional-resonant control in the stationary frame, resonant at ``w_e`` (a real-coefficient
    resonator acts on the backward-rotating unbalance as on a forward one): the z1-z2 counterpart of
    [`ProportionalResonant`][pmsmjax.controllers.pr.ProportionalResonant] (same discretisations, phase lead
    and back-calculation anti-windup; no feed-forward: z1-z2 links no magnet flux).

    **Arguments:** `kp` V/A, `kr` V/A, `w_c` rad/s; `discretisation`, `phase_lead` (static);
    `z_limit_fraction` (static). State ``(2, 2)`` resonator states, V.
    """

    kp: Array = eqx.field(converter=as_float)
    kr: Array = eqx.field(converter=as_float)
    w_c: Array = eqx.field(converter=as_float)
    discretisation: Discretisation = eqx.field(static=True, default="tustin-prewarp")
    phase_lead: bool = eqx.field(static=True, default=True)
    z_limit_fraction: float = eqx.field(static=True, default=0.2)

    def __check_init__(self):
        check_positive("ZProportionalResonant.kp", self.kp, "V/A")
        check_nonnegative("ZProportionalResonant.kr", self.kr, "V/A")
        check_positive("ZProportionalResonant.w_c", self.w_c, "rad/s")
        check_choice("ZProportionalResonant.discretisation", self.discretisation, DISCRETISATIONS)

    def init(self, dtype):
        return jnp.zeros((2, 2), dtype)

    def step(self, state, i_z, theta_e, omega_e, ctx):
        lead = angle_lead(ctx.Ts, ctx.delayed)
        phi = omega_e * lead if self.phase_lead else jnp.zeros_like(omega_e)
        co = resonant_coefficients(omega_e, self.w_c, self.kr, ctx.Ts, phi, self.discretisation)
        error = -i_z
        v = self.kp * error + state @ co.Cd + co.Dd * error
        u_z = clip_magnitude(self.z_limit_fraction * ctx.u_max)(v)
        error_r = error + (u_z - v) / self.kp  # back-calculation, tracking time Kp/Ki
        return state @ jnp.swapaxes(co.Ad, -1, -2) + error_r[:, None] * co.Bd, u_z


# --- double dq --------------------------------------------------------------------------------------
def _double_dq_derivative(m, i_dd, u_dd, omega_e):
    """d i_dd/dt (A/s) of the double-dq model under ``u_dd (4,)`` V
    ([`pmsmjax.machines.pmsm6`][pmsmjax.machines.pmsm6])."""
    psi = double_dq_flux(m, i_dd)
    dpsi = u_dd - m.R * i_dd - omega_e * jnp.stack([-psi[1], psi[0], -psi[3], psi[2]])
    return double_dq_current_rate(m, dpsi)


class DoubleDQCurrentPI(AbstractMultiPhaseCurrentController):
    """Double-dq current control: one dq PI pair per set, cross-coupling compensation (module docstring).

    **Arguments:** `kp_d`, `kp_q` V/A and `ki_d`, `ki_q` V/(A s): each set's PIs (the same for both sets);
    `kc_d`, `kc_q` V/A: cross-coupling compensation, set k's output gains ``kc e_other`` (the mutual
    voltage ``M di_other/dt`` with the other loop's demand ``a_c e_other``; 0 switches it off).
    Each set's reference is the dq reference (equal sharing, z1-z2 reference 0); each set's voltage is
    limited to ``u_max``. With decoupling: each set's speed voltage ``w_e J psi_k``, mutual flux
    included. With a computational delay and delay compensation: the set currents predicted one period
    ahead with the double-dq model. State ``(integral (4,) V, last command (4,) V)``.
    """

    kp_d: Array = eqx.field(converter=as_float)
    kp_q: Array = eqx.field(converter=as_float)
    ki_d: Array = eqx.field(converter=as_float)
    ki_q: Array = eqx.field(converter=as_float)
    kc_d: Array = eqx.field(converter=as_float)
    kc_q: Array = eqx.field(converter=as_float)
    layout: ClassVar[PhaseLayout] = SIX_PHASE  # two three-phase sets: the dual three-phase machine only

    def init(self, dtype):
        return (jnp.zeros(4, dtype), jnp.zeros(4, dtype))

    def step(self, state, i_dq_ref, i_phase, theta_e, omega_e, ctx):
        m = ctx.model
        integral, u_prev = state
        i_dd = double_dq(i_phase, theta_e)
        if ctx.delayed and ctx.delay_compensation:
            i_ctrl = i_dd + ctx.Ts * _double_dq_derivative(m, i_dd, u_prev, omega_e)
        else:
            i_ctrl = i_dd
        ref = jnp.tile(i_dq_ref, 2)
        error = ref - i_ctrl
        cross = jnp.stack([self.kc_d, self.kc_q, self.kc_d, self.kc_q]) * jnp.roll(error, 2)
        if ctx.decoupling:
            psi = double_dq_flux(m, i_ctrl)
            ff = omega_e * jnp.stack([-psi[1], psi[0], -psi[3], psi[2]])
        else:
            ff = jnp.zeros(4, i_dd.dtype)
        kp = jnp.stack([self.kp_d, self.kp_q, self.kp_d, self.kp_q])
        ki = jnp.stack([self.ki_d, self.ki_q, self.ki_d, self.ki_q])
        v = kp * error + integral + ff + cross
        u_dd = clip_magnitude(ctx.u_max)(v.reshape(2, 2)).reshape(4)
        # The integral acts on the predicted sets' mean and the measured sets' difference (module docstring:
        # the same integral as the VSD scheme's, whose z1-z2 PI integrates the measured current).
        difference = 0.5 * (error - jnp.roll(error, 2)) - 0.5 * ((ref - i_dd) - jnp.roll(ref - i_dd, 2))
        integral = integral + ctx.Ts * ki * (error - difference) + (u_dd - v)
        theta_act = theta_e + omega_e * angle_lead(ctx.Ts, ctx.delayed)
        x = double_dq_to_vsd(u_dd, theta_act)  # [d, q, z1, z2], z1-z2 stationary at the acting angle
        return (integral, u_dd), jnp.concatenate([inverse_park(x[:2], theta_act), x[2:]]), x[:2]


# --- design rules -----------------------------------------------------------------------------------
