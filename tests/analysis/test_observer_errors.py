"""The observer figures of :mod:`pmsmjax.analysis.observer_errors` on hand-made cases: wrapped angle errors
(modulo 2 pi and pi, NumPy and JAX alike), the out-of-lock criterion at its thresholds, run lengths and the
10 ms lock window, the full-record figures of hand-made traces, error statistics of a log, and the
differentiable RMS and chord of the tuning objectives."""

import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.analysis import observer_errors as om

TS = 1e-4


def fake_trace(angle_error_rad, speed_error, speed_ref=100.0):
    """A trace whose estimate is off the plant by the given per-period errors (NumPy, period TS)."""
    n = len(angle_error_rad)
    theta = np.linspace(0.0, 40.0, n)
    omega = np.full(n, speed_ref)
    return SimpleNamespace(
        t=np.arange(n) * TS,
        theta_e=theta,
        theta_e_est=theta + np.asarray(angle_error_rad),
        omega_m=omega,
        omega_m_est=omega + np.asarray(speed_error),
        speed_ref=np.full(n, speed_ref),
    )


# --- per sample -----------------------------------------------------------------------------------------


def test_angle_error_wraps():
    e = om.angle_error(np.array([3.1, -3.1, 0.1]), np.array([-3.1, 3.1, 2 * math.pi]))
    np.testing.assert_allclose(e, [6.2 - 2 * math.pi, 2 * math.pi - 6.2, 0.1], atol=1e-12)


def test_angle_error_modulo_pi_and_its_kinds():
    """3 rad off is 3 - pi modulo pi; 1.6 rad off is 1.6 - pi (beyond pi/2). NumPy float64 and JAX give the
    same bits, NumPy float32 stays float32, and the JAX form traces."""
    est = np.array([3.0, 1.6, -1.6, 0.2]) + 10.0
    theta = np.full(4, 10.0)
    expected = [3.0 - math.pi, 1.6 - math.pi, math.pi - 1.6, 0.2]
    np.testing.assert_allclose(om.angle_error_modulo_pi(est, theta), expected, atol=1e-13)
    np.testing.assert_allclose(om.angle_error(est, theta, math.pi), expected, atol=1e-13)
    traced = jax.jit(om.angle_error_modulo_pi)(jnp.asarray(est), jnp.asarray(theta))  # float64 (conftest)
    np.testing.assert_array_equal(np.asarray(traced), om.angle_error_modulo_pi(est, theta))
    assert om.angle_error(est.astype(np.float32), theta.astype(np.float32)).dtype == np.float32


def test_out_of_lock_at_its_thresholds():
    """Angle beyond 90 deg (45 deg modulo pi) or speed error beyond 0.5 |w*| + 1 rad/s (here 51 rad/s)."""
    ref = np.full(6, -100.0)
    e_theta = np.array([1.57, 1.58, 0.0, 0.0, 0.78, 0.79])
    e_speed = np.array([0.0, 0.0, 50.9, -51.1, 0.0, 0.0])
    np.testing.assert_array_equal(om.out_of_lock(e_theta, e_speed, ref), [0, 1, 0, 1, 0, 0])
    np.testing.assert_array_equal(om.out_of_lock(e_theta, e_speed, ref, modulo_pi=True), [1, 1, 0, 1, 0, 1])
    np.testing.assert_array_equal(om.out_of_lock(e_theta, e_speed, ref, speed_lock=False), [0, 1, 0, 0, 0, 0])
    # a zero reference keeps a 1 rad/s floor
    np.testing.assert_array_equal(om.out_of_lock(np.zeros(2), np.array([0.9, 1.1]), np.zeros(2)), [0, 1])


