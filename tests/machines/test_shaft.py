"""The compliant shaft (pmsmjax/machines/shaft.py) against independent references, in float64 (conftest).

- Power balance of the two-mass plant in the dq, alpha-beta and abc frames: electrical input power = copper
  loss + rate of stored magnetic energy + rate of kinetic and spring energy + friction, damper and load
  power, to float rounding; the mechanical part alone on the saturated and flux-map plants.
- The simulated free response against the analytic two-mass frequencies: two free inertias swing at the
  resonance ``sqrt(K (J_m + J_L) / (J_m J_L))``, the load on a motor held still (imposed speed) at the
  anti-resonance ``sqrt(K / J_L)``.
- Without a shaft the drive's trace is bit for bit the rigid one; the load speed is in the trace.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.assemble import with_parts
from pmsmjax.frames.three_phase import alpha_beta_to_abc, inverse_park
from pmsmjax.machines import MachineInput, MachineState
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
from pmsmjax.machines.saturation import saturated_machine
from pmsmjax.machines.shaft import anti_resonance_rad_s, mechanical_energy, resonance_rad_s
from pmsmjax.presets.three_phase import book_drive, book_motor
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate

#: A servo's shaft on the book motor: motor 1.5e-3, load 3e-3 kg m^2, K 2000 N m/rad (resonance 225 Hz).
J_M, J_L, K_S, D_S = 1.5e-3, 3.0e-3, 2000.0, 0.05


def two_mass_motor(salient=True, **changes):
    motor = book_motor(salient=salient)
    values = {**dict(J=J_M, load_inertia=J_L, shaft_stiffness=K_S, shaft_damping=D_S), **changes}
    return dataclasses.replace(motor, **{k: jnp.asarray(v, jnp.float64) for k, v in values.items()})


def _flux_map_machine(motor):
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec

    machine = spec_drive(drive_spec("saturated-ipm")).machine
    shaft = {k: getattr(motor, k) for k in ("J", "load_inertia", "shaft_stiffness", "shaft_damping")}
    return dataclasses.replace(machine, motor=dataclasses.replace(machine.motor, **shaft))


def make_machine(frame, motor):
    makers = {"dq": PMSMdq, "alpha_beta": PMSMAlphaBeta, "abc": PMSMabc, "saturated": saturated_machine}
    return _flux_map_machine(motor) if frame == "flux_map" else makers[frame](motor)


def _random_state(machine, rng):
    th = jnp.asarray(rng.uniform(-np.pi, np.pi))
    currents = machine.currents_from_dq(jnp.asarray(rng.uniform(-15, 15, 2)), th)
    omega_m = jnp.asarray(rng.uniform(-150, 150))
    shaft = jnp.asarray([rng.uniform(-0.01, 0.01), float(omega_m) + rng.uniform(-20, 20)])
    return MachineState(currents, omega_m, th, shaft)


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc", "saturated", "flux_map"])
def test_mechanical_power_balance(frame):
    """d/dt (kinetic + spring energy) = T_e w_m - B w_m^2 - D (w_m - w_L)^2 - T_L w_L."""
    machine = make_machine(frame, two_mass_motor())
    m = machine.motor
    rng = np.random.default_rng(3)
    for _ in range(4):
        state = _random_state(machine, rng)
        load = 4.0
        inputs = MachineInput(jnp.asarray(rng.uniform(-200, 200, 2)), jnp.asarray(load))
        dx = machine.vector_field(None, state, inputs)
        _, dE = jax.jvp(lambda x: mechanical_energy(m, x.omega_m, x.shaft), (state,), (dx,))
        w_m, w_l = state.omega_m, state.shaft[1]
        t_e = machine.electromagnetic_torque(state)
        p = t_e * w_m - m.B * w_m**2 - m.shaft_damping * (w_m - w_l) ** 2 - load * w_l
        scale = abs(float(t_e * w_m)) + abs(float(dE)) + abs(load * float(w_l))
        assert abs(float(dE - p)) < 1e-13 * scale
        assert float(m.shaft_damping * (w_m - w_l) ** 2) > 0.0  # the damper's loss is in the balance


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc"])
def test_electrical_and_mechanical_power_balance(frame):
    """Input power = copper loss + rate of magnetic energy + rate of mechanical energy + losses + load."""
    machine = make_machine(frame, two_mass_motor())
    m = machine.motor
    rng = np.random.default_rng(11)
    for _ in range(4):
        state = _random_state(machine, rng)
        u_ab, load = jnp.asarray(rng.uniform(-200, 200, 2)), 3.0
        dx = machine.vector_field(None, state, MachineInput(u_ab, jnp.asarray(load)))
        i_dq = machine.currents_dq(state)
        if frame == "abc":
            p_in = alpha_beta_to_abc(u_ab) @ state.currents
            magnetic = lambda x: 0.5 * x.currents @ machine.inductance(x.theta_e) @ x.currents
        elif frame == "alpha_beta":
            p_in = 1.5 * u_ab @ inverse_park(i_dq, state.theta_e)
            magnetic = lambda x: 0.75 * x.currents @ machine.inductance(x.theta_e) @ x.currents
        else:
            p_in = 1.5 * u_ab @ inverse_park(i_dq, state.theta_e)
            magnetic = lambda x: 0.75 * (m.L_d * x.currents[0] ** 2 + m.L_q * x.currents[1] ** 2)

        def stored(x, magnetic=magnetic):
            return magnetic(x) + mechanical_energy(m, x.omega_m, x.shaft)

        _, dW = jax.jvp(stored, (state,), (dx,))
        w_m, w_l = state.omega_m, state.shaft[1]
        losses = 1.5 * m.R * (i_dq @ i_dq) + m.B * w_m**2 + m.shaft_damping * (w_m - w_l) ** 2
        out = dW + losses + load * w_l
        scale = abs(float(p_in)) + abs(float(dW)) + abs(float(losses))
        assert abs(float(p_in - out)) < 1e-12 * scale


def _free_swing(machine, initial_twist, n_periods=4000, Ts=1e-4):
    """Speeds ``(N,)`` of the motor and of the load of ``machine`` (no magnet, no current, no voltage: only
    the shaft moves), released with the shaft twisted by ``initial_twist`` rad."""
    state = MachineState(
        machine.currents_from_dq(jnp.zeros(2), jnp.asarray(0.0)), jnp.asarray(0.0), jnp.asarray(0.0),
        jnp.asarray([initial_twist, 0.0]),
    )  # fmt: skip
    inputs = MachineInput(jnp.zeros(2), jnp.asarray(0.0))

    def body(s, _):
        s = advance(machine, s, inputs, Ts, 4)
        return s, jnp.stack([s.omega_m, s.shaft[1]])

    return np.asarray(jax.lax.scan(body, state, None, length=n_periods)[1]), Ts


def _frequency_rad_s(x, dt):
    """Angular frequency of the oscillation ``x`` from its upward zero crossings (linear interpolation)."""
    k = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    t = (k + x[k] / (x[k] - x[k + 1])) * dt
    return 2.0 * np.pi * (len(t) - 1) / (t[-1] - t[0])


@pytest.mark.parametrize("frame", ["dq", "alpha_beta"])
def test_free_response_swings_at_the_resonance(frame):
    machine = make_machine(frame, two_mass_motor(psi_f=0.0, shaft_damping=0.0, B=0.0))
    speeds, Ts = _free_swing(machine, 1e-3)
    w_r = resonance_rad_s(J_M, J_L, K_S)
    measured = _frequency_rad_s(speeds[:, 0], Ts)
    assert abs(measured / w_r - 1.0) < 1e-6
    # momentum is conserved: the two inertias swing against each other
    np.testing.assert_allclose(J_M * speeds[:, 0] + J_L * speeds[:, 1], 0.0, atol=1e-12)


def test_load_on_a_held_motor_swings_at_the_anti_resonance():
    motor = two_mass_motor(psi_f=0.0, shaft_damping=0.0, B=0.0)
    machine = PMSMdq(motor, mechanics="imposed")
    speeds, Ts = _free_swing(machine, 1e-3)
    w_a = anti_resonance_rad_s(J_L, K_S)
    assert np.all(speeds[:, 0] == 0.0)
    assert abs(_frequency_rad_s(speeds[:, 1], Ts) / w_a - 1.0) < 1e-6
    assert 1.5 < resonance_rad_s(J_M, J_L, K_S) / w_a < 2.0  # sqrt(1 + J_L/J_m) = sqrt(3)


SCENARIO = Scenario(
    duration_s=0.04, speed_ref=Profile.constant(100.0), load_torque=Profile.step(0.02, 0.0, 5.0)
)


def test_rigid_drive_is_unchanged_and_shaft_drive_traces_the_load():
    drive = book_drive(book_motor())
    rigid = simulate(drive, SCENARIO)
    assert rigid.load_speed is None and "load_speed" not in rigid.columns()
    assert drive.machine.motor.load_inertia is None

    def with_shaft(stiffness):
        shaft = {
            "machine.motor.J": jnp.asarray(J_M), "machine.motor.load_inertia": jnp.asarray(J_L),
            "machine.motor.shaft_stiffness": jnp.asarray(stiffness),
            "machine.motor.shaft_damping": jnp.asarray(D_S),
        }  # fmt: skip
        return simulate(with_parts(drive, shaft), SCENARIO)

    # the book motor's J = 3e-3 kg m^2 split 1.5e-3 + 3e-3 would be a heavier drive: compare at equal total
    two_mass = with_shaft(K_S)
    assert two_mass.load_speed.shape == two_mass.omega_m.shape and "load_speed" in two_mass.columns()
    twist = np.asarray(two_mass.omega_m - two_mass.load_speed)
    assert np.abs(twist).max() > 0.1  # the load lags and swings
    # after the load step the shaft carries the load torque: the speeds agree again (twist K phi = T_L)
    np.testing.assert_allclose(two_mass.load_speed[-1], two_mass.omega_m[-1], atol=0.5)
    # a shaft 100 times stiffer behaves as a rigid one of the same total inertia
    stiff = with_shaft(100 * K_S)
    rigid_same = simulate(with_parts(drive, {"machine.motor.J": jnp.asarray(J_M + J_L)}), SCENARIO)
    np.testing.assert_allclose(stiff.omega_m, rigid_same.omega_m, atol=0.1)
    np.testing.assert_allclose(stiff.load_speed, rigid_same.omega_m, atol=0.1)
