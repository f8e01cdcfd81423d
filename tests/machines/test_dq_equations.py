"""The steady-state dq equations written once (pmsmjax/machines/dq_equations.py) against the machine they
describe: the voltage they give, held in the rotor frame, leaves the dq plant's currents standing still,
and the torque they give is the plant's; the same functions on floats, NumPy and JAX agree."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.machines import dq_equations as dq
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.machines.pmsm3 import PMSMdq

SALIENT = PMSMParameters(R=0.958, L_d=5.25e-3, L_q=12e-3, psi_f=0.1827, pole_pairs=4, J=0.003, B=0.008)


@pytest.mark.parametrize("i_d, i_q, omega_e", [(0.0, 5.0, 400.0), (-3.0, 8.0, -250.0), (-6.0, -2.0, 900.0)])
def test_steady_voltage_holds_the_plant_currents(i_d, i_q, omega_e):
    m = SALIENT
    psi_d, psi_q = dq.linear_flux(m.psi_f, m.L_d, m.L_q, i_d, i_q)
    u_d, u_q = dq.voltage(m.R, omega_e, i_d, i_q, psi_d, psi_q)
    plant = PMSMdq(m)
    u = MachineInput(jnp.array([u_d, u_q]), jnp.zeros(()), "rotor")
    d_currents = plant.current_derivative(jnp.array([i_d, i_q]), jnp.asarray(0.7), jnp.asarray(omega_e), u)
    scale = (abs(u_d) + abs(u_q)) / min(float(m.L_d), float(m.L_q))
    assert np.max(np.abs(np.asarray(d_currents))) < 1e-12 * scale
    torque = dq.linear_torque(dq.torque_factor(m.pole_pairs), m.psi_f, m.L_d, m.L_q, i_d, i_q)
    plant_torque = plant.torque(jnp.array([i_d, i_q]), jnp.asarray(0.7))
    assert float(torque) == pytest.approx(float(plant_torque), rel=1e-12)


def test_floats_numpy_and_jax_agree():
    args = (0.5, 300.0, -2.0, 6.0, 0.09, 0.03)
    as_float = dq.voltage_magnitude(*args, xp=math)
    as_numpy = dq.voltage_magnitude(*map(np.float64, args), xp=np)
    as_jax = dq.voltage_magnitude(*map(jnp.asarray, args), xp=jnp)
    assert as_float == pytest.approx(float(as_numpy), rel=1e-15)
    assert as_float == pytest.approx(float(as_jax), rel=1e-12)
    assert as_float == pytest.approx(math.hypot(0.5 * -2.0 - 300.0 * 0.03, 0.5 * 6.0 + 300.0 * 0.09))
