"""The warm motor (pmsmjax/machines/thermal.py) against independent references, in float64 (conftest).

- The thermal network alone: its per-period update against the analytic step response
  ``T_amb + P R_th (1 - exp(-t / (R_th C_th)))``, in float64 and, over a million periods, in float32.
- The warm plant's power balance, in every three-phase frame: electrical input power = copper loss
  ``1.5 R(T) |i_dq|^2`` + rate of stored magnetic energy + rate of kinetic energy + friction and load power,
  to float rounding.
- ``R(T)``, ``psi_f(T)`` visible: at a fixed current the hot machine's torque (and back-EMF) is lower by
  ``beta dT``, in the dq, alpha-beta, abc, saturated and flux-map plants.
- The closed-loop drive with its thermal network against scipy's ``solve_ivp`` of the coupled electrical and
  thermal equations (continuous coupling, written out here) under the voltages the drive applied.
- Gradients through the thermal parameters are finite and match central differences.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsmjax.assemble import with_parts
from pmsmjax.frames.three_phase import alpha_beta_to_abc, inverse_park
from pmsmjax.machines import MachineInput, MachineState
from pmsmjax.machines.pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
from pmsmjax.machines.saturation import saturated_machine
from pmsmjax.machines.thermal import WindingThermal
from pmsmjax.presets.three_phase import book_drive, book_motor
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate

ALPHA, BETA = 0.00393, -0.0011  # copper; sintered NdFeB (-0.11 %/K)


def thermal(r_th=0.5, c_th=2.0, ambient_k=313.15, initial_k=313.15, reference_k=293.15):
    return WindingThermal(r_th, c_th, ambient_k, initial_k, reference_k, ALPHA, BETA)


def run_network(net, loss_w, Ts, n):
    def body(s, _):
        s = net.step(s, loss_w, Ts)
        return s, net.temperature(s)

    return jax.lax.scan(body, net.init(net.r_th.dtype), None, length=n)[1]


def test_step_response_is_exact():
    net = thermal(r_th=0.4, c_th=50.0, initial_k=313.15)
    P, Ts, n = 150.0, 1e-3, 5000
    T = np.asarray(run_network(net, P, Ts, n))
    t = Ts * np.arange(1, n + 1)
    expected = 313.15 + P * 0.4 * (1.0 - np.exp(-t / (0.4 * 50.0)))
    np.testing.assert_allclose(T, expected, rtol=0, atol=1e-10)
    assert T[-1] - 313.15 > 10.0  # the run does heat the node


def test_step_response_in_float32_over_a_million_periods():
    # 100 s at 10 kHz with a 20 s time constant: micro-kelvin increments on 313 K (float32 resolves 3e-5 K)
    net = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32), thermal(r_th=0.4, c_th=50.0))
    n, Ts, P = 10**6, 1e-4, 150.0
    T = np.asarray(run_network(net, jnp.float32(P), Ts, n), np.float64)
    t = Ts * np.arange(1, n + 1)
    expected = 313.15 + P * 0.4 * (1.0 - np.exp(-t / 20.0))
    # float32 holds 313 K to 1.5e-5 K; the compensated sum keeps the error at that level (a plain float32
    # sum of these increments drifts by kelvins)
    assert np.abs(T - expected).max() < 1e-4
    assert expected[-1] - 313.15 > 59.0


def _energy_terms(machine, thermal_net, temperature_k, currents, omega_m, theta_e, u_ab, load):
    """(input power, copper loss, rate of magnetic energy, rate of kinetic energy + friction + load)."""
    k_r, k_psi = thermal_net.factors(temperature_k)
    warm = machine.at_temperature(k_r, k_psi)
    state = MachineState(currents, omega_m, theta_e)
    inputs = MachineInput(u_ab, load)
    dx = warm.vector_field(None, state, inputs)
    i_dq = warm.currents_dq(state)
    m = warm.motor
    if isinstance(warm, PMSMabc):
        p_in = alpha_beta_to_abc(u_ab) @ currents

        def magnetic(x):
            return 0.5 * x.currents @ warm.inductance(x.theta_e) @ x.currents

    else:
        p_in = 1.5 * u_ab @ inverse_park(i_dq, theta_e)
        if isinstance(warm, PMSMAlphaBeta):

            def magnetic(x):
                return 1.5 * 0.5 * x.currents @ warm.inductance(x.theta_e) @ x.currents

        elif getattr(warm, "saturation", None) is None:

            def magnetic(x):
                return 1.5 * (0.5 * m.L_d * x.currents[0] ** 2 + 0.5 * m.L_q * x.currents[1] ** 2)

        else:  # field energy int_0^i_d x L_dd(x) dx (Gauss-Legendre, exact to rounding) + L_q i_q^2 / 2

            def magnetic(x):
                i_d, i_q = x.currents[0], x.currents[1]
                nodes, weights = np.polynomial.legendre.leggauss(40)
                xs = 0.5 * i_d * (nodes + 1.0)
                field_d = (
                    0.5 * i_d * jnp.sum(weights * xs * warm.saturation.incremental_inductance(m.L_d, xs))
                )
                return 1.5 * (field_d + 0.5 * m.L_q * i_q**2)

    _, dW = jax.jvp(magnetic, (state,), (dx,))
    p_cu = 1.5 * m.R * (i_dq @ i_dq)
    p_mech = m.J * omega_m * dx.omega_m + m.B * omega_m**2 + load * omega_m
    return p_in, p_cu, dW, p_mech


def linear_machine(frame: str, motor):
    """The plant of ``motor`` in ``frame``: the dq, alpha-beta and abc models, or the saturated dq one."""
    makers = {"dq": PMSMdq, "alpha_beta": PMSMAlphaBeta, "abc": PMSMabc, "saturated": saturated_machine}
    return makers[frame](motor)


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc", "saturated"])
def test_warm_plant_power_balance(frame):
    motor = book_motor(salient=True)
    machine = linear_machine(frame, motor)
    net = thermal()
    rng = np.random.default_rng(7)
    for _ in range(4):
        th = rng.uniform(-np.pi, np.pi)
        i_dq = rng.uniform(-15, 15, 2)
        currents = machine.currents_from_dq(jnp.asarray(i_dq), jnp.asarray(th))
        terms = _energy_terms(
            machine, net, rng.uniform(250.0, 450.0), currents, jnp.asarray(rng.uniform(-150, 150)),
            jnp.asarray(th), jnp.asarray(rng.uniform(-200, 200, 2)), 3.0,
        )  # fmt: skip
        p_in, p_cu, dW, p_mech = (float(x) for x in terms)
        scale = abs(p_in) + abs(p_cu) + abs(dW) + abs(p_mech)
        assert abs(p_in - (p_cu + dW + p_mech)) < 1e-12 * scale
        assert p_cu > 0.0


def test_copper_loss_uses_the_warm_resistance():
    net = thermal()
    motor = book_motor()
    warm = net.machine_at(PMSMdq(motor), net.init(jnp.float64))  # 313.15 K: 20 K above the reference
    np.testing.assert_allclose(float(warm.motor.R), float(motor.R) * (1.0 + ALPHA * 20.0), rtol=1e-14)
    loss = net.copper_loss(warm.motor.R, jnp.array([3.0, 4.0]), jnp.array([0.0, 5.0]))
    np.testing.assert_allclose(float(loss), 1.5 * float(warm.motor.R) * 25.0, rtol=1e-14)


def _flux_map_machine():
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec

    return spec_drive(drive_spec("saturated-ipm")).machine


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc", "saturated", "flux_map"])
def test_hot_magnet_lowers_torque_and_back_emf(frame):
    motor = book_motor()
    if frame == "flux_map":
        machine = _flux_map_machine()
    else:
        machine = linear_machine(frame, motor)
    net = thermal()
    dT = 100.0
    k_r, k_psi = net.factors(net.reference_k + dT)
    hot = machine.at_temperature(k_r, k_psi)
    th = jnp.asarray(0.3)
    # torque at i_d = 0: 1.5 p psi_d(0, i_q) i_q, the magnet's share scaled by (1 + beta dT)
    state = MachineState(machine.currents_from_dq(jnp.array([0.0, 5.0]), th), jnp.asarray(0.0), th)
    t_cold = float(machine.electromagnetic_torque(state))
    t_hot = float(hot.electromagnetic_torque(state))
    magnet = float(machine.flux_map(jnp.zeros(2))[0][0]) if frame == "flux_map" else float(motor.psi_f)
    p = machine.motor.pole_pairs
    np.testing.assert_allclose(t_cold - t_hot, -1.5 * p * BETA * dT * magnet * 5.0, rtol=1e-10)
    # back-EMF at zero current: the open-circuit current derivative -e / L along q scales with psi_f(T)
    zero = MachineState(machine.currents_from_dq(jnp.zeros(2), th), jnp.asarray(100.0), th)
    inputs = MachineInput(jnp.zeros(2), jnp.asarray(0.0))
    d_cold = machine.currents_to_dq(machine.vector_field(None, zero, inputs).currents, th)
    d_hot = hot.currents_to_dq(hot.vector_field(None, zero, inputs).currents, th)
    np.testing.assert_allclose(float(d_hot[1] / d_cold[1]), 1.0 + BETA * dT, rtol=1e-10)
    np.testing.assert_allclose(float(hot.motor.R), float(machine.motor.R) * (1.0 + ALPHA * dT), rtol=1e-14)


# --- the closed-loop drive against scipy ------------------------------------------------------------
R_TH, C_TH = 0.25, 0.08  # K/W, J/K: a 20 ms time constant, so that 30 ms of run heat the winding visibly
T_AMB, T_REF = 313.15, 293.15
SCENARIO = Scenario(
    duration_s=0.03, speed_ref=Profile.constant(150.0), load_torque=Profile.step(0.015, 0.0, 6.0)
)


@pytest.fixture(scope="module")
def warm_run():
    motor = book_motor()
    drive = with_parts(book_drive(motor), {"thermal": thermal(R_TH, C_TH, T_AMB, 353.15, T_REF)})
    return drive, simulate(drive, SCENARIO)


def coupled_reference(drive, trace, c_th=C_TH):
    """``(N, 5)`` ``[i_d, i_q, omega_m, theta_e, T]`` at the trace's period starts: scipy's DOP853 solution of
    the coupled electrical and thermal equations (continuous coupling) under the voltages the drive
    applied, each period's held over that period."""
    m = drive.machine.motor
    R, Ld, Lq, psi, J, B = (float(x) for x in (m.R, m.L_d, m.L_q, m.psi_f, m.J, m.B))
    p = m.pole_pairs
    Ts = drive.Ts
    u_abc = np.asarray(trace.u_abc)
    u_ab = np.stack(
        [(2 * u_abc[:, 0] - u_abc[:, 1] - u_abc[:, 2]) / 3, (u_abc[:, 1] - u_abc[:, 2]) / np.sqrt(3)], 1
    )
    load = np.asarray(trace.load_torque)

    def rhs(t, x, u, tl):
        i_d, i_q, w, th, T = x
        c, s = np.cos(th), np.sin(th)
        u_d, u_q = u[0] * c + u[1] * s, -u[0] * s + u[1] * c
        R_T = R * (1 + ALPHA * (T - T_REF))
        psi_T = psi * (1 + BETA * (T - T_REF))
        we = p * w
        di_d = (u_d - R_T * i_d + we * Lq * i_q) / Ld
        di_q = (u_q - R_T * i_q - we * (Ld * i_d + psi_T)) / Lq
        Te = 1.5 * p * (psi_T * i_q + (Ld - Lq) * i_d * i_q)
        dT = (1.5 * R_T * (i_d**2 + i_q**2) - (T - T_AMB) / R_TH) / c_th
        return [di_d, di_q, (Te - tl - B * w) / J, we, dT]

    n = len(load)
    ref = np.empty((n, 5))
    x = np.array([0.0, 0.0, 0.0, 0.0, 353.15])
    for k in range(n):
        ref[k] = x
        # the drive applies the duties of each period's row over that period (the trace's u_abc)
        x = solve_ivp(rhs, (0, Ts), x, args=(u_ab[k], load[k]), method="DOP853", rtol=1e-10, atol=1e-10).y[
            :, -1
        ]
    return ref


