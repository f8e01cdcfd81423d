"""The dq machine's trig-free sub-stepping equals RK4 with the voltage rotated by cos/sin at every stage."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.machines.base import MachineInput, MachineState
from pmsmjax.machines.integrate import advance, rk4_step, rotate_back
from pmsmjax.presets.three_phase import book_motor, make_machine


@pytest.mark.parametrize("delta", [0.0, 1e-3, -0.2, 0.5, -0.5])
def test_rotate_back_is_the_rotation_matrix(delta):
    x = np.array([3.0, -1.5])
    c, s = np.cos(delta), np.sin(delta)
    expected = np.array([x[0] * c + x[1] * s, -x[0] * s + x[1] * c])
    np.testing.assert_allclose(np.asarray(rotate_back(jnp.asarray(x), delta)), expected, rtol=0, atol=1e-15)


def test_rotate_back_in_float32_is_exact_to_float32_resolution():
    delta = np.linspace(-0.5, 0.5, 2001)
    x = np.array([3.0, -1.5])
    exact = np.stack(
        [x[0] * np.cos(delta) + x[1] * np.sin(delta), -x[0] * np.sin(delta) + x[1] * np.cos(delta)]
    )
    got = jax.vmap(lambda d: rotate_back(jnp.asarray(x, jnp.float32), d))(jnp.asarray(delta, jnp.float32))
    assert got.dtype == jnp.float32
    # |x| = 3.35: float32 rounding of the result alone is about 2e-7; the series adds under 1e-9.
    np.testing.assert_allclose(np.asarray(got, np.float64).T, exact, rtol=0, atol=1e-6)


@pytest.mark.parametrize("salient", [False, True])
@pytest.mark.parametrize("speed_m", [20.0, 105.0, 600.0])  # the last: 0.24 rad per 100 us sub-step
def test_advance_equals_stagewise_trigonometry(salient, speed_m):
    machine = make_machine(book_motor(salient), "dq")
    assert machine.angle_only_in_voltage
    state = MachineState(jnp.array([1.3, 7.9]), jnp.asarray(speed_m), jnp.asarray(2.9))
    inputs = MachineInput(jnp.array([120.0, -60.0]), jnp.asarray(4.0), "stator")
    Ts, n = 1e-4, 10 if speed_m < 500 else 1  # one long sub-step checks the series at a large angle

    fast = advance(machine, state, inputs, Ts, n)
    # Reference: the generic RK4 step, which evaluates the stator-to-rotor voltage with cos/sin.
    ref = state
    for _ in range(n):
        ref = rk4_step(machine, ref, inputs, Ts / n)
    assert jax.tree.all(
        jax.tree.map(lambda a, b: np.allclose(a, b, rtol=1e-13, atol=1e-12), fast.currents, ref.currents)
    )
    assert float(fast.omega_m) == pytest.approx(float(ref.omega_m), rel=1e-14)
    wrapped = np.mod(float(ref.theta_e) + np.pi, 2 * np.pi) - np.pi
    assert float(fast.theta_e) == pytest.approx(wrapped, abs=1e-13)
