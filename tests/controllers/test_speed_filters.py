"""The speed loop's low-pass and notch (pmsmjax/controllers/speed_filters.py): their sampled responses
against the analytic filters, their place in the speed PI, refusals, and gradients against finite
differences."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import signal

from pmsmjax.controllers.design import speed_loop_active_damping
from pmsmjax.controllers.speed_filters import SpeedLoopFilters, low_pass_gain, notch_coefficients
from pmsmjax.presets.three_phase import book_motor
from pmsmjax.spec.validation import ParameterError

TS = 1e-4  # s, the speed loop at the book's 10 kHz control rate


def _response(b, a, f_hz, Ts=TS):
    z = np.exp(1j * 2 * np.pi * np.asarray(f_hz) * Ts)
    return np.polyval(np.asarray(b)[::-1], 1 / z) / np.polyval(np.asarray(a)[::-1], 1 / z)


@pytest.mark.parametrize("f_n", [150.0, 1200.0, 4000.0])
def test_notch_centre_depth_and_unit_gain(f_n):
    b, a = notch_coefficients(f_n, 0.5 * f_n, 20.0, TS)
    # prewarped: the discrete notch's deepest point is exactly at f_n, 20 dB down
    np.testing.assert_allclose(abs(_response(b, a, f_n)), 0.1, rtol=1e-9)
    np.testing.assert_allclose(abs(_response(b, a, 0.0)), 1.0, rtol=1e-12)
    np.testing.assert_allclose(abs(_response(b, a, 0.5 / TS)), 1.0, rtol=1e-9)
    f = np.linspace(0.5 * f_n, min(1.5 * f_n, 0.49 / TS), 2001)
    assert abs(f[np.argmin(abs(_response(b, a, f)))] - f_n) <= f[1] - f[0]


def test_notch_matches_scipy_bilinear_with_prewarping():
    f_n, width, depth = 300.0, 120.0, 30.0
    w_n = 2 * np.pi * f_n
    zp = width / (2 * f_n)
    zz = zp * 10 ** (-depth / 20)
    # scipy's bilinear with prewarping at f_n: fs_eff = w_n / (2 tan(w_n T / 2))
    fs_warped = w_n / (2 * np.tan(w_n * TS / 2))
    b_ref, a_ref = signal.bilinear([1, 2 * zz * w_n, w_n**2], [1, 2 * zp * w_n, w_n**2], fs=fs_warped)
    b, a = notch_coefficients(f_n, width, depth, TS)
    np.testing.assert_allclose(np.asarray(b), b_ref / a_ref[0], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(a), a_ref / a_ref[0], rtol=1e-12)


def test_low_pass_is_the_sampled_first_order_lag():
    f_c = 80.0
    filters = SpeedLoopFilters(speed_filter_hz=f_c)
    state = filters.init(jnp.float64)
    out = []
    for _ in range(200):
        state, y = filters.feedback(state, 1.0, TS)
        out.append(float(y))
    t = TS * np.arange(1, 201)
    np.testing.assert_allclose(out, 1 - np.exp(-2 * np.pi * f_c * t), rtol=1e-12)
    assert float(low_pass_gain(f_c, TS)) == pytest.approx(1 - np.exp(-2 * np.pi * f_c * TS))


def test_filters_in_the_speed_pi():
    pi = speed_loop_active_damping(book_motor(), 50.0)
    assert pi.filters is None and pi.init(jnp.float64).shape == ()  # the plain PI's state unchanged
    filtered = dataclasses.replace(pi, filters=SpeedLoopFilters(500.0, 200.0, 100.0, 20.0))
    state = filtered.init(jnp.float64)
    # at a constant speed and no error, the steady state holds: zero output, the low-pass at the speed
    steady = filtered.steady_state(state, 100.0)
    new, out = filtered.step(steady, 100.0, 100.0, 15.0, TS)
    assert abs(float(out)) < 1e-12
    np.testing.assert_allclose(np.asarray(new[1][0]), 100.0)
    # a large error: the notched output stays inside the limit
    for _ in range(5):
        state, out = filtered.step(state, 500.0, 0.0, 15.0, TS)
        assert abs(float(out)) <= 15.0


def test_refusals():
    with pytest.raises(ParameterError, match="notch_hz, notch_width_hz and notch_depth_db"):
        SpeedLoopFilters(notch_hz=200.0)
    with pytest.raises(ParameterError, match="notch_width_hz = 500 Hz is not below twice"):
        SpeedLoopFilters(None, 200.0, 500.0, 20.0)
    with pytest.raises(ParameterError, match="notch_depth_db = 80 dB"):
        SpeedLoopFilters(None, 200.0, 100.0, 80.0)
    with pytest.raises(ParameterError, match="speed_filter_hz"):
        SpeedLoopFilters(speed_filter_hz=-5.0)
    with pytest.raises(ParameterError, match="Nyquist frequency 2500 Hz"):
        SpeedLoopFilters(None, 3000.0, 1000.0, 20.0).check_rate(2e-4)
    SpeedLoopFilters(None, 2000.0, 1000.0, 20.0).check_rate(2e-4)


def test_gradients_match_finite_differences():
    def loss(p):
        filters = SpeedLoopFilters(p[0], p[1], p[2], p[3])
        state = filters.init(jnp.float64)
        total = 0.0
        for k in range(60):
            x = jnp.sin(2 * jnp.pi * 250.0 * k * TS)
            state, w = filters.feedback(state, x, TS)
            state, y = filters.reference(state, w, TS)
            total = total + y**2
        return total

    p = jnp.array([600.0, 240.0, 120.0, 18.0])
    g = jax.grad(loss)(p)
    for i in range(4):
        h = 1e-4 * float(p[i])
        e = jnp.zeros(4).at[i].set(h)
        fd = (loss(p + e) - loss(p - e)) / (2 * h)
        np.testing.assert_allclose(float(g[i]), float(fd), rtol=1e-5, atol=1e-10)