@pytest.mark.parametrize("c_th", [C_TH, 4 * C_TH])
def test_drive_against_solve_ivp_of_the_coupled_equations(warm_run, c_th):
    drive, _ = warm_run
    drive = with_parts(drive, {"thermal": thermal(R_TH, c_th, T_AMB, 353.15, T_REF)})  # same program
    trace = simulate(drive, SCENARIO)
    ref = coupled_reference(drive, trace, c_th)
    T = np.asarray(trace.winding_temperature)
    rise = np.ptp(ref[:, 4])
    assert rise > 10.0  # the run heats the winding by kelvins
    # The drive holds R(T), psi_f(T) over a period (a lag of one period in the coupling) and heats by the
    # trapezoid of the period's loss: errors of first order in Ts / (R_th C_th) (measured 0.19 and 0.18 times
    # it here), negligible at a real winding's seconds-to-minutes time constant.
    lag = drive.Ts / (R_TH * c_th)
    assert np.abs(T - ref[:, 4]).max() < 0.5 * lag * rise
    i_peak = np.abs(ref[:, :2]).max()
    assert np.abs(np.asarray(trace.i_dq) - ref[:, :2]).max() < 0.3 * lag * i_peak
    speed_peak = np.abs(ref[:, 2]).max()
    assert np.abs(np.asarray(trace.omega_m) - ref[:, 2]).max() < 0.3 * lag * speed_peak


