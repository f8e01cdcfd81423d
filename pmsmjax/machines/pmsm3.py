"""Three-phase PMSM in the rotor (dq), stationary (alpha-beta) and natural (abc) frames.

Each model is written from its own frame's equations (the book, ch. 1) so that comparing them is an
independent check of each:

- [`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq]: ``u_d = R i_d + L_d di_d/dt - w_e L_q i_q``,
  ``u_q = R i_q + L_q di_q/dt + w_e (L_d i_d + psi_f)``; ``T_e = 1.5 p_n [psi_f i_q + (L_d - L_q) i_d i_q]``.
- [`PMSMAlphaBeta`][pmsmjax.machines.pmsm3.PMSMAlphaBeta]: flux ``psi = L_ab(th) i + psi_f [cos th, sin th]``
  with ``L_ab = [[L0 + L2 cos 2th, L2 sin 2th], [L2 sin 2th, L0 - L2 cos 2th]]``, ``u = R i + dpsi/dt``,
  ``T_e = 1.5 p_n (psi_a i_b - psi_b i_a)``.
- [`PMSMabc`][pmsmjax.machines.pmsm3.PMSMabc]: flux ``psi = L_abc(th) i + psi_PM,abc(th)`` with self/mutual
  inductances ``L_xy = L_l delta_xy + L_0m cos(phi_x - phi_y) + L_2m cos(2 th - phi_x - phi_y)``
  (phase axes phi = 0, 2pi/3, -2pi/3), ``u = R i + dpsi/dt``; torque from the co-energy
  ``T_e = p_n dW'/dth_e``, ``W' = 1/2 i^T L i + i^T psi_PM``, taken by automatic differentiation.
  ``L_d = L_l + 1.5 (L_0m + L_2m)``, ``L_q = L_l + 1.5 (L_0m - L_2m)``.

In the flux-based models ``dpsi/dt = L(th) di/dt + w_e dpsi/dth``; the angle derivative of the flux is
taken with ``jax.jvp`` so the EMF and reluctance terms cannot be mis-derived by hand.

Each model takes optional ``harmonics`` ([`MagnetHarmonics`][pmsmjax.machines.harmonics.MagnetHarmonics]:
magnet flux harmonics and cogging torque), written in the model's own frame: the abc model adds them to
``psi_PM,abc`` (its co-energy torque then includes them), the alpha-beta model to its magnet flux with the
torque ``1.5 p i . dpsi_h,ab/dth``, the dq model the rotor-frame EMF ``w_e eps_dq`` and torque
``1.5 p i_dq . eps_dq``; each adds the cogging torque to ``torque``. ``None`` (default): the program is the
sinusoidal machine's.
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta, alpha_beta_to_abc, inverse_park, park
from pmsmjax.machines import dq_equations as dq
from pmsmjax.machines.base import AbstractMachine, MachineInput, Mechanics
from pmsmjax.machines.harmonics import MagnetHarmonics, stator_axis
from pmsmjax.machines.motor import PMSMParameters, as_float

# NumPy float64 at import; converted where used so the JAX precision mode of that moment applies.
_PHASE_AXES = np.array([0.0, 2.0 * np.pi / 3.0, -2.0 * np.pi / 3.0])


def _solve2(L: Array, b: Array) -> Array:
    """Solve a 2x2 linear system in closed form (cheaper than LAPACK inside a scan)."""
    det = L[0, 0] * L[1, 1] - L[0, 1] * L[1, 0]
    return jnp.stack([L[1, 1] * b[0] - L[0, 1] * b[1], L[0, 0] * b[1] - L[1, 0] * b[0]]) / det


def alpha_beta_inductance(L_d, L_q, theta_e) -> Array:
    """``(2, 2)`` stationary-frame inductance matrix ``L_ab(th)``, H, of a machine with ``L_d``, ``L_q`` (H)
    at the electrical angle ``theta_e`` (rad): the module docstring's ``L_ab``."""
    L0, L2 = 0.5 * (L_d + L_q), 0.5 * (L_d - L_q)
    c2, s2 = jnp.cos(2.0 * theta_e), jnp.sin(2.0 * theta_e)
    return jnp.stack([jnp.stack([L0 + L2 * c2, L2 * s2]), jnp.stack([L2 * s2, L0 - L2 * c2])])


def alpha_beta_magnet_flux(psi_f, theta_e) -> Array:
    """``(2,)`` PM flux in the stationary frame, ``psi_f [cos th, sin th]``, Wb."""
    return psi_f * jnp.stack([jnp.cos(theta_e), jnp.sin(theta_e)])


