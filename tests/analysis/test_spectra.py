"""Spectra and THD (pmsmjax.analysis.spectra) against closed-form Fourier series.

- Six-step phase voltage (isolated neutral): components ``2 U_dc / (n pi)`` at ``n = 6k +- 1``, zero
  elsewhere; its THD over all orders is ``sqrt(pi^2/9 - 1) = 31.08 %``, and up to order N the partial sum.
- Sampled sinusoids: amplitudes and DC exactly.
"""

import numpy as np
import pytest

from pmsmjax.analysis.spectra import piecewise_constant_spectrum, sampled_spectrum, thd

U_DC = 300.0
F1 = 50.0


def six_step(cycles):
    """Interval bounds (s) and phase-to-neutral voltages (V) of six-step operation over ``cycles``."""
    states = np.array([[1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1], [1, 0, 1]], float)
    # start half a sextant early so phase a's fundamental is a cosine (its high state is centred at 0)
    times = (np.arange(6 * cycles + 1) - 0.5) / (6 * F1)
    s = np.tile(states, (cycles, 1))
    return times, U_DC * (s - s.mean(axis=1, keepdims=True))


def test_six_step_spectrum_is_the_closed_form():
    cycles, n_max = 2, 2 * 200
    times, u = six_step(cycles)
    spec = piecewise_constant_spectrum(times, u, cycles, n_max)
    orders = spec.harmonic_orders()
    h = np.round(orders).astype(int)
    whole = np.isclose(orders, h)
    expected = np.where(
        whole & (h % 2 == 1) & (h % 3 != 0), 2 * U_DC / (np.pi * np.maximum(orders, 1e-9)), 0.0
    )
    expected[0] = 0.0
    np.testing.assert_allclose(spec.amplitudes[:, 0], expected, rtol=0, atol=1e-9 * U_DC)
    assert spec.fundamental[0] == pytest.approx(2 * U_DC / np.pi, rel=1e-12)
    # the three phases have the same spectrum (balanced)
    np.testing.assert_allclose(spec.amplitudes[:, 1], spec.amplitudes[:, 0], atol=1e-9 * U_DC)
    # THD up to order 200 is the partial sum; over all orders sqrt(pi^2/9 - 1)
    n = np.arange(2, 201)
    partial = np.sqrt(np.sum(1.0 / n[(n % 2 == 1) & (n % 3 != 0)] ** 2))
    got = thd(spec, f_max_hz=200 * F1)
    np.testing.assert_allclose(got, partial, rtol=1e-9)
    assert abs(got[0] - np.sqrt(np.pi**2 / 9 - 1)) < 3e-3  # tail beyond order 200: about 1/(3 * 200)


def test_window_origin_does_not_matter():
    times, u = six_step(2)
    a = piecewise_constant_spectrum(times, u, 2, 60).amplitudes
    b = piecewise_constant_spectrum(times + 0.123, u, 2, 60).amplitudes
    np.testing.assert_allclose(a, b, atol=1e-9 * U_DC)


def test_sampled_spectrum_of_sinusoids():
    cycles, N = 3, 600
    t = np.arange(N) / N * cycles / F1
    w = 2 * np.pi * F1
    x = 1.2 + 3.0 * np.cos(w * t + 0.2) + 0.5 * np.cos(5 * w * t - 1.0) + 0.1 * np.sin(17 * w * t)
    spec = sampled_spectrum(x, cycles / F1, cycles)
    expected = np.zeros(spec.amplitudes.shape)
    expected[[0, 3, 15, 51]] = [1.2, 3.0, 0.5, 0.1]
    np.testing.assert_allclose(spec.amplitudes, expected, atol=1e-12)
    assert thd(spec, 20 * F1) == pytest.approx(np.hypot(0.5, 0.1) / 3.0, rel=1e-12)
    assert thd(spec, 10 * F1) == pytest.approx(0.5 / 3.0, rel=1e-12)


def test_bad_requests_are_rejected():
    times, u = six_step(1)
    with pytest.raises(ValueError, match="cycles"):
        piecewise_constant_spectrum(times, u, 0, 10)
    with pytest.raises(ValueError, match="Nyquist"):
        sampled_spectrum(np.zeros(64), 0.02, 1, n_max=40)
    with pytest.raises(ValueError, match="below f_max"):
        thd(piecewise_constant_spectrum(times, u, 1, 10), 20 * F1)
