"""The three PMSM frames (dq, alpha-beta, abc) against an independent NumPy/scipy reference and each other.

Shown: under open-loop, piecewise-constant stator-frame voltage sequences (2000 periods of 1e-4 s),
with the speed imposed and as a state, for the surface and the salient book motor, every frame model
integrated by ``pmsmjax.machines.advance`` with 1, 2 or 10 RK4 sub-steps per period stays within 0.1 % of
the peak current of a scipy ``solve_ivp`` (DOP853, rtol 1e-10, atol 1e-12) solution of the dq equations
written here by hand from the book, ch. 1.

The reference holds the voltage in the stator frame as a real inverter does: over each period the
alpha-beta voltage is constant, so inside the ODE the dq voltage is Park(u_ab, theta(t)).
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsmjax.machines import MachineInput, MachineState, advance
from pmsmjax.presets.three_phase import book_motor, make_machine

TS = 1e-4
N_PERIODS = 2000
FRAMES = ("dq", "alpha_beta", "abc")
SPEED_IMPOSED = 1000.0 * 2.0 * np.pi / 60.0  # 1000 r/min, mechanical rad/s
THETA0 = 0.3
I_DQ0 = (0.5, -1.0)


# ---------------------------------------------------------------------------------------------------
# Independent reference: the dq equations of the book, ch. 1 in NumPy, integrated by scipy.
# ---------------------------------------------------------------------------------------------------
def motor_numbers(salient: bool) -> dict:
    # Written out (not read from the library's preset) so a wrong preset would also show.
    return dict(R=0.958, Ld=5.25e-3, Lq=12e-3 if salient else 5.25e-3, psi=0.1827, J=0.003, B=0.008, p=4)


def dq_rhs(t, x, u_ab, load, P, imposed):
    """x = [i_d, i_q, w_m, theta_e]; u_ab held in the stator frame."""
    i_d, i_q, w_m, th = x
    c, s = np.cos(th), np.sin(th)
    u_d = u_ab[0] * c + u_ab[1] * s
    u_q = -u_ab[0] * s + u_ab[1] * c
    w_e = P["p"] * w_m
    di_d = (u_d - P["R"] * i_d + w_e * P["Lq"] * i_q) / P["Ld"]
    di_q = (u_q - P["R"] * i_q - w_e * (P["Ld"] * i_d + P["psi"])) / P["Lq"]
    T_e = 1.5 * P["p"] * (P["psi"] * i_q + (P["Ld"] - P["Lq"]) * i_d * i_q)
    dw = 0.0 if imposed else (T_e - load - P["B"] * w_m) / P["J"]
    return [di_d, di_q, dw, w_e]


def scipy_reference(P, x0, u_ab, load, imposed):
    """States at every period boundary, ``(N+1, 4)``; the angle is left unwrapped."""
    out = np.empty((len(u_ab) + 1, 4))
    out[0] = x = np.asarray(x0, float)
    for k in range(len(u_ab)):
        sol = solve_ivp(
            dq_rhs, (0.0, TS), x, method="DOP853", rtol=1e-10, atol=1e-12, args=(u_ab[k], load[k], P, imposed)
        )
        assert sol.success
        out[k + 1] = x = sol.y[:, -1]
    return out


def voltage_sequence(P, imposed: bool, seed: int):
    """Random, reproducible open-loop stator-frame voltages ``(N, 2)`` V and load torques ``(N,)`` N m.

    A rotating component steers the machine along a planned (i_d, i_q) operating point: at the imposed
    1000 r/min it cancels most of the 76 V back-EMF; with speed as a state it follows a planned
    acceleration (about 1300 r/min after 0.2 s) so the machine actually turns. A uniform random
    component (+-15 V per period) on top excites the currents (several amperes, peaks near 10 A).
    """
    rng = np.random.default_rng(seed)
    n = N_PERIODS
    load = np.zeros(n) if imposed else np.where(np.arange(n) < n // 2, 0.3, 1.0)
    i_d, i_q = (-1.0, 4.0) if imposed else (0.0, 3.0)
    w, th = (SPEED_IMPOSED, THETA0) if imposed else (0.0, THETA0)
    u = np.empty((n, 2))
    for k in range(n):
        w_e = P["p"] * w
        u_d = P["R"] * i_d - w_e * P["Lq"] * i_q
        u_q = P["R"] * i_q + w_e * (P["Ld"] * i_d + P["psi"])
        th_mid = th + 0.5 * TS * w_e
        u[k] = [u_d * np.cos(th_mid) - u_q * np.sin(th_mid), u_d * np.sin(th_mid) + u_q * np.cos(th_mid)]
        if not imposed:
            T_e = 1.5 * P["p"] * P["psi"] * i_q
            w += TS * (T_e - load[k] - P["B"] * w) / P["J"]
        th += TS * w_e
    u += rng.uniform(-15.0, 15.0, size=(n, 2))
    return u, load


@functools.cache
def reference_case(salient: bool, mechanics: str):
    P = motor_numbers(salient)
    imposed = mechanics == "imposed"
    u, load = voltage_sequence(P, imposed, seed=7 + 2 * salient + imposed)
    w0 = SPEED_IMPOSED if imposed else 0.0
    ref = scipy_reference(P, [I_DQ0[0], I_DQ0[1], w0, THETA0], u, load, imposed)
    return u, load, ref


# ---------------------------------------------------------------------------------------------------
# Library side: one jit-compiled scan per (frame, mechanics, n_substeps), reused across motors.
# ---------------------------------------------------------------------------------------------------
@eqx.filter_jit
def run_machine(machine, state0, u_ab, load, n_substeps):
    def step(state, inp):
        u, tl = inp
        new = advance(machine, state, MachineInput(u, tl, "stator"), TS, n_substeps)
        return new, new

    _, hist = jax.lax.scan(step, state0, (u_ab, load))
    i_dq = jax.vmap(machine.currents_to_dq)(hist.currents, hist.theta_e)
    return hist, i_dq


@functools.cache
def library_case(salient: bool, mechanics: str, frame: str, n_substeps: int):
    u, load, _ = reference_case(salient, mechanics)
    machine = make_machine(book_motor(salient=salient), frame, mechanics)
    w0 = SPEED_IMPOSED if mechanics == "imposed" else 0.0
    state0 = machine.initial_state(I_DQ0, w0, THETA0)
    hist, i_dq = run_machine(machine, state0, jnp.asarray(u), jnp.asarray(load), n_substeps)
    return jax.tree.map(np.asarray, hist), np.asarray(i_dq)


def wrapped(x):
    return np.mod(x + np.pi, 2.0 * np.pi) - np.pi


def errors(salient, mechanics, frame, n_substeps):
    _, _, ref = reference_case(salient, mechanics)
    hist, i_dq = library_case(salient, mechanics, frame, n_substeps)
    i_peak = np.max(np.linalg.norm(ref[:, :2], axis=1))
    e_i = np.max(np.abs(i_dq - ref[1:, :2])) / i_peak
    e_w = np.max(np.abs(hist.omega_m - ref[1:, 2]))
    e_th = np.max(np.abs(wrapped(hist.theta_e - ref[1:, 3])))
    return e_i, e_w, e_th, i_peak


@pytest.mark.parametrize("n_substeps", [1, 2, 10])
@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("mechanics", ["imposed", "dynamic"])
@pytest.mark.parametrize("salient", [False, True], ids=["surface", "salient"])
def test_frame_matches_scipy(salient, mechanics, frame, n_substeps):
    _, _, ref = reference_case(salient, mechanics)
    hist, _ = library_case(salient, mechanics, frame, n_substeps)
    e_i, e_w, e_th, i_peak = errors(salient, mechanics, frame, n_substeps)
    print(
        f"\n{frame:10s} {mechanics:8s} salient={salient} n={n_substeps:2d}: "
        f"current {e_i:.2e} of {i_peak:.1f} A, speed {e_w:.2e} rad/s, angle {e_th:.2e} rad"
    )
    # The scenario must be demanding: currents of several amperes, and a real acceleration.
    assert i_peak > 5.0
    assert e_i < 1e-3  # the criterion: 0.1 % of the peak current
    assert e_th < 1e-4  # 1e-4 rad electrical (~0.006 deg)
    assert np.all(hist.theta_e >= -np.pi) and np.all(hist.theta_e < np.pi)
    if mechanics == "imposed":
        np.testing.assert_array_equal(hist.omega_m, SPEED_IMPOSED)
    else:
        assert ref[-1, 2] > 100.0  # accelerated to > 950 r/min
        assert e_w < 1e-3 * np.max(np.abs(ref[:, 2]))


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("mechanics", ["imposed", "dynamic"])
@pytest.mark.parametrize("salient", [False, True], ids=["surface", "salient"])
def test_substeps_converge_at_rk4_order(salient, mechanics, frame):
    # The sub-steps really are taken: halving the step divides the error by ~16 (fourth order), and ten
    # sub-steps reach the reference's own accuracy (~1e-11 of the peak).
    e = {n: errors(salient, mechanics, frame, n)[0] for n in (1, 2, 10)}
    assert e[1] / e[2] > 8.0, e
    assert e[10] < max(e[2] / 100.0, 1e-10), e


@pytest.mark.parametrize("mechanics", ["imposed", "dynamic"])
@pytest.mark.parametrize("salient", [False, True], ids=["surface", "salient"])
def test_frames_agree_with_each_other(salient, mechanics):
    base_hist, base_i = library_case(salient, mechanics, "dq", 2)
    i_peak = np.max(np.linalg.norm(base_i, axis=1))
    for frame in ("alpha_beta", "abc"):
        hist, i_dq = library_case(salient, mechanics, frame, 2)
        assert np.max(np.abs(i_dq - base_i)) < 1e-3 * i_peak
        assert np.max(np.abs(hist.omega_m - base_hist.omega_m)) < 1e-3 * max(np.max(base_hist.omega_m), 1.0)
        assert np.max(np.abs(wrapped(hist.theta_e - base_hist.theta_e))) < 1e-4


@pytest.mark.parametrize("mechanics", ["imposed", "dynamic"])
@pytest.mark.parametrize("salient", [False, True], ids=["surface", "salient"])
def test_abc_zero_sequence_stays_zero(salient, mechanics):
    hist, i_dq = library_case(salient, mechanics, "abc", 2)
    i_peak = np.max(np.linalg.norm(i_dq, axis=1))
    assert hist.currents.shape == (N_PERIODS, 3)
    assert np.max(np.abs(hist.currents.sum(axis=1))) < 1e-12 * i_peak


@pytest.mark.parametrize("salient", [False, True], ids=["surface", "salient"])
def test_abc_zero_sequence_decays_through_leakage(salient):
    # A zero-sequence current sees only R and the leakage L_l: i_0(t) = i_0(0) exp(-R t / L_l),
    # independently of the rotor and the balanced part.
    motor = book_motor(salient=salient)
    machine = make_machine(motor, "abc", "imposed")
    s = machine.initial_state((2.0, 3.0), SPEED_IMPOSED, THETA0)
    i0 = 1.5
    state = MachineState(s.currents + i0, s.omega_m, s.theta_e)
    u = jnp.asarray(np.random.default_rng(3).uniform(-50, 50, size=(50, 2)))
    hist, _ = run_machine(machine, state, u, jnp.zeros(50), 10)
    t = TS * np.arange(1, 51)
    expected = i0 * np.exp(-0.958 * t / float(machine.leakage_inductance))
    np.testing.assert_allclose(np.asarray(hist.currents).mean(axis=1), expected, rtol=1e-6)


@pytest.mark.parametrize("salient", [False, True], ids=["surface", "salient"])
def test_torque_equal_in_all_frames(salient):
    P = motor_numbers(salient)
    rng = np.random.default_rng(11)
    i_dq = rng.uniform(-15.0, 15.0, size=(200, 2))
    theta = rng.uniform(-np.pi, np.pi, size=200)
    expected = 1.5 * P["p"] * (P["psi"] * i_dq[:, 1] + (P["Ld"] - P["Lq"]) * i_dq[:, 0] * i_dq[:, 1])
    # Model-frame currents built here in NumPy, not by the library's transforms.
    c, s = np.cos(theta), np.sin(theta)
    i_ab = np.stack([i_dq[:, 0] * c - i_dq[:, 1] * s, i_dq[:, 0] * s + i_dq[:, 1] * c], axis=1)
    i_abc = np.stack(
        [
            i_ab[:, 0],
            -0.5 * i_ab[:, 0] + 0.5 * np.sqrt(3) * i_ab[:, 1],
            -0.5 * i_ab[:, 0] - 0.5 * np.sqrt(3) * i_ab[:, 1],
        ],
        axis=1,
    )
    currents = {"dq": i_dq, "alpha_beta": i_ab, "abc": i_abc}
    motor = book_motor(salient=salient)
    for frame in FRAMES:
        machine = make_machine(motor, frame, "dynamic")
        torque = jax.jit(jax.vmap(machine.torque))(jnp.asarray(currents[frame]), jnp.asarray(theta))
        np.testing.assert_allclose(np.asarray(torque), expected, rtol=1e-11, atol=1e-11)
        # and the state-based accessor agrees, for states built by the library
        states = jax.jit(jax.vmap(machine.initial_state, in_axes=(0, None, 0)))(
            jnp.asarray(i_dq), 0.0, jnp.asarray(theta)
        )
        np.testing.assert_allclose(
            np.asarray(jax.jit(jax.vmap(machine.electromagnetic_torque))(states)),
            expected,
            rtol=1e-11,
            atol=1e-11,
        )
        np.testing.assert_allclose(np.asarray(states.currents), currents[frame], atol=1e-12)
    if salient:
        assert (
            np.max(np.abs(expected - 1.5 * P["p"] * P["psi"] * i_dq[:, 1])) > 1.0
        )  # reluctance torque present


@pytest.mark.parametrize("frame", FRAMES)
def test_rotor_hold_equals_stator_hold_at_standstill(frame):
    # At zero speed the rotor frame does not turn, so holding u_dq = Park(u_ab, theta) is holding u_ab.
    motor = book_motor(salient=True)
    machine = make_machine(motor, frame, "imposed")
    theta = 0.7
    state0 = machine.initial_state((1.0, -2.0), 0.0, theta)
    rng = np.random.default_rng(5)
    u_ab = rng.uniform(-60.0, 60.0, size=(300, 2))
    c, s = np.cos(theta), np.sin(theta)
    u_dq = np.stack([u_ab[:, 0] * c + u_ab[:, 1] * s, -u_ab[:, 0] * s + u_ab[:, 1] * c], axis=1)

    @eqx.filter_jit
    def run(hold_frame, u):
        def step(x, v):
            x = advance(machine, x, MachineInput(v, jnp.zeros(()), hold_frame), TS, 2)
            return x, x

        return jax.lax.scan(step, state0, u)[1]

    h_stator = run("stator", jnp.asarray(u_ab))
    h_rotor = run("rotor", jnp.asarray(u_dq))
    i_scale = np.max(np.abs(np.asarray(h_stator.currents)))
    assert i_scale > 5.0
    np.testing.assert_allclose(
        np.asarray(h_rotor.currents), np.asarray(h_stator.currents), atol=1e-12 * i_scale
    )
    np.testing.assert_allclose(np.asarray(h_rotor.theta_e), theta, rtol=0, atol=1e-15)
    # Sanity (the comparison can fail): holding the same numbers in the other frame differs.
    h_wrong = run("rotor", jnp.asarray(u_ab))
    assert np.max(np.abs(np.asarray(h_wrong.currents) - np.asarray(h_stator.currents))) > 1.0