def test_run_lengths_and_the_lock_window():
    flags = np.array([0, 1, 1, 0, 1, 1, 1, 0, 1], bool)
    assert om.longest_run(flags) == 3 and om.longest_run(np.zeros(5, bool)) == 0
    # the Monte Carlo kernel's way: a scan carries the run and keeps its maximum
    (_, longest), _ = jax.lax.scan(
        lambda c, f: ((om.out_of_lock_run(c[0], f), jnp.maximum(c[1], om.out_of_lock_run(c[0], f))), None),
        (jnp.int32(0), jnp.int32(0)),
        jnp.asarray(flags),
    )
    assert int(longest) == 3
    assert not om.lock_lost(100, TS) and om.lock_lost(101, TS)  # 10 ms is not longer than 10 ms


# --- over a full record ----------------------------------------------------------------------------------


def test_observer_errors_of_a_hand_made_trace():
    n = 1500  # 0.15 s; periods from 0.05 s (k = 500) count
    e = np.zeros(n)
    e[:500] = 3.0  # before convergence: ignored, although out of lock
    e[600:700] = 0.2  # 100 periods of 0.2 rad
    e[800:901] = -2.0  # 101 periods out of lock: 10.1 ms > 10 ms
    trace = fake_trace(e, np.zeros(n))
    out = om.observer_errors(trace, TS)
    rms = math.sqrt((100 * 0.2**2 + 101 * 2.0**2) / 1000)
    assert out["angle_error_rms_deg"] == pytest.approx(math.degrees(rms), rel=1e-9)
    assert out["angle_error_max_deg"] == pytest.approx(math.degrees(2.0), rel=1e-9)
    assert out["lock_lost"] and out["longest_out_of_lock_s"] == pytest.approx(101 * TS)
    e[900] = 0.0  # now exactly 100 periods (10 ms): not longer than the window
    assert not om.observer_errors(fake_trace(e, np.zeros(n)), TS)["lock_lost"]
    # the speed criterion alone: 0.5 * 100 + 1 = 51 rad/s
    w = np.zeros(n)
    w[1000:1200] = 52.0
    out = om.observer_errors(fake_trace(np.zeros(n), w), TS)
    assert out["lock_lost"] and out["speed_error_rms_rpm"] == pytest.approx(
        30 / math.pi * math.sqrt(200 * 52.0**2 / 1000), rel=1e-9
    )
    assert out["speed_error_max_rpm"] == pytest.approx(30 / math.pi * 52.0, rel=1e-12)
    assert out["speed_tracking_rms_rpm"] == 0.0  # the plant holds its reference
    w[1000:1200] = 50.0
    assert not om.observer_errors(fake_trace(np.zeros(n), w), TS)["lock_lost"]


def test_observer_errors_are_scored_in_float64_from_a_float32_trace():
    """The wrapped difference of float32 angles, here 1e-4 rad, would lose about 1e-3 of itself to the
    float32 rounding of ``e + pi`` (spacing 2.4e-7 rad); the figures come from float64 copies instead."""
    n = 1000
    trace = fake_trace(np.full(n, 1e-4), np.zeros(n))
    single = SimpleNamespace(**{k: np.asarray(v, np.float32) for k, v in vars(trace).items()})
    e = single.theta_e_est.astype(np.float64) - single.theta_e.astype(np.float64)
    exact = np.degrees(np.sqrt(np.mean(e[500:] ** 2)))
    assert om.observer_errors(single, TS)["angle_error_rms_deg"] == pytest.approx(exact, rel=1e-12)


def test_speed_held_definition():
    n = 1000
    trace = fake_trace(np.zeros(n), np.zeros(n), speed_ref=10.0)
    trace.omega_m = trace.omega_m.copy()
    trace.omega_m[-1] = 10.0 - 0.99  # error 0.99 <= 10 % of 10 rad/s
    held = om.speed_held(trace, TS, 0.08)
    assert held["held"] and held["speed_error_max_rpm"] == pytest.approx(0.99 * 30 / math.pi, rel=1e-12)
    trace.omega_m[-1] = 10.0 - 1.01
    assert not om.speed_held(trace, TS, 0.08)["held"]
    trace.omega_m[-1] = 10.0
    trace.theta_e_est = trace.theta_e.copy()
    trace.theta_e_est[-1] += math.radians(31.0)
    held = om.speed_held(trace, TS, 0.08)
    assert not held["held"] and held["angle_error_max_deg"] == pytest.approx(31.0, rel=1e-9)


