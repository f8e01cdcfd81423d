"""The generalised drive's plumbing: scenario timing by period index, the sample a controller sees, the
estimator slot (exact sensor, encoder) and the checks that refuse an inconsistent drive.

References are independent of the code under test: integer arithmetic for event timing, the averaged
bridge's own returned period average for the sampled voltage, and the encoder's quantum and tracking-loop
dynamics written out here.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pmsmjax
from pmsmjax import Profile, Scenario, presets
from pmsmjax.estimators import Encoder, ExactSensor
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.simulate import period_inputs

TS = 1e-4


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
@pytest.mark.parametrize("event_s", [0.2352, 0.2, 0.0301, 0.0999])
def test_events_land_in_their_period_in_float32_and_float64(dtype, event_s):
    """A step at a whole number of periods acts from exactly that period on (integer reference)."""
    n = 3000
    profile = jax.tree.map(lambda a: a.astype(dtype), Profile.step(event_s, 0.0, 10.0))
    values = np.asarray(profile.sample_periods(n, TS))
    k_event = round(event_s / TS)
    expected = np.where(np.arange(n) >= k_event, 10.0, 0.0)
    np.testing.assert_array_equal(values, expected)
    assert values.dtype == dtype


def test_float_time_sampling_was_late_in_float32():
    """The motivating case: comparing float32 times k Ts with 0.2352 s puts the step one period late."""
    t = jnp.arange(3000, dtype=jnp.float32) * jnp.float32(TS)
    late = np.argmax(np.asarray(t >= jnp.float32(0.2352)))
    assert late == 2353  # the bug the period index removes (see the test above: 2352 there)


def test_ramp_between_events_is_linear_in_period_units():
    n = 100
    values = np.asarray(Profile.ramp(2e-3, 6e-3, 0.0, 4.0).sample_periods(n, TS))
    k = np.arange(n)
    expected = np.clip((k - 20) / 40.0, 0.0, 1.0) * 4.0
    np.testing.assert_allclose(values, expected, atol=1e-12)


@pytest.fixture(scope="module")
def book():
    return presets.book_drive(), presets.book_scenario(duration_s=0.1, load_time_s=0.05)


def test_exact_sensor_estimate_is_the_plant(book):
    drive, scenario = book
    tr = pmsmjax.simulate(drive, scenario)
    assert isinstance(drive.estimator, ExactSensor) and not drive.records_estimate
    np.testing.assert_array_equal(np.asarray(tr.theta_e_est), np.asarray(tr.theta_e))
    np.testing.assert_array_equal(np.asarray(tr.omega_m_est), np.asarray(tr.omega_m))


def test_sample_holds_what_was_applied(book):
    """The sampled 'last voltage' is the period average the averaged bridge applied in the last period."""
    drive, scenario = book
    xs = period_inputs(scenario, drive.Ts)
    state = drive.init()
    for k in range(5):
        x = jax.tree.map(lambda a, k=k: a[k], xs)
        duties_applied = state.pending_duties
        _, u_ab_bridge = drive.bridge.advance(
            drive.machine, state.machine, duties_applied, x.load_torque, drive.Ts, drive.n_substeps
        )
        state, _ = drive.step(state, x)
        sample = drive.sample(state.machine, state.last_duties)
        np.testing.assert_allclose(np.asarray(sample.u_ab_last), np.asarray(u_ab_bridge), atol=1e-12)
        ref = abc_to_alpha_beta(phase_voltages(duties_applied, drive.bridge.u_dc))
        np.testing.assert_allclose(np.asarray(sample.u_ab_last), np.asarray(ref), atol=1e-12)
        i_abc = np.asarray(sample.i_phase)
        assert abs(i_abc.sum()) < 1e-12  # a star with isolated neutral


def test_encoder_quantum_and_tracking():
    """Encoder on the book drive: counted angle within one quantum of the truth (no delay), tracked speed
    close to the true speed in steady state, and the drive still meets the book scenario."""
    lines = 1024
    encoder = Encoder(lines=lines, pole_pairs=4, speed_bandwidth=2000.0)
    drive = eqx.tree_at(lambda d: d.estimator, presets.book_drive(), encoder)
    scenario = presets.book_scenario(duration_s=0.3, load_time_s=0.2)
    tr = pmsmjax.simulate(drive, scenario)
    quantum = 2 * math.pi * 4 / (4 * lines)
    assert encoder.quantum_rad == pytest.approx(quantum)
    # The counted angle is the truth floored to a count: error in [-quantum, 0] (modulo 2 pi).
    err = np.angle(np.exp(1j * (np.asarray(tr.theta_e_est) - np.asarray(tr.theta_e))))
    assert err.max() <= 1e-9 and err.min() >= -quantum - 1e-9
    # Steady state at 1000 r/min before the load: tracked speed within 0.5 % of the true speed.
    window = (np.asarray(tr.t) > 0.15) & (np.asarray(tr.t) < 0.2)
    speed_err = np.abs(np.asarray(tr.omega_m_est - tr.omega_m))[window]
    assert speed_err.max() < 0.005 * 104.72
    # The speed loop on the encoder ends where the exact-sensor drive does (the tracking loop's lag,
    # about acceleration / bw = 5500 / 2000 rad/s while accelerating, changes the transient only).
    exact = pmsmjax.simulate(presets.book_drive(), scenario)
    assert abs(float(tr.omega_m[-1] - exact.omega_m[-1])) < 0.005 * 104.72


def test_encoder_delay_is_compensated_by_the_tracked_speed():
    """With a 50 us count latency the estimate adds omega_e * delay back: the mean angle error stays
    within a quantum, where the uncompensated latency alone would be omega_e * delay (0.021 rad here)."""
    delay = 50e-6
    encoder = Encoder(lines=4096, pole_pairs=4, delay_s=delay, speed_bandwidth=500.0)
    drive = eqx.tree_at(lambda d: d.estimator, presets.book_drive(), encoder)
    tr = pmsmjax.simulate(drive, presets.book_scenario(duration_s=0.2, load_time_s=0.15))
    window = np.asarray(tr.t) > 0.1
    err = np.angle(np.exp(1j * (np.asarray(tr.theta_e_est) - np.asarray(tr.theta_e))))[window]
    uncompensated = 4 * 104.72 * delay
    assert abs(err.mean()) < 0.1 * uncompensated
    assert abs(err.mean()) < encoder.quantum_rad


def test_encoder_refuses_an_unstable_tracking_loop():
    drive = presets.book_drive()
    with pytest.raises(pmsmjax.ParameterError, match=r"Encoder.speed_bandwidth .* too fast"):
        pmsmjax.Drive(
            drive.machine,
            drive.controller,
            drive.modulator,
            drive.bridge,
            TS,
            estimator=Encoder(lines=1000, pole_pairs=4, speed_bandwidth=8000.0),
        )


def test_voltage_controller_needs_a_modulator():
    drive = presets.book_drive()
    with pytest.raises(pmsmjax.ParameterError, match="give the Drive a modulator"):
        pmsmjax.Drive(drive.machine, drive.controller, None, drive.bridge, TS)


def test_batches_of_encoder_drives_equal_single_runs():
    """vmap over encoder bandwidths: each row equals its own single run."""
    base = eqx.tree_at(lambda d: d.estimator, presets.book_drive(), Encoder(lines=2048, pole_pairs=4))
    scenario = Scenario(0.02, speed_ref=Profile.constant(50.0))
    bws = jnp.array([200.0, 800.0])
    batch = jax.vmap(
        lambda bw: pmsmjax.simulate(eqx.tree_at(lambda d: d.estimator.speed_bandwidth, base, bw), scenario)
    )(bws)
    for i, bw in enumerate(bws):
        single = pmsmjax.simulate(eqx.tree_at(lambda d: d.estimator.speed_bandwidth, base, bw), scenario)
        np.testing.assert_allclose(
            np.asarray(batch.omega_m_est[i]), np.asarray(single.omega_m_est), rtol=1e-12
        )
