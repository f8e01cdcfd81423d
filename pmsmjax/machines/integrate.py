"""Fixed-step integration of a machine over an interval with a held input."""

import jax
import numpy as np

from ..frames import wrap_angle
from .base import AbstractMachine, MachineInput, MachineState


def rk4_step(machine: AbstractMachine, state: MachineState, inputs: MachineInput, h) -> MachineState:
    """One classical Runge-Kutta step of length ``h`` (s)."""
    f = lambda x: machine.vector_field(None, x, inputs)
    add = lambda x, k, a: jax.tree.map(lambda xi, ki: xi + a * ki, x, k)
    k1 = f(state)
    k2 = f(add(state, k1, 0.5 * h))
    k3 = f(add(state, k2, 0.5 * h))
    k4 = f(add(state, k3, h))
    return jax.tree.map(
        lambda x, a, b, c, d: x + (h / 6.0) * (a + 2.0 * b + 2.0 * c + d), state, k1, k2, k3, k4
    )


def advance(
    machine: AbstractMachine, state: MachineState, inputs: MachineInput, duration, n_substeps: int
) -> MachineState:
    """Integrate over ``duration`` (s) with ``n_substeps`` RK4 steps; the angle is wrapped at the end.

    Wrapping only at the interval end keeps every RK4 stage on a continuous angle.
    """
    h = duration / n_substeps
    body = lambda _, x: rk4_step(machine, x, inputs, h)
    if n_substeps == 1:
        state = body(0, state)
    else:
        state = jax.lax.fori_loop(0, n_substeps, body, state)
    return MachineState(state.currents, state.omega_m, wrap_angle(state.theta_e))


def max_stable_substep(motor_or_machine, max_speed_m) -> float:
    """Longest RK4 sub-step (s) we accept: 0.5 / (fastest electrical rate), from concrete values.

    The electrical rates are ``R/L`` (the current's own pole) and ``omega_e`` (rotation of the flux); RK4
    is stable to about 2.8 on both axes and accurate to 1e-4 per period at 0.5. Used by the input checks,
    so it works on NumPy values (it must not create JAX tracers inside a jit).
    """
    motor = getattr(motor_or_machine, "motor", motor_or_machine)
    R, L_d, L_q = (np.asarray(jax.device_get(x), dtype=float) for x in (motor.R, motor.L_d, motor.L_q))
    rate = np.maximum(R / np.minimum(L_d, L_q), motor.pole_pairs * np.abs(max_speed_m))
    return float(np.min(0.5 / rate))