def test_error_statistics_of_a_log():
    """After 0.01 s: the angle off by +0.1 rad then -0.3 rad (mean -0.1, RMS sqrt(0.05)), the speed by
    +-2 rad/s alternately (RMS 2 rad/s); the first 100 rows are ignored."""
    n = 500
    time = 1.0 + np.arange(n) * TS  # the log's clock need not start at 0
    theta = np.linspace(-3.0, 3.0, n)
    e = np.concatenate([np.full(100, 2.0), np.full(200, 0.1), np.full(200, -0.3)])
    w = 50.0 + np.concatenate([np.full(100, 9.0), np.tile([2.0, -2.0], 200)])
    s = om.error_statistics(time, theta + e, w, theta, np.full(n, 50.0), settle_s=100 * TS - 1e-9)
    assert s["samples"] == 400
    assert s["angle_mean_deg"] == pytest.approx(math.degrees(-0.1), rel=1e-12)
    assert s["angle_rms_deg"] == pytest.approx(math.degrees(math.sqrt(0.05)), rel=1e-12)
    assert s["angle_max_deg"] == pytest.approx(math.degrees(0.3), rel=1e-12)
    assert s["speed_rms_rpm"] == pytest.approx(2.0 * 30 / math.pi, rel=1e-12)
    assert s["speed_max_rpm"] == pytest.approx(2.0 * 30 / math.pi, rel=1e-12)
    pi_off = om.error_statistics(time, theta + e + math.pi, w, theta, np.full(n, 50.0), 0.0, modulo_pi=True)
    assert pi_off["angle_max_deg"] == pytest.approx(math.degrees(math.pi - 2.0), rel=1e-9)  # 2 rad: 2 - pi


def test_rms_and_max_abs():
    x = np.array([[3.0, -4.0], [0.0, 0.0]])
    rms, largest = om.rms_and_max_abs(x, axis=1)
    np.testing.assert_allclose(rms, [math.sqrt(12.5), 0.0])
    np.testing.assert_array_equal(largest, [4.0, 0.0])


# --- over a traced window (the tuning objectives) ----------------------------------------------------------


@pytest.mark.parametrize("period", [2 * math.pi, math.pi])
def test_windowed_angle_rms_and_chord(period):
    """A constant error e0 inside the window (outside it: 3 rad, not counted): RMS |e0| wrapped to the
    period, chord |2 sin(e0/2)| (modulo pi: |sin(e0)|)."""
    n = 400
    theta = np.linspace(-3.0, 3.0, n)
    weight = np.repeat([0.0, 1.0], n // 2)
    for e0 in (0.05, -0.4, 2.5):
        err = np.where(weight > 0, e0, 3.0)
        wrapped = (e0 + period / 2) % period - period / 2
        m = 2 * math.pi / period
        rms = float(om.angle_error_rms(theta + err, theta, weight, period))
        chord = float(om.angle_chord_rms(theta + err, theta, weight, period))
        assert rms == pytest.approx(abs(wrapped), rel=1e-12)
        assert chord == pytest.approx(abs(2.0 * math.sin(m * e0 / 2.0)) / m, rel=1e-12)


def test_windowed_angle_rms_is_differentiable_at_zero_and_propagates_nan():
    theta = jnp.linspace(-3.0, 3.0, 50)
    weight = jnp.ones(50)
    for figure in (om.angle_error_rms, om.angle_chord_rms):
        g = jax.grad(lambda est, f=figure: f(est, theta, weight))(theta)
        np.testing.assert_array_equal(np.asarray(g), 0.0)  # exact sensor: zero error, zero gradient
        assert math.isnan(float(figure(theta.at[3].set(jnp.nan), theta, weight)))
