"""The continuous-time vector field serves diffrax and linearisation (independent checks)."""

import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.machines import MachineInput, advance, linearise, solve_adaptive
from pmsmjax.presets.three_phase import book_motor, make_machine


@pytest.mark.parametrize("salient", [False, True])
def test_linearised_dq_model_matches_hand_derived_jacobian(salient):
    """A = df/dx of the dq model with rotor-frame input, derived by hand from the book, ch. 1."""
    m = book_motor(salient)
    machine = make_machine(m, "dq")
    i_d, i_q, w = -1.3, 4.2, 80.0
    state = machine.initial_state((i_d, i_q), w, 0.3)
    A, B = linearise(machine, state, MachineInput(jnp.array([5.0, 30.0]), jnp.array(2.0), "rotor"))
    p, R, Ld, Lq, psi, J, Bf = 4, m.R, m.L_d, m.L_q, m.psi_f, m.J, m.B
    we = p * w
    kt = 1.5 * p
    expected_A = np.array(
        [
            [-R / Ld, we * Lq / Ld, p * Lq * i_q / Ld, 0.0],
            [-we * Ld / Lq, -R / Lq, -p * (Ld * i_d + psi) / Lq, 0.0],
            [kt * (Ld - Lq) * i_q / J, kt * (psi + (Ld - Lq) * i_d) / J, -Bf / J, 0.0],
            [0.0, 0.0, p, 0.0],
        ]
    )
    expected_B = np.array([[1 / Ld, 0, 0], [0, 1 / Lq, 0], [0, 0, -1 / J], [0, 0, 0]])
    np.testing.assert_allclose(A, expected_A, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(B, expected_B, rtol=1e-12, atol=1e-12)


def test_standstill_poles_are_winding_time_constants():
    """At rest with imposed speed the current poles are -R/L_d and -R/L_q."""
    m = book_motor(salient=True)
    machine = make_machine(m, "dq", "imposed")
    A, _ = linearise(machine, machine.initial_state(), MachineInput(jnp.zeros(2), jnp.array(0.0), "rotor"))
    poles = np.sort(np.linalg.eigvals(np.asarray(A[:2, :2])).real)
    np.testing.assert_allclose(poles, np.sort([-m.R / m.L_d, -m.R / m.L_q]), rtol=1e-12)


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc"])
def test_fixed_step_scan_agrees_with_adaptive_diffrax_solve(frame):
    """One 100 us period of 10 RK4 steps against Dopri8 at rtol 1e-10, at speed, salient machine."""
    machine = make_machine(book_motor(salient=True), frame)
    state = machine.initial_state((1.0, 6.0), 100.0, 0.4)
    inputs = MachineInput(jnp.array([40.0, -70.0]), jnp.array(3.0), "stator")
    fixed = advance(machine, state, inputs, 1e-4, 10)
    ref = solve_adaptive(machine, state, inputs, 1e-4)
    i_fixed, i_ref = machine.currents_dq(fixed), machine.currents_dq(ref)
    assert float(jnp.max(jnp.abs(i_fixed - i_ref))) < 1e-8 * 6.0
    assert abs(float(fixed.omega_m - ref.omega_m)) < 1e-10
