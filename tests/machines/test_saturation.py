"""d-axis saturation model (pmsmjax/machines/saturation.py) against independent references.

- Switched off it is the linear dq machine: ``saturation=None`` bit for bit, ``depth = 0`` to 1e-12, over a
  closed-loop book drive run.
- Switched on, open loop under piecewise-constant stator-frame voltages, the RK4 scan agrees with a scipy
  ``solve_ivp`` (DOP853) solution of the saturated dq equations written here by hand.
- Torque equals ``p_n dW'/dth_e`` with the co-energy integrated here by quadrature (scipy ``quad``).
- The flux map is what it claims: ``dpsi_d/di_d`` is the incremental inductance, and +d saturates.
- A trajectory is differentiable w.r.t. the saturation depth (``jax.grad`` against central differences).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import check_gradient
from scipy.integrate import quad, solve_ivp

from pmsmjax.machines import MachineInput, MachineState, advance
from pmsmjax.machines.saturation import DAxisSaturation, SaturatedPMSMdq, saturated_machine
from pmsmjax.presets.three_phase import book_drive, book_motor
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate

A, I_S = 0.3, 8.0  # depth, current scale (A)
P = dict(R=0.958, Ld=5.25e-3, Lq=12e-3, psi=0.1827, J=0.003, B=0.008, p=4)  # written out: salient book motor


def psi_d_ref(i_d):
    # flux as the integral of the incremental inductance L_d (1 - a tanh(x / i_s)), by quadrature
    return P["psi"] + quad(lambda x: P["Ld"] * (1.0 - A * np.tanh(x / I_S)), 0.0, i_d, epsabs=1e-14)[0]


def rhs(t, x, u_ab, load):
    i_d, i_q, w_m, th = x
    c, s = np.cos(th), np.sin(th)
    u_d, u_q = u_ab[0] * c + u_ab[1] * s, -u_ab[0] * s + u_ab[1] * c
    w_e = P["p"] * w_m
    L_dd = P["Ld"] * (1.0 - A * np.tanh(i_d / I_S))
    psi_d = P["psi"] + P["Ld"] * (i_d - A * I_S * np.log(np.cosh(i_d / I_S)))
    di_d = (u_d - P["R"] * i_d + w_e * P["Lq"] * i_q) / L_dd
    di_q = (u_q - P["R"] * i_q - w_e * psi_d) / P["Lq"]
    T_e = 1.5 * P["p"] * (psi_d * i_q - P["Lq"] * i_q * i_d)
    return [di_d, di_q, (T_e - load - P["B"] * w_m) / P["J"], w_e]


@pytest.fixture(scope="module")
def machine():
    return saturated_machine(book_motor(salient=True), depth=A, current_scale=I_S)


def _short_scenario():
    return Scenario(
        duration_s=0.03, speed_ref=Profile.constant(100.0), load_torque=Profile.step(0.02, 0.0, 3.0)
    )


@pytest.mark.slow
def test_off_is_the_linear_machine():
    drive = book_drive(book_motor(salient=True))
    linear = simulate(drive, _short_scenario())
    motor = drive.machine.motor
    none = simulate(eqx.tree_at(lambda d: d.machine, drive, SaturatedPMSMdq(motor)), _short_scenario())
    zero = SaturatedPMSMdq(motor, saturation=DAxisSaturation(0.0, I_S))
    zero_trace = simulate(eqx.tree_at(lambda d: d.machine, drive, zero), _short_scenario())
    assert np.abs(linear.i_dq).max() > 5.0  # the run does exercise the currents
    for name in ("i_dq", "omega_m", "theta_e", "torque"):
        np.testing.assert_array_equal(getattr(none, name), getattr(linear, name))
        np.testing.assert_allclose(getattr(zero_trace, name), getattr(linear, name), rtol=0, atol=1e-12)


def test_open_loop_against_solve_ivp(machine):
    rng = np.random.default_rng(3)
    Ts, n = 1e-4, 300
    # +-60 V steps every 5 periods: the currents swing through +-d saturation and the rotor moves
    u_ab = np.repeat(rng.uniform(-60.0, 60.0, size=(n // 5, 2)), 5, axis=0)
    load = 0.5
    x0 = [1.0, -2.0, 5.0, 0.4]
    ref = np.empty((n + 1, 4))
    ref[0] = x = np.asarray(x0)
    for k in range(n):
        sol = solve_ivp(rhs, (0, Ts), x, args=(u_ab[k], load), method="DOP853", rtol=1e-11, atol=1e-12)
        ref[k + 1] = x = sol.y[:, -1]

    def body(state, u):
        nxt = advance(machine, state, MachineInput(u, jnp.asarray(load)), Ts, 4)
        return nxt, jnp.concatenate([nxt.currents, nxt.omega_m[None]])

    s0 = MachineState(jnp.asarray(x0[:2]), jnp.asarray(x0[2]), jnp.asarray(x0[3]))
    _, out = jax.lax.scan(body, s0, jnp.asarray(u_ab))
    out = np.asarray(out)
    assert np.abs(ref[:, 0]).max() > 8.0  # reaches the saturating region
    i_peak = np.abs(ref[:, :2]).max()
    assert np.abs(out[:, :2] - ref[1:, :2]).max() < 1e-5 * i_peak
    assert np.abs(out[:, 2] - ref[1:, 2]).max() < 1e-6 * np.abs(ref[:, 2]).max()


@pytest.mark.parametrize("i_dq", [(6.0, 4.0), (-9.0, 7.0), (15.0, -3.0)])
def test_torque_from_coenergy(machine, i_dq):
    def coenergy(i_ab, th):
        # W' = 1.5 [int_0^i_d psi_d(x) dx + L_q i_q^2 / 2] at stator-frame currents i_ab, rotor angle th
        i_d = i_ab[0] * np.cos(th) + i_ab[1] * np.sin(th)
        i_q = -i_ab[0] * np.sin(th) + i_ab[1] * np.cos(th)
        return 1.5 * (quad(psi_d_ref, 0.0, i_d, epsabs=1e-14)[0] + 0.5 * P["Lq"] * i_q**2)

    th, h = 0.7, 1e-5
    i_ab = np.array(
        [i_dq[0] * np.cos(th) - i_dq[1] * np.sin(th), i_dq[0] * np.sin(th) + i_dq[1] * np.cos(th)]
    )
    T_ref = P["p"] * (coenergy(i_ab, th + h) - coenergy(i_ab, th - h)) / (2 * h)
    T = float(machine.torque(jnp.asarray(i_dq), th))
    assert abs(T - T_ref) < 1e-6 * abs(T_ref)


@pytest.mark.slow
def test_flux_map(machine):
    i_d = np.linspace(-20.0, 20.0, 9)
    sat = machine.saturation
    L_dd = np.asarray(sat.incremental_inductance(P["Ld"], jnp.asarray(i_d)))
    dpsi = np.asarray(jax.vmap(jax.grad(lambda x: sat.flux(P["psi"], P["Ld"], x)))(jnp.asarray(i_d)))
    np.testing.assert_allclose(dpsi, L_dd, rtol=1e-12)
    np.testing.assert_allclose(
        [float(sat.flux(P["psi"], P["Ld"], x)) for x in i_d], [psi_d_ref(x) for x in i_d], rtol=1e-10
    )
    assert abs(L_dd[4] - P["Ld"]) < 1e-15  # datasheet L_d at zero current
    assert np.all(np.diff(L_dd) < 0)  # +d saturates, -d relieves the magnet's bias
    with pytest.raises(ValueError, match="depth"):
        DAxisSaturation(1.0, I_S)


@pytest.mark.slow
def test_gradient_wrt_depth():
    motor = book_motor(salient=True)

    def final_current(depth):
        m = SaturatedPMSMdq(motor, saturation=DAxisSaturation(depth, I_S))
        s0 = m.initial_state((0.0, 0.0), 0.0, 0.2)
        s = advance(m, s0, MachineInput(jnp.array([80.0, 20.0]), jnp.asarray(0.0)), 1e-3, 4)
        return s.currents[0]

    r = check_gradient(final_current, 0.3, rel_step=1e-5, rtol=1e-6, labels=["depth"])
    assert abs(r.grad[0]) > 1.0