class AbstractPMSMdq(AbstractMachine):
    """A three-phase PMSM in the rotor frame, state currents ``(2,)`` = [i_d, i_q], A: the frame
    conversions and the linear (unsaturated) equations that [`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq] and
    [`SaturatedPMSMdq`][pmsmjax.machines.saturation.SaturatedPMSMdq] share.

    Its equations see the rotor angle only through the voltage (a stator-frame voltage read in the rotor
    frame), which lets [`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance] rotate that
    voltage by small angle increments instead of evaluating trigonometry at every RK4 stage. Its concrete
    classes hold the motor's parameters and the mechanics (``"dynamic"`` or ``"imposed"`` speed).
    """

    angle_only_in_voltage: ClassVar[bool] = True

    def linear_current_derivative(self, currents, theta_e, omega_e, u: MachineInput) -> Array:
        """``d[i_d, i_q]/dt`` of the linear machine, A/s (the module docstring's rotor-frame equations)."""
        m, u_dq = self.motor, u.dq(theta_e)
        derivative = dq.linear_current_derivative(
            m.R, m.L_d, m.L_q, m.psi_f, omega_e, currents[0], currents[1], u_dq[0], u_dq[1]
        )
        return jnp.stack(derivative)

    def linear_torque(self, currents) -> Array:
        """Electromagnetic torque of the linear machine, N m (the module docstring's ``T_e``)."""
        m = self.motor
        i_d, i_q = currents[0], currents[1]
        return dq.linear_torque(dq.torque_factor(m.pole_pairs), m.psi_f, m.L_d, m.L_q, i_d, i_q)

    def currents_to_dq(self, currents, theta_e):
        return currents

    def currents_from_dq(self, i_dq, theta_e):
        return i_dq


class PMSMdq(AbstractPMSMdq):
    """PMSM in the rotor frame; state currents ``(2,)`` = [i_d, i_q], A. Surface or salient (the equations
    of [`AbstractPMSMdq`][pmsmjax.machines.pmsm3.AbstractPMSMdq]).

    **Arguments:** `motor` ([`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters]); `mechanics`:
    ``"dynamic"`` or ``"imposed"`` speed; `harmonics`: magnet flux harmonics and cogging torque
    ([`MagnetHarmonics`][pmsmjax.machines.harmonics.MagnetHarmonics]), ``None`` for none.
    """

    motor: PMSMParameters
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    harmonics: MagnetHarmonics | None = None

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        h = self.harmonics
        if h is None or not h.has_flux:
            return self.linear_current_derivative(currents, theta_e, omega_e, u)
        # the harmonics' rotor-frame EMF w_e eps_dq, taken off the voltage; on scalars, not on stacked
        # vectors, so that XLA fuses each stage's arithmetic once (docs/performance.md, "Ripple")
        m, u_dq = self.motor, u.dq(theta_e)
        e_d, e_q, _ = h.rotor_terms(theta_e, u.angle_cos_sin())
        u_d, u_q = u_dq[0] - omega_e * e_d, u_dq[1] - omega_e * e_q
        derivative = dq.linear_current_derivative(
            m.R, m.L_d, m.L_q, m.psi_f, omega_e, currents[0], currents[1], u_d, u_q
        )
        return jnp.stack(derivative)

    def torque(self, currents, theta_e):
        return self._torque(currents, theta_e, None)

    def stator_axis(self, theta_e):
        """``[cos theta_e, -sin theta_e]`` with harmonics (their terms are read from it,
        [`MagnetHarmonics.rotor_terms`][pmsmjax.machines.harmonics.MagnetHarmonics.rotor_terms]), ``None``
        without."""
        return None if self.harmonics is None else stator_axis(theta_e)

    def stage_torque(self, currents, theta_e, inputs: MachineInput):
        return self._torque(currents, theta_e, inputs.angle_cos_sin())

    def _torque(self, currents, theta_e, unit):
        if self.harmonics is None:
            return self.linear_torque(currents)
        return self.linear_torque(currents) + self.harmonics.dq_torque(
            currents, theta_e, self.motor.pole_pairs, unit
        )


