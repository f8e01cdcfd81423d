"""n-phase PMSM models in the natural frame and in VSD coordinates (the book, ch. 7; five phases:
ch. 10), for any [`PhaseLayout`][pmsmjax.frames.multiphase.PhaseLayout] (six phases by default).

Each model is written from its own frame's equations so that comparing them checks each:

- [`MultiPhasePMSMNatural`][pmsmjax.machines.pmsm_multiphase_natural.MultiPhasePMSMNatural]: ``n`` phase
  currents;
  flux ``psi = L(th) i + psi_PM(th)`` with
  ``L_xy = L_ls delta_xy + L_0m cos(g_x - g_y) + L_2m cos(2 th - g_x - g_y)`` (phase axes ``g``),
  ``psi_PM,x = psi_f cos(th - g_x)``, ``u = R i + dpsi/dt`` with the star-point voltages that keep each
  isolated star's current sum at zero; torque ``p_n dW'/dth_e`` of the co-energy by automatic differentiation.
  ``L_0m = (L_d + L_q - 2 L_ls)/n``, ``L_2m = (L_d - L_q)/n``.
- [`MultiPhasePMSMVSD`][pmsmjax.machines.pmsm_multiphase.MultiPhasePMSMVSD]: stationary VSD currents
  ``[alpha, beta, planes...]`` (the zero sequences of isolated stars are identically 0 and not states): the
  fundamental plane as the three-phase alpha-beta model (salient inductance matrix of ``L0 = (L_d + L_q)/2``,
  ``L2 = (L_d - L_q)/2``), every other plane ``u = R i + L_ls di/dt``: it sees only leakage and links no
  magnet flux, so it produces no torque. ``T_e = (n/2) p_n (psi_a i_b - psi_b i_a)``.
- [`MultiPhasePMSMdq`][pmsmjax.machines.pmsm_multiphase.MultiPhasePMSMdq]: ``[d, q, planes...]``: the
  fundamental in the rotor frame (the three-phase dq equations), the other planes stationary;
  ``T_e = (n/2) p_n [psi_f i_q + (L_d - L_q) i_d i_q]``. Its equations see the rotor angle only through the
  held stator-frame voltage, so it integrates with
  [`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance]'s rotating hold (the fast model
  for drives).

The block structure (the non-fundamental planes decoupled, leakage only) is a property of the natural
model, not an assumption of the test: the VSD of ``L(th)`` is block-diagonal because
``sum_k e^{j m g_k} = 0`` for the orders ``m`` that would couple the planes
(tests/machines/test_multiphase_machines.py checks it for six and five phases).

Asymmetric phase resistances (``resistance_scale``, ``(n,)`` factors of ``R``, default None: balanced)
model the unbalance that the z1-z2 current loops of chapter 9 exist to remove. The resistive voltage is
then computed through the phases, ``T_act diag(R k) T_act^-1 i`` (isolated stars: the zero-sequence rows
are absorbed by the star-point voltages), in every model. With it, the dq model loses its fast hold.

**Third-harmonic back-EMF** (``motor.psi_f3``, five phases, the book, ch. 10; None: left out). The
phase magnet flux gains ``psi_f3 cos(3 (th - g_x))``. Its VSD lies in the order-3 plane (five phases:
x-y) as ``psi_f3 [cos 3th, sin 3th]`` (``(2/n) sum_k cos(3 th - 3 g_k) e^{j 3 g_k} = e^{j 3 th}``), so that
plane gains the back-EMF ``3 w_e psi_f3 [-sin 3th, cos 3th]`` and the torque
``(n/2) p_n 3 psi_f3 (i_y cos 3th - i_x sin 3th)`` (co-energy derivative): x-y currents then make torque.
The natural model takes it in its flux (torque by the co-energy derivative, as above); the VSD model in
the x-y flux; the dq model (x-y stationary) as the two terms above, and then integrates with the angle
as a state (no rotating hold, no split advance).

Input: [`MachineInput`][pmsmjax.machines.base.MachineInput] with ``u`` of ``2 n_planes`` components: the
stationary VSD voltage ``[u_alpha, u_beta, u_z1, u_z2, ...]`` (``frame="stator"``), or
``[u_d, u_q, u_z1, u_z2, ...]`` with only the fundamental in the rotor frame (``frame="rotor"``).
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import SIX_PHASE, PhaseLayout, inverse_vsd_matrix, vsd_matrix
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.machines import dq_equations as dq
from pmsmjax.machines.base import AbstractMachine, MachineInput, MachineState, Mechanics
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm3 import _solve2, alpha_beta_inductance, alpha_beta_magnet_flux
from pmsmjax.spec.validation import ParameterError, check_positive

__all__ = [
    "AbstractMultiPhaseMachine",
    "MultiPhasePMSMVSD",
    "MultiPhasePMSMdq",
]


def _as_scale(scale):
    return None if scale is None else jnp.asarray(scale, dtype=jnp.result_type(float))


class AbstractMultiPhaseMachine(AbstractMachine):
    """An n-phase PMSM in one frame. ``n_phases`` is the layout's phase count.

    Adds to [`AbstractMachine`][pmsmjax.machines.base.AbstractMachine]:
    [`currents_to_vsd`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine.currents_to_vsd] /
    [`currents_from_vsd`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine.currents_from_vsd] (model
    frame <-> stationary VSD ``(2 n_planes,)`` [alpha, beta, z1, z2, ...], A),
    [`vsd_currents`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine.vsd_currents] and
    [`initial_state_vsd`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine.initial_state_vsd]; phase
    currents are the inverse VSD with zero sequences 0. Every frame's model takes the same fields.

    Args:
        motor: The motor's parameters.
        layout: The winding layout (static).
        mechanics: ``"dynamic"`` or ``"imposed"`` speed.
        resistance_scale: ``(n,)`` phase resistance factors, or ``None`` (balanced).
    """

    motor: MultiPhaseParameters
    layout: PhaseLayout = eqx.field(static=True, default=SIX_PHASE)
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    resistance_scale: Array | None = eqx.field(default=None, converter=_as_scale)

    def __check_init__(self):
        self._check()

    @property
    def n_phases(self) -> int:  # type: ignore[override]
        return self.layout.n

    def _check(self):
        self.layout.check()
        if self.motor.n_phases != self.layout.n:
            raise ParameterError(
                f"the motor has n_phases = {self.motor.n_phases} but the winding layout {self.layout.name!r} "
                f"has {self.layout.n} phases: give a MultiPhaseParameters(n_phases={self.layout.n}, ...)."
            )
        if self.resistance_scale is not None:
            if jnp.shape(self.resistance_scale)[-1:] != (self.layout.n,):
                raise ParameterError(
                    f"resistance_scale must have shape ({self.layout.n},) (one factor per phase), got "
                    f"{jnp.shape(self.resistance_scale)}."
                )
            check_positive("resistance_scale (phase resistance factors)", self.resistance_scale)
        if self.motor.psi_f3 is not None and 3 not in self.layout.harmonics:
            raise ParameterError(
                f"psi_f3 (third-harmonic PM flux) is modelled only for windings with an order-3 plane (five "
                f"phases: x-y); the layout {self.layout.name!r} has orders {self.layout.harmonics}: its "
                "third harmonic is zero sequence and makes no current with isolated stars. Give psi_f3=None."
            )

    @property
    def third_harmonic_plane(self) -> int:
        """Index of the first VSD component of the order-3 plane (five phases: 2, the x axis)."""
        return 2 * self.layout.harmonics.index(3)

    def third_harmonic_flux(self, theta_e) -> Array:
        """PM flux of the order-3 plane, ``psi_f3 [cos 3th, sin 3th]`` (requires ``psi_f3``).

        Args:
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(2,)`` flux, Wb.
        """
        return self.motor.psi_f3 * jnp.stack([jnp.cos(3.0 * theta_e), jnp.sin(3.0 * theta_e)])

    # --- frame conversions ---------------------------------------------------------------------
    @abc.abstractmethod
    def currents_to_vsd(self, currents: Array, theta_e: Array) -> Array:
        """Model-frame currents -> ``(2 n_planes,)`` stationary VSD currents, A."""

    @abc.abstractmethod
    def currents_from_vsd(self, i_vsd: Array, theta_e: Array) -> Array:
        """``(2 n_planes,)`` stationary VSD currents -> model-frame currents, A."""

    def currents_to_dq(self, currents, theta_e):
        return park(self.currents_to_vsd(currents, theta_e)[:2], theta_e)

    def currents_from_dq(self, i_dq, theta_e):
        rest = jnp.zeros(self.layout.n_active - 2, i_dq.dtype)
        return self.currents_from_vsd(jnp.concatenate([inverse_park(i_dq, theta_e), rest]), theta_e)

    def vsd_currents(self, state: MachineState) -> Array:
        """Stationary VSD currents of a state.

        Args:
            state: The machine's state.

        Returns:
            ``(2 n_planes,)`` currents [alpha, beta, z1, z2, ...], A.
        """
        return self.currents_to_vsd(state.currents, state.theta_e)

    def phase_currents(self, state: MachineState) -> Array:
        """Phase currents (the inverse VSD, zero sequences 0).

        Args:
            state: The machine's state.

        Returns:
            ``(n,)`` phase currents, A.
        """
        T_inv = jnp.asarray(inverse_vsd_matrix(self.layout)[:, : self.layout.n_active])
        return T_inv @ self.vsd_currents(state)

    def stationary_currents(self, state: MachineState) -> Array:
        return self.vsd_currents(state)[:2]

    def initial_state_vsd(self, i_vsd, omega_m=0.0, theta_e=0.0) -> MachineState:
        """State with the given stationary VSD currents, speed and angle.

        Args:
            i_vsd: ``(2 n_planes,)`` VSD currents, A.
            omega_m: Mechanical speed, rad/s.
            theta_e: Electrical rotor angle, rad.
        """
        dtype = self.motor.R.dtype
        theta = jnp.asarray(theta_e, dtype)
        return MachineState(
            self.currents_from_vsd(jnp.asarray(i_vsd, dtype), theta), jnp.asarray(omega_m, dtype), theta
        )

    # --- the resistive voltage, balanced or not -------------------------------------------------
    def resistive_voltage_vsd(self, i_vsd: Array) -> Array:
        """Resistive voltage of stationary VSD currents: ``R i`` when balanced,
        ``T_act diag(R k) T_act^-1 i`` with the phase factors ``k`` (module docstring).

        Args:
            i_vsd: ``(2 n_planes,)`` VSD currents, A.

        Returns:
            ``(2 n_planes,)`` voltage, V.
        """
        if self.resistance_scale is None:
            return self.motor.R * i_vsd
        m = self.layout.n_active
        T = jnp.asarray(vsd_matrix(self.layout)[:m], i_vsd.dtype)
        T_inv = jnp.asarray(inverse_vsd_matrix(self.layout)[:, :m], i_vsd.dtype)
        return T @ (self.motor.R * self.resistance_scale * (T_inv @ i_vsd))


class MultiPhasePMSMVSD(AbstractMultiPhaseMachine):
    """n-phase PMSM in stationary VSD coordinates; state ``(2 n_planes,)`` [alpha, beta, z1, z2, ...], A.

    Its fields are those of
    [`AbstractMultiPhaseMachine`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine].
    """

    def inductance(self, theta_e) -> Array:
        """``(2, 2)`` inductances of the fundamental (alpha-beta) plane at the electrical angle ``theta_e``
        (rad), H: [`alpha_beta_inductance`][pmsmjax.machines.pmsm3.alpha_beta_inductance]."""
        return alpha_beta_inductance(self.motor.L_d, self.motor.L_q, theta_e)

    def flux(self, currents, theta_e) -> Array:
        """Stator flux linkage in VSD coordinates.

        Args:
            currents: ``(2 n_planes,)`` VSD currents, A.
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(2 n_planes,)`` flux linkage, Wb.
        """
        psi_ab = self.inductance(theta_e) @ currents[:2] + alpha_beta_magnet_flux(self.motor.psi_f, theta_e)
        psi_rest = self.motor.L_ls * currents[2:]
        if self.motor.psi_f3 is not None:
            k = self.third_harmonic_plane - 2
            psi_rest = psi_rest.at[k : k + 2].add(self.third_harmonic_flux(theta_e))
        return jnp.concatenate([psi_ab, psi_rest])

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        _, dflux = jax.jvp(lambda th: self.flux(currents, th), (theta_e,), (jnp.ones_like(theta_e),))
        rhs = u.alpha_beta(theta_e) - self.resistive_voltage_vsd(currents) - omega_e * dflux
        return jnp.concatenate([_solve2(self.inductance(theta_e), rhs[:2]), rhs[2:] / self.motor.L_ls])

    def torque(self, currents, theta_e):
        psi = self.flux(currents, theta_e)
        torque = psi[0] * currents[1] - psi[1] * currents[0]
        if self.motor.psi_f3 is not None:
            # d/dth of i_xy . psi_f3 e^{j 3th} = 3 (psi_x i_y - psi_y i_x) (the leakage part cancels).
            k = self.third_harmonic_plane
            torque = torque + 3.0 * (psi[k] * currents[k + 1] - psi[k + 1] * currents[k])
        return self.motor.torque_factor * torque

    def currents_to_vsd(self, currents, theta_e):
        return currents

    def currents_from_vsd(self, i_vsd, theta_e):
        return i_vsd


class _Fundamental(AbstractMachine):
    """The fundamental (dq) subspace of
    [`MultiPhasePMSMdq`][pmsmjax.machines.pmsm_multiphase.MultiPhasePMSMdq] with the mechanics, on its own:
    the three-phase dq equations with the n-phase torque factor (for
    [`MultiPhasePMSMdq.split_advance`][pmsmjax.machines.pmsm_multiphase.MultiPhasePMSMdq.split_advance])."""

    motor: MultiPhaseParameters
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    angle_only_in_voltage: ClassVar[bool] = True

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        m, u_dq = self.motor, u.dq(theta_e)
        derivative = dq.linear_current_derivative(
            m.R, m.L_d, m.L_q, m.psi_f, omega_e, currents[0], currents[1], u_dq[0], u_dq[1]
        )
        return jnp.stack(derivative)

    def torque(self, currents, theta_e):
        m = self.motor
        return dq.linear_torque(m.torque_factor, m.psi_f, m.L_d, m.L_q, currents[0], currents[1])

    def currents_to_dq(self, currents, theta_e):
        return currents  # the state is already the dq currents

    def currents_from_dq(self, i_dq, theta_e):
        return i_dq


class MultiPhasePMSMdq(AbstractMultiPhaseMachine):
    """n-phase PMSM, fundamental in the rotor frame, other planes stationary; state ``(2 n_planes,)``
    [i_d, i_q, z1, z2, ...], A. The fast model for drives (module docstring).

    Balanced (``resistance_scale=None``), the planes after the fundamental are independent first-order
    systems ``L_ls di/dt = u - R i`` under a held voltage:
    [`split_advance`][pmsmjax.machines.pmsm_multiphase.MultiPhasePMSMdq.split_advance] integrates the
    fundamental and the mechanics with the rotating-hold RK4 of the three-phase dq model and those planes
    exactly (``i(t) = e^{-t R/L_ls} i(0) + (1 - e^{-t R/L_ls}) u/R``). The result is the same ODE's solution,
    at a per-period cost near the three-phase model's, where RK4 over the whole state costs about twice as
    much (docs/performance.md, "Six-phase and five-phase drives").

    Its fields are those of
    [`AbstractMultiPhaseMachine`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine].
    """

    @property
    def angle_only_in_voltage(self) -> bool:
        """The rotating-hold integration applies unless an asymmetric resistance or a third-harmonic
        back-EMF brings the angle in."""
        return self.resistance_scale is None and self.motor.psi_f3 is None

    @property
    def split_advance(self):
        """``(state, inputs, duration, n_substeps) -> state`` integrating the fundamental and the other
        planes separately (class docstring), or ``None`` when an unbalance couples them or a third-harmonic
        back-EMF drives the x-y plane."""
        if self.resistance_scale is not None or self.motor.psi_f3 is not None:
            return None

        def advance_split(state: MachineState, inputs: MachineInput, duration, n_substeps: int):
            from pmsmjax.machines.integrate import advance

            fundamental = _Fundamental(self.motor, self.mechanics)
            u = inputs.u
            sub = MachineState(state.currents[:2], state.omega_m, state.theta_e)
            sub = advance(
                fundamental, sub, MachineInput(u[:2], inputs.load_torque, inputs.frame), duration, n_substeps
            )
            m = self.motor
            decay = jnp.exp(-duration * m.R / m.L_ls)
            i_rest = decay * state.currents[2:] + (1.0 - decay) * u[2:] / m.R
            return MachineState(jnp.concatenate([sub.currents, i_rest]), sub.omega_m, sub.theta_e)

        return advance_split

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        m = self.motor
        i_d, i_q = currents[0], currents[1]
        u_m = u.dq(theta_e)
        if self.resistance_scale is None:
            r = m.R * currents
        else:
            i_vsd = jnp.concatenate([inverse_park(currents[:2], theta_e), currents[2:]])
            r_vsd = self.resistive_voltage_vsd(i_vsd)
            r = jnp.concatenate([park(r_vsd[:2], theta_e), r_vsd[2:]])
        did = (u_m[0] - r[0] + omega_e * m.L_q * i_q) / m.L_d
        diq = (u_m[1] - r[1] - omega_e * (m.L_d * i_d + m.psi_f)) / m.L_q
        u_rest = u_m[2:] - r[2:]
        if m.psi_f3 is not None:
            # Back-EMF of the third-harmonic flux in its (stationary) plane: d/dt psi_f3 e^{j 3th}.
            k = self.third_harmonic_plane - 2
            psi3 = self.third_harmonic_flux(theta_e)
            u_rest = u_rest.at[k : k + 2].add(-3.0 * omega_e * jnp.stack([-psi3[1], psi3[0]]))
        return jnp.concatenate([jnp.stack([did, diq]), u_rest / m.L_ls])

    def torque(self, currents, theta_e):
        m = self.motor
        i_d, i_q = currents[0], currents[1]
        torque = m.psi_f * i_q + (m.L_d - m.L_q) * i_d * i_q
        if m.psi_f3 is not None:
            k = self.third_harmonic_plane
            psi3 = self.third_harmonic_flux(theta_e)
            torque = torque + 3.0 * (psi3[0] * currents[k + 1] - psi3[1] * currents[k])
        return m.torque_factor * torque

    def currents_to_dq(self, currents, theta_e):
        return currents[:2]

    def currents_to_vsd(self, currents, theta_e):
        return jnp.concatenate([inverse_park(currents[:2], theta_e), currents[2:]])

    def currents_from_vsd(self, i_vsd, theta_e):
        return jnp.concatenate([park(i_vsd[:2], theta_e), i_vsd[2:]])
