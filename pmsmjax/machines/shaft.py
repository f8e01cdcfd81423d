"""A compliant shaft: the motor and its load as two inertias joined by a torsional spring and damper.

**Equations** (mechanical angles and speeds; the motor side is where the drive's speed sensor sits):

- ``J_m dw_m/dt = T_e - B w_m - T_s`` (the motor: its own inertia ``J_m``, the machine's ``J``, and its
  viscous friction ``B``),
- ``J_L dw_L/dt = T_s - T_L`` (the load: its inertia ``J_L`` and the load torque ``T_L``),
- ``dphi/dt = w_m - w_L``, ``T_s = K phi + D (w_m - w_L)`` (the shaft's twist ``phi``, its torsional
  stiffness ``K`` and damping ``D``).

The same two-inertia model as motulator's two-mass mechanics (``MechanicsTwoMass``: ``J_M``, ``J_L``,
``K_S``, ``C_S``) and the transmitted torque of MathWorks' Simscape Electrical *Mechanical Shaft* block,
``T = K int(w_m - w_l) dt + B (w_m - w_l)``.

**Frequencies** of the undamped shaft (``D = 0``): seen from the motor's torque, the speed ``w_m`` has a
*resonance* (a pole pair) at ``w_r = sqrt(K (J_m + J_L) / (J_m J_L))`` and an *anti-resonance* (a zero
pair: the load swinging against a motor that stands still) at ``w_a = sqrt(K / J_L)``; ``w_r / w_a =
sqrt(1 + J_L / J_m)``. The resonance is what a fast speed loop excites; a notch on the torque reference
(``pmsmjax.controllers.speed_filters``) takes the loop's gain away there.

**State.** [`MachineState.shaft`][pmsmjax.machines.base.MachineState] is ``(2,)`` ``[phi, w_L]`` (rad, rad/s)
when the motor's parameters carry a shaft (``load_inertia`` not None) and ``None`` otherwise, so a rigid drive
traces a program without any shaft state. ``phi`` is a twist of thousandths of a radian: held as
the difference itself, not as two large angles, so it keeps its resolution in float32.

**Energy.** ``d/dt (J_m w_m^2/2 + J_L w_L^2/2 + K phi^2/2) = T_e w_m - B w_m^2 - D (w_m - w_L)^2 - T_L w_L``
(tests/machines/test_shaft.py checks it to float rounding on every three-phase plant).
"""

import math

import jax.numpy as jnp

from pmsmjax._types import Array

__all__ = [
    "has_shaft",
    "initial_shaft_state",
    "two_mass_derivative",
    "shaft_torque",
    "resonance_rad_s",
    "anti_resonance_rad_s",
    "mechanical_energy",
]


def has_shaft(motor) -> bool:
    """Whether ``motor``'s parameters carry a compliant shaft (its ``load_inertia`` is not None)."""
    return getattr(motor, "load_inertia", None) is not None


def initial_shaft_state(omega_m, dtype) -> Array:
    """``(2,)`` ``[phi, w_L]``: an untwisted shaft, the load turning with the motor at ``omega_m`` (rad/s)."""
    omega = jnp.asarray(omega_m, dtype)
    return jnp.stack([jnp.zeros_like(omega), omega])


def shaft_torque(motor, omega_m, shaft) -> Array:
    """The torque the shaft transmits from the motor to the load, N m: ``K phi + D (w_m - w_L)``.

    Args:
        motor: Parameters with ``shaft_stiffness`` (N m/rad) and ``shaft_damping`` (N m s/rad).
        omega_m: Motor speed, rad/s.
        shaft: ``(2,)`` ``[phi, w_L]``, rad and rad/s.
    """
    return motor.shaft_stiffness * shaft[0] + motor.shaft_damping * (omega_m - shaft[1])


def two_mass_derivative(motor, torque, omega_m, shaft, load_torque) -> tuple[Array, Array]:
    """The two-inertia mechanics (module docstring).

    Args:
        motor: Parameters: ``J`` (the motor's own inertia, kg m^2), ``B`` (N m s/rad), ``load_inertia``
            (kg m^2), ``shaft_stiffness`` (N m/rad), ``shaft_damping`` (N m s/rad).
        torque: Electromagnetic torque, N m.
        omega_m: Motor speed, rad/s.
        shaft: ``(2,)`` ``[phi, w_L]``, rad and rad/s.
        load_torque: Load torque on the load side, N m.

    Returns:
        ``(dw_m/dt, d[phi, w_L]/dt)``: rad/s^2 and ``(2,)`` (rad/s, rad/s^2).
    """
    t_s = shaft_torque(motor, omega_m, shaft)
    domega_m = (torque - motor.B * omega_m - t_s) / motor.J
    domega_l = (t_s - load_torque) / motor.load_inertia
    return domega_m, jnp.stack([omega_m - shaft[1], domega_l])


def resonance_rad_s(motor_inertia, load_inertia, stiffness) -> float:
    """Resonance of the undamped two-mass shaft, rad/s: ``sqrt(K (J_m + J_L) / (J_m J_L))``.

    Args:
        motor_inertia: ``J_m``, kg m^2.
        load_inertia: ``J_L``, kg m^2.
        stiffness: ``K``, N m/rad.
    """
    return math.sqrt(stiffness * (motor_inertia + load_inertia) / (motor_inertia * load_inertia))


def anti_resonance_rad_s(load_inertia, stiffness) -> float:
    """Anti-resonance of the undamped two-mass shaft seen at the motor, rad/s: ``sqrt(K / J_L)``.

    Args:
        load_inertia: ``J_L``, kg m^2.
        stiffness: ``K``, N m/rad.
    """
    return math.sqrt(stiffness / load_inertia)


def mechanical_energy(motor, omega_m, shaft) -> Array:
    """Kinetic energy of both inertias plus the spring's, J: ``J_m w_m^2/2 + J_L w_L^2/2 + K phi^2/2``.

    Args:
        motor: Parameters with ``J``, ``load_inertia``, ``shaft_stiffness``.
        omega_m: Motor speed, rad/s.
        shaft: ``(2,)`` ``[phi, w_L]``.
    """
    return 0.5 * (
        motor.J * omega_m**2 + motor.load_inertia * shaft[1] ** 2 + motor.shaft_stiffness * shaft[0] ** 2
    )