class PMSMAlphaBeta(AbstractMachine):
    """PMSM in the stationary frame; state currents ``(2,)`` = [i_alpha, i_beta], A.

    Args:
        motor: The motor's parameters.
        mechanics: ``"dynamic"`` or ``"imposed"`` speed.
        harmonics: Magnet flux harmonics and cogging torque, or ``None``.
    """

    motor: PMSMParameters
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    harmonics: MagnetHarmonics | None = None

    def inductance(self, theta_e) -> Array:
        """Alpha-beta inductance matrix at an electrical angle.

        Args:
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(2, 2)`` inductances, H.
        """
        return alpha_beta_inductance(self.motor.L_d, self.motor.L_q, theta_e)

    def flux(self, currents, theta_e) -> Array:
        """Stator flux linkage.

        Args:
            currents: ``(2,)`` alpha-beta currents, A.
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(2,)`` flux linkage, Wb.
        """
        flux = self.inductance(theta_e) @ currents + alpha_beta_magnet_flux(self.motor.psi_f, theta_e)
        if self.harmonics is not None and self.harmonics.has_flux:
            flux = flux + self.harmonics.flux_alpha_beta(theta_e)[0]
        return flux

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        _, dflux_dtheta = jax.jvp(lambda th: self.flux(currents, th), (theta_e,), (jnp.ones_like(theta_e),))
        rhs = u.alpha_beta(theta_e) - self.motor.R * currents - omega_e * dflux_dtheta
        return _solve2(self.inductance(theta_e), rhs)

    def torque(self, currents, theta_e):
        p, h = self.motor.pole_pairs, self.harmonics
        if h is None:
            psi = self.flux(currents, theta_e)
            return 1.5 * p * (psi[0] * currents[1] - psi[1] * currents[0])
        # the sinusoidal machine's torque, plus the harmonics' 1.5 p i . dpsi_h/dth and the cogging torque
        psi = self.inductance(theta_e) @ currents + alpha_beta_magnet_flux(self.motor.psi_f, theta_e)
        torque = 1.5 * p * (psi[0] * currents[1] - psi[1] * currents[0]) + h.cogging_torque(theta_e)
        if h.has_flux:
            torque = torque + 1.5 * p * (currents @ h.flux_alpha_beta(theta_e)[1])
        return torque

    def currents_to_dq(self, currents, theta_e):
        return park(currents, theta_e)

    def currents_from_dq(self, i_dq, theta_e):
        return inverse_park(i_dq, theta_e)


class PMSMabc(AbstractMachine):
    """PMSM in the natural frame; state currents ``(3,)`` = [i_a, i_b, i_c], A (star, isolated neutral).

    Args:
        motor: The motor's parameters.
        leakage_inductance: Per-phase leakage ``L_l``, H; it is also the zero-sequence inductance. It does
            not affect balanced operation; the default (``None``) is a tenth of ``min(L_d, L_q)``.
        mechanics: ``"dynamic"`` or ``"imposed"`` speed.
        harmonics: Magnet flux harmonics and cogging torque, or ``None``.
    """

    motor: PMSMParameters
    leakage_inductance: Array
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    harmonics: MagnetHarmonics | None = None

    def __init__(
        self,
        motor: PMSMParameters,
        leakage_inductance=None,
        mechanics: Mechanics = "dynamic",
        harmonics: MagnetHarmonics | None = None,
    ):
        self.motor = motor
        if leakage_inductance is None:
            leakage_inductance = 0.1 * jnp.minimum(motor.L_d, motor.L_q)
        self.leakage_inductance = as_float(leakage_inductance)
        self.mechanics = mechanics
        self.harmonics = harmonics

    def inductance(self, theta_e) -> Array:
        """Phase inductance matrix ``L_abc(theta_e)``.

        Args:
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(3, 3)`` inductances, H.
        """
        m = self.motor
        L_l = self.leakage_inductance
        L_0m = (m.L_d + m.L_q - 2.0 * L_l) / 3.0
        L_2m = (m.L_d - m.L_q) / 3.0
        phi_x, phi_y = _PHASE_AXES[:, None], _PHASE_AXES[None, :]
        return (
            L_l * jnp.eye(3) + L_0m * jnp.cos(phi_x - phi_y) + L_2m * jnp.cos(2.0 * theta_e - phi_x - phi_y)
        )

    def magnet_flux(self, theta_e) -> Array:
        """PM flux linked by each phase.

        Args:
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(3,)`` flux linkages, Wb.
        """
        flux = self.motor.psi_f * jnp.cos(theta_e - _PHASE_AXES)
        if self.harmonics is not None and self.harmonics.has_flux:
            flux = flux + self.harmonics.flux_abc(theta_e)
        return flux

    def flux(self, currents, theta_e) -> Array:
        """Phase flux linkages.

        Args:
            currents: ``(3,)`` phase currents, A.
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(3,)`` flux linkages, Wb.
        """
        return self.inductance(theta_e) @ currents + self.magnet_flux(theta_e)

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        _, dflux_dtheta = jax.jvp(lambda th: self.flux(currents, th), (theta_e,), (jnp.ones_like(theta_e),))
        u_abc = alpha_beta_to_abc(u.alpha_beta(theta_e))
        rhs = u_abc - self.motor.R * currents - omega_e * dflux_dtheta
        return jnp.linalg.solve(self.inductance(theta_e), rhs)

    def torque(self, currents, theta_e):
        def coenergy(th):
            return 0.5 * currents @ self.inductance(th) @ currents + currents @ self.magnet_flux(th)

        torque = self.motor.pole_pairs * jax.grad(coenergy)(theta_e)
        if self.harmonics is not None:
            torque = torque + self.harmonics.cogging_torque(theta_e)
        return torque

    def currents_to_dq(self, currents, theta_e):
        return park(abc_to_alpha_beta(currents), theta_e)

    def currents_from_dq(self, i_dq, theta_e):
        return alpha_beta_to_abc(inverse_park(i_dq, theta_e))