def test_trace_records_the_winding_temperature(warm_run):
    _, trace = warm_run
    columns = trace.columns()
    np.testing.assert_allclose(columns["winding_temperature_c"][0], 80.0, rtol=1e-12)


@pytest.mark.slow
def test_gradient_through_thermal_parameters(warm_run):
    drive, _ = warm_run
    scenario = Scenario(
        duration_s=0.004, speed_ref=Profile.constant(150.0), load_torque=Profile.constant(2.0)
    )

    def final(params):
        net = thermal(params[0], params[1], T_AMB, 353.15, T_REF)
        net = WindingThermal(
            net.r_th, net.c_th, net.ambient_k, net.initial_k, net.reference_k, params[2], params[3]
        )
        tr = simulate(with_parts(drive, {"thermal": net}), scenario)
        return tr.winding_temperature[-1] + tr.omega_m[-1]

    x = jnp.array([R_TH, C_TH, ALPHA, BETA])
    g = np.asarray(jax.grad(final)(x))
    assert np.all(np.isfinite(g)) and np.all(g != 0.0)
    for j in range(4):
        h = 1e-6 * abs(float(x[j]))
        fd = (float(final(x.at[j].add(h))) - float(final(x.at[j].add(-h)))) / (2 * h)
        np.testing.assert_allclose(g[j], fd, rtol=1e-5)


def test_absent_network_adds_nothing_to_the_program():
    from pmsmjax.simulate import _simulate

    drive = book_drive(book_motor())
    scenario = Scenario(duration_s=0.001, speed_ref=Profile.constant(100.0))
    cold = _simulate.lower(drive, scenario, 1, None).as_text()
    warm = _simulate.lower(with_parts(drive, {"thermal": thermal()}), scenario, 1, None).as_text()
    # the thermal update's expm1 and its Kahan sum are in the warm program only
    assert "exponential_minus_one" in warm and "exponential_minus_one" not in cold
    assert simulate(drive, scenario).winding_temperature is None
    assert "winding_temperature_c" not in simulate(drive, scenario).columns()
