"""Magnet flux harmonics and cogging torque (pmsmjax/machines/harmonics.py) against independent references,
in float64 (conftest).

- Power balance in every three-phase plant (dq, alpha-beta, abc, flux map): electrical input = copper loss
  + rate of magnetic energy (the flux map: the field's power ``1.5 i . L_inc di/dt``) + rate of cogging
  co-energy + shaft power, to float rounding.
- The frames agree: the same closed-loop run in the dq, alpha-beta and abc models gives the same trace.
- The open-circuit line EMF over one electrical revolution at constant speed, by FFT, against the analytic
  spectrum ``sqrt(3) k w_e A_k`` at the phase ``phi_k + pi/2 + arg(1 - exp(-j 2 pi k / 3))`` of each order.
- The cogging torque at standstill against the formula, and against ``-dW_cog/dtheta_m`` by differences.
- Refusals of orders; gradients through the amplitudes and phases against central differences.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.assemble import with_parts
from pmsmjax.frames.three_phase import alpha_beta_to_abc, inverse_park
from pmsmjax.machines import MachineInput, MachineState
from pmsmjax.machines.harmonics import MagnetHarmonics
from pmsmjax.machines.pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
from pmsmjax.presets.three_phase import book_drive, book_motor
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError
from tests.helpers.gradient_check import check_gradient

FLUX = [[5, 0.0019, 0.4], [7, 0.0009, -1.1], [11, 0.0004, 2.0]]
COGGING = [[6, 0.045, 0.3], [12, 0.018, -0.8]]


def harmonics():
    return MagnetHarmonics.from_rows(FLUX, COGGING)


def _flux_map_machine():
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec

    return spec_drive(drive_spec("saturated-ipm")).machine


def machine_in(frame: str, motor=None, h=None):
    h = harmonics() if h is None else h
    if frame == "flux_map":
        return with_parts(_flux_map_machine(), {"harmonics": h})
    maker = {"dq": PMSMdq, "alpha_beta": PMSMAlphaBeta, "abc": PMSMabc}[frame]
    return maker(motor, harmonics=h)


def _balance_terms(machine, currents, omega_m, theta_e, u_ab, load):
    state = MachineState(currents, omega_m, theta_e)
    dx = machine.vector_field(None, state, MachineInput(u_ab, load))
    i_dq = machine.currents_dq(state)
    m = machine.motor
    h = machine.harmonics
    if isinstance(machine, PMSMabc):
        p_in = alpha_beta_to_abc(u_ab) @ currents
        field = lambda x: 0.5 * x.currents @ machine.inductance(x.theta_e) @ x.currents
    elif isinstance(machine, PMSMAlphaBeta):
        p_in = 1.5 * u_ab @ currents
        field = lambda x: 1.5 * 0.5 * x.currents @ machine.inductance(x.theta_e) @ x.currents
    elif isinstance(machine, PMSMdq):
        p_in = 1.5 * u_ab @ inverse_park(i_dq, theta_e)
        field = lambda x: 1.5 * (0.5 * m.L_d * x.currents[0] ** 2 + 0.5 * m.L_q * x.currents[1] ** 2)
    else:  # flux map: the field's power 1.5 i . L_inc(i) di/dt (its energy when the map is reciprocal)
        p_in = 1.5 * u_ab @ inverse_park(i_dq, theta_e)
        field_power = 1.5 * currents @ (machine.flux_and_inductance(currents)[1] @ dx.currents)
        _, dW_cog = jax.jvp(lambda th: h.cogging_energy(th, m.pole_pairs), (theta_e,), (dx.theta_e,))
        p_cu = 1.5 * m.R * (i_dq @ i_dq)
        p_mech = m.J * omega_m * dx.omega_m + m.B * omega_m**2 + load * omega_m
        return p_in, p_cu, field_power + dW_cog, p_mech
    energy = lambda x: field(x) + h.cogging_energy(x.theta_e, m.pole_pairs)
    _, dW = jax.jvp(energy, (state,), (dx,))
    p_cu = 1.5 * m.R * (i_dq @ i_dq)
    p_mech = m.J * omega_m * dx.omega_m + m.B * omega_m**2 + load * omega_m
    return p_in, p_cu, dW, p_mech


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc", "flux_map"])
def test_power_balance_with_harmonics(frame):
    machine = machine_in(frame, book_motor(salient=True))
    rng = np.random.default_rng(3)
    residuals = []
    for _ in range(5):
        th = jnp.asarray(rng.uniform(-np.pi, np.pi))
        i_dq = jnp.asarray(rng.uniform(-10, 10, 2))
        currents = machine.currents_from_dq(i_dq, th)
        omega_m, u_ab = jnp.asarray(rng.uniform(-150, 150)), jnp.asarray(rng.uniform(-200, 200, 2))
        terms = _balance_terms(machine, currents, omega_m, th, u_ab, 2.0)
        p_in, p_cu, dW, p_mech = (float(x) for x in terms)
        scale = abs(p_in) + abs(p_cu) + abs(dW) + abs(p_mech)
        residuals.append(abs(p_in - (p_cu + dW + p_mech)) / scale)
    assert max(residuals) < 1e-12


@pytest.mark.parametrize("frame", ["dq", "alpha_beta", "abc", "flux_map"])
def test_cogging_torque_at_standstill(frame):
    machine = machine_in(frame, book_motor())
    p = machine.motor.pole_pairs
    angles = jnp.linspace(-np.pi, np.pi, 37)
    zero = machine.currents_from_dq(jnp.zeros(2), jnp.asarray(0.0))
    torque = jax.vmap(lambda th: machine.torque(zero, th))(angles)
    expected = sum(a * np.sin(k * np.asarray(angles) + ph) for k, a, ph in COGGING)
    np.testing.assert_allclose(np.asarray(torque), expected, rtol=0, atol=1e-14)
    # conservative: T_cog = -dW_cog/dtheta_m, theta_e = p theta_m (central differences in theta_m)
    h = machine.harmonics
    dth_m = 1e-5
    w = lambda th: float(h.cogging_energy(jnp.asarray(th), p))
    for th in np.asarray(angles[::6]):
        dW = (w(th + p * dth_m) - w(th - p * dth_m)) / (2 * dth_m)
        np.testing.assert_allclose(-dW, float(h.cogging_torque(jnp.asarray(th))), rtol=0, atol=1e-9)


def _open_circuit_emf_abc(machine, omega_e, theta):
    """``(3,)`` phase EMF (V) at zero current: the voltage that holds ``di/dt = 0``, from the model's own
    equations (``L di/dt = u - R i - e`` at ``u = 0``, ``i = 0``)."""
    state = MachineState(machine.currents_from_dq(jnp.zeros(2), theta), omega_e / 4.0, theta)
    di = machine.vector_field(None, state, MachineInput(jnp.zeros(2), 0.0)).currents
    if isinstance(machine, PMSMabc):
        return -machine.inductance(theta) @ di
    m = machine.motor
    e_dq = -jnp.stack([m.L_d * di[0], m.L_q * di[1]])
    return alpha_beta_to_abc(inverse_park(e_dq, theta))


@pytest.mark.parametrize("frame", ["dq", "abc"])
def test_line_emf_spectrum(frame):
    machine = machine_in(frame, book_motor())
    omega_e = 4.0 * 100.0
    n = 256
    theta = 2 * np.pi * np.arange(n) / n  # one electrical revolution at constant speed
    e = np.asarray(jax.vmap(lambda th: _open_circuit_emf_abc(machine, omega_e, th))(jnp.asarray(theta)))
    line = e[:, 0] - e[:, 1]
    spectrum = 2.0 * np.fft.rfft(line) / n
    psi_f = float(machine.motor.psi_f)
    expected = {1: (psi_f, 0.0)} | {k: (a, ph) for k, a, ph in FLUX}
    errors = []
    for k, (a, ph) in expected.items():
        want = (
            np.sqrt(3)
            * k
            * omega_e
            * a
            * np.exp(1j * (ph + np.pi / 2 + np.angle(1 - np.exp(-2j * np.pi * k / 3))))
        )
        errors.append(abs(spectrum[k] - want) / abs(want))
    assert max(errors) < 1e-12
    others = np.delete(np.abs(spectrum), [0] + list(expected))
    assert others.max() < 1e-12 * np.abs(spectrum[1])  # no other order, no triplen in the line voltage


SCENARIO = Scenario(
    duration_s=0.02, speed_ref=Profile.constant(30.0), load_torque=Profile.step(0.01, 0.0, 2.0)
)


@pytest.fixture(scope="module")
def frame_traces():
    motor = book_motor(salient=True)
    out = {}
    for frame in ("dq", "alpha_beta", "abc"):
        drive = with_parts(book_drive(motor, frame=frame), {"machine.harmonics": harmonics()})
        out[frame] = simulate(drive, SCENARIO)
    return out


@pytest.mark.parametrize("frame", ["alpha_beta", "abc"])
def test_frames_agree(frame_traces, frame):
    ref, other = frame_traces["dq"], frame_traces[frame]
    for name in ("omega_m", "theta_e", "i_dq", "torque"):
        a, b = np.asarray(getattr(ref, name)), np.asarray(getattr(other, name))
        scale = np.abs(a).max()
        assert np.abs(a - b).max() < 1e-9 * scale, name
    # the run does show the harmonics: the dq current ripples at the 6th order
    assert np.ptp(np.asarray(ref.i_dq)[100:, 1]) > 0.05


def test_orders_refused():
    with pytest.raises(ParameterError, match="triplen"):
        MagnetHarmonics.from_rows([[9, 0.001, 0.0]])
    with pytest.raises(ParameterError, match="fundamental"):
        MagnetHarmonics.from_rows([[1, 0.001, 0.0]])
    with pytest.raises(ParameterError, match="whole number"):
        MagnetHarmonics.from_rows(cogging=[[6.5, 0.01, 0.0]])
    with pytest.raises(ParameterError, match="as many"):
        MagnetHarmonics((5,), [0.001, 0.002], [0.0, 0.0])


def test_gradients_through_harmonics():
    motor = book_motor()
    base = book_drive(motor)
    scenario = Scenario(duration_s=0.005, speed_ref=Profile.constant(20.0), load_torque=Profile.constant(0.0))

    def loss(params):
        h = MagnetHarmonics(
            (5, 7), params["flux_a"], params["flux_phi"], (6,), params["cog_a"], params["cog_phi"]
        )
        trace = simulate(with_parts(base, {"machine.harmonics": h}), scenario)
        return jnp.mean(trace.omega_m**2) + jnp.mean(trace.i_dq[:, 1] ** 2)

    x = {
        "flux_a": jnp.array([0.0019, 0.0009]),
        "flux_phi": jnp.array([0.4, -1.1]),
        "cog_a": jnp.array([0.045]),
        "cog_phi": jnp.array([0.3]),
    }
    check_gradient(jax.jit(loss), x, rel_step=1e-4, step_floor=1e-2, rtol=1e-5, atol=1e-10)
