"""The figures of merit of :mod:`pmsmjax.analysis.metrics` on signals whose figures are known in closed form:
exponential errors (ITAE/IAE/ISE as geometric sums and as integrals), first- and second-order step
responses (rise time tau ln 9, settling time tau ln 50, overshoot exp(-zeta pi / sqrt(1 - zeta^2))), a
load dip of known depth and recovery (a root found by scipy), balanced sinusoids (peak and RMS currents,
ripple), and hand-made flags. The scan accumulation of the per-period terms, as the Monte Carlo kernel does
it, is checked against the full-record figures."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq

from pmsmjax.analysis import metrics

DT = 1e-4


def first_order_step(tau, n, y_start=0.0, y_final=1.0):
    t = np.arange(n) * DT
    return t, y_final + (y_start - y_final) * np.exp(-t / tau)


def second_order_step(zeta, omega_n, n_peak, n):
    """Unit step response of ``omega_n^2 / (s^2 + 2 zeta omega_n s + omega_n^2)``, sampled so that the peak
    time ``pi / omega_d`` is sample ``n_peak``."""
    omega_d = omega_n * math.sqrt(1.0 - zeta**2)
    t = np.arange(n) * (math.pi / omega_d) / n_peak
    decay = np.exp(-zeta * omega_n * t)
    return t, 1.0 - decay * (np.cos(omega_d * t) + zeta / math.sqrt(1.0 - zeta**2) * np.sin(omega_d * t))


# --- integral criteria -----------------------------------------------------------------------------------


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_integral_criteria_of_an_exponential_error(sign):
    """e_k = E0 q^k (q = exp(-dt/tau)): the sums are geometric, and near the integrals of E0 exp(-t/tau)."""
    e0, tau, n = 3.0, 5e-3, 2000  # 0.2 s = 40 tau
    t = np.arange(n) * DT
    e = sign * e0 * np.exp(-t / tau)
    q = math.exp(-DT / tau)
    iae = e0 * DT * (1 - q**n) / (1 - q)
    ise = e0**2 * DT * (1 - q ** (2 * n)) / (1 - q**2)
    itae = e0 * DT**2 * q * (1 - n * q ** (n - 1) + (n - 1) * q**n) / (1 - q) ** 2
    assert float(metrics.iae(t, e)) == pytest.approx(iae, rel=1e-12)
    assert float(metrics.ise(t, e)) == pytest.approx(ise, rel=1e-12)
    assert float(metrics.itae(t, e)) == pytest.approx(itae, rel=1e-12)
    # the rectangle rule against the integrals over [0, 40 tau), a = dt/tau = 0.02: first-order errors
    # a/2 and a (1.003 % and 2.013 % measured), second-order a^2/12 where t e vanishes at both ends
    assert float(metrics.iae(t, e)) == pytest.approx(e0 * tau, rel=0.0101)
    assert float(metrics.ise(t, e)) == pytest.approx(e0**2 * tau / 2, rel=0.0202)
    assert float(metrics.itae(t, e)) == pytest.approx(e0 * tau**2, rel=4e-5)


def test_itae_accumulated_period_by_period_equals_the_full_record():
    """The Monte Carlo kernel's way: a scan sums itae_term(t_k, e_k), times dt at the end."""
    t, y = first_order_step(3e-3, 800)
    e = metrics.tracking_error(1.0, y)
    total, _ = jax.lax.scan(lambda acc, te: (acc + metrics.itae_term(*te), None), 0.0, (t, e))
    assert float(total * DT) == pytest.approx(float(metrics.itae(t, e)), rel=1e-12)


def test_tracking_error_is_reference_minus_output():
    np.testing.assert_array_equal(
        np.asarray(metrics.tracking_error(np.array([5.0, -5.0]), np.array([4.0, -4.0]))), [1.0, -1.0]
    )


# --- step figures of a step response -----------------------------------------------------------------------


@pytest.mark.parametrize("y_start, y_final", [(0.0, 1.0), (5.0, 2.0)])
def test_rise_time_of_a_first_order_step_is_tau_ln9(y_start, y_final):
    tau = 4e-3
    t, y = first_order_step(tau, 500, y_start, y_final)
    # linear interpolation between samples, dt/tau = 0.025: measured 1.1e-5 short
    assert float(metrics.rise_time(t, y, y_start, y_final)) == pytest.approx(tau * math.log(9.0), rel=2e-5)
    assert math.isnan(float(metrics.rise_time(t, np.full(500, y_start), y_start, y_final)))  # never rises


def test_overshoot_of_a_second_order_step():
    zeta = 0.3
    t, y = second_order_step(zeta, 200.0, n_peak=400, n=2000)
    expected = 100.0 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))  # peak sampled exactly
    assert float(metrics.overshoot(y, 0.0, 1.0)) == pytest.approx(expected, rel=1e-12)
    assert float(metrics.overshoot(-y, 0.0, -1.0)) == pytest.approx(expected, rel=1e-12)  # either sign
    _, y1 = first_order_step(1e-3, 1000)
    assert float(metrics.overshoot(y1, 0.0, 1.0)) == 0.0


def test_settling_time_of_a_first_order_step_is_tau_ln50_on_the_sample_grid():
    """Within 2 % from t = tau ln 50 on; the figure is the first sample there."""
    tau = 4e-3
    t, y = first_order_step(tau, 1000)
    exact = tau * math.log(50.0)
    settled = float(metrics.settling_time(t, y, 0.0, 1.0, 0.02))
    assert settled == pytest.approx(math.ceil(exact / DT) * DT, rel=1e-12)
    assert exact <= settled < exact + DT
    assert math.isnan(float(metrics.settling_time(t[:100], y[:100], 0.0, 1.0)))  # 10 ms < tau ln 50: never
    assert float(metrics.settling_time(t, np.ones(1000), 0.0, 1.0)) == 0.0  # never outside


def test_first_sample_after_last():
    flags = np.array(
        [[False, False, False], [True, False, False], [False, True, False], [False, False, True]]
    )
    np.testing.assert_array_equal(np.asarray(metrics.first_sample_after_last(flags)), [0, 1, 2, 3])


# --- step figures against the reference --------------------------------------------------------------------


@pytest.mark.parametrize("w_ref", [150.0, -150.0])
def test_overshoot_against_the_reference_equals_the_step_overshoot_from_rest(w_ref):
    zeta = 0.3
    _, y = second_order_step(zeta, 200.0, n_peak=400, n=2000)
    w = w_ref * y
    excess = metrics.excess_over_reference(w, w_ref)
    overshoot = float(metrics.percent_of_reference(jnp.max(excess), w_ref))
    assert overshoot == pytest.approx(100.0 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2)), rel=1e-12)
    assert float(excess[0]) == -abs(w_ref)  # at rest: short of the reference by all of it
    # a zero reference: the floor keeps the percentage finite
    assert float(metrics.percent_of_reference(2e-7, 0.0)) == pytest.approx(20.0, rel=1e-12)


def test_outside_reference_band():
    y = np.array([98.0, 97.9, 102.0, 102.1, -98.0, -97.9])
    ref = np.array([100.0, 100.0, 100.0, 100.0, -100.0, -100.0])
    flags = metrics.outside_reference_band(y, ref, 0.02)
    np.testing.assert_array_equal(np.asarray(flags), [False, True, False, True, False, True])
    # a zero reference: the band is 0.02 of the 1e-6 floor
    zero = metrics.outside_reference_band(np.array([1e-8, 3e-8]), 0.0, 0.02)
    np.testing.assert_array_equal(np.asarray(zero), [False, True])


def test_settling_time_to_the_reference():
    """A first-order approach to -100 rad/s settles at the first sample with exp(-t/tau) <= 2 %; a window
    that ends before then is censored at the sample after it."""
    tau, n = 4e-3, 1000
    t, y = first_order_step(tau, n, 0.0, -100.0)
    settled = float(metrics.settling_time_to_reference(t, y, -100.0, 0.02, np.ones(n)))
    assert settled == pytest.approx(math.ceil(tau * math.log(50.0) / DT) * DT, rel=1e-12)
    window = (np.arange(n) < 100).astype(float)  # 10 ms, all outside the band
    assert float(metrics.settling_time_to_reference(t, y, -100.0, 0.02, window)) == pytest.approx(t[100])
    assert float(metrics.settling_time_to_reference(t, y, -100.0, 0.02, np.zeros(n))) == 0.0


# --- steady state and load response --------------------------------------------------------------------


def test_steady_state_error():
    ref = np.full(100, 50.0)
    y = ref - np.linspace(0.0, 1.98, 100)  # the error ramps: 0.02 k
    assert float(metrics.steady_state_error(y, ref, 10)) == pytest.approx(0.02 * np.mean(np.arange(90, 100)))


def test_disturbance_dip_of_a_known_response():
    """y = W - D x e^(1 - x), x = (t - t_event) / tau after the event: the dip is D at x = 1 (a sample);
    it recovers to within b once x e^(1 - x) <= b / D for good (the root beyond x = 1, found by brentq)."""
    w_nominal, depth, tau, t_event, band, n = 100.0, 20.0, 5e-3, 0.01, 0.5, 1000
    t = np.arange(n) * DT
    x = np.maximum(t - t_event, 0.0) / tau
    y = w_nominal - depth * x * np.exp(1.0 - x)
    dip, recovery = metrics.disturbance_dip(t, y, t_event, w_nominal, band)
    assert float(dip) == pytest.approx(depth, rel=1e-12)
    x_out = brentq(lambda x: x * math.exp(1.0 - x) - band / depth, 1.0, 50.0, xtol=1e-14)
    first_inside = math.ceil((t_event + tau * x_out) / DT) * DT  # the first sample at or after the root
    assert float(recovery) == pytest.approx(first_inside - t_event, rel=1e-12)
    assert tau * x_out <= float(recovery) < tau * x_out + DT
    _, never = metrics.disturbance_dip(t[:300], y[:300], t_event, w_nominal, band)  # cut at x = 4
    assert math.isnan(float(never))


# --- currents, voltages, ripple -----------------------------------------------------------------------------


def balanced_currents(amplitude, n_per_period=200, periods=3):
    theta = 2 * np.pi * np.arange(n_per_period * periods) / n_per_period
    return amplitude * np.cos(theta[:, None] - np.array([0.0, 2 * np.pi / 3, 4 * np.pi / 3]))


def test_peak_and_rms_of_balanced_sinusoidal_currents():
    """Peak I (sampled at theta = 0) and RMS I / sqrt(2) (uniform samples over whole periods)."""
    i_abc = balanced_currents(12.0)
    assert float(metrics.peak_phase_current(i_abc)) == pytest.approx(12.0, rel=1e-15)
    assert float(metrics.rms_phase_current(i_abc)) == pytest.approx(12.0 / math.sqrt(2.0), rel=1e-12)
    # over a window: samples outside it (a 100 A spike) do not count
    spiked = np.concatenate([i_abc, np.full((50, 3), 100.0)])
    active = np.concatenate([np.ones(len(i_abc)), np.zeros(50)])
    assert float(metrics.peak_phase_current(spiked * active[:, None])) == pytest.approx(12.0, rel=1e-15)
    assert float(metrics.rms_phase_current(spiked, active)) == pytest.approx(12.0 / math.sqrt(2.0), rel=1e-12)
    # one period's currents, as the Monte Carlo kernel takes them
    assert float(metrics.peak_phase_current(np.array([[1.0, -7.0, 6.0]]))) == 7.0


def test_voltage_use_saturation_and_control_effort():
    """Half the periods at 0.5 u_max, half at 2 u_max (on the limit): saturation 1/2 (the soft count
    misses by sigmoid(-0.499 / 0.005) and 1 - sigmoid(1.001 / 0.005), both < 1e-43), effort (0.25 + 4) / 2."""
    u_max = 300.0
    angle = np.linspace(0.0, 2 * np.pi, 40)
    unit = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    u_dq = np.concatenate([0.5 * u_max * unit, 2.0 * u_max * unit])
    everywhere = np.ones(80)
    np.testing.assert_allclose(
        np.asarray(metrics.voltage_use(u_dq, u_max)), [0.5] * 40 + [2.0] * 40, rtol=1e-12
    )
    assert float(metrics.voltage_saturation(u_dq, u_max, everywhere)) == pytest.approx(0.5, rel=1e-12)
    assert float(metrics.control_effort(u_dq, u_max, everywhere)) == pytest.approx(2.125, rel=1e-12)
    first_half = np.repeat([1.0, 0.0], 40)
    assert float(metrics.voltage_saturation(u_dq, u_max, first_half)) < 1e-40
    assert float(metrics.control_effort(u_dq, u_max, first_half)) == pytest.approx(0.25, rel=1e-12)
    # at the limit (0.999 u_max) the soft count is one half
    at_limit = 0.999 * u_max * unit
    assert float(metrics.voltage_saturation(at_limit, u_max, np.ones(40))) == pytest.approx(0.5, rel=1e-9)


def test_ripple_about_the_mean_of_a_sinusoid():
    """T0 + A sin over whole periods: the RMS deviation about the mean is A / sqrt(2); samples outside the
    window do not count, an empty window gives 0."""
    k = np.arange(400)
    torque = 10.0 + 0.3 * np.sin(2 * np.pi * k / 100)
    window = np.ones(400)
    ripple = 0.3 / math.sqrt(2)
    assert float(metrics.ripple_rms_about_mean(torque, window)) == pytest.approx(ripple, rel=1e-12)
    spiked = np.concatenate([np.full(100, 50.0), torque])
    tail = np.concatenate([np.zeros(100), window])
    assert float(metrics.ripple_rms_about_mean(spiked, tail)) == pytest.approx(ripple, rel=1e-12)
    assert float(metrics.ripple_rms_about_mean(spiked, np.zeros(500))) == 0.0


# --- one definition, two array types ------------------------------------------------------------------------


def _figures(t, w, ref, i_abc, duties):
    """Every figure of a recorded run a summary reads, from arrays of one type."""
    return {
        "rise": metrics.rise_time(t, w, 0.0, 100.0),
        "overshoot": metrics.overshoot(w, 0.0, 100.0),
        "settling": metrics.settling_time(t, w, 0.0, 100.0),
        "sse": metrics.steady_state_error(w, ref, 50),
        "itae": metrics.itae(t, metrics.tracking_error(ref, w)),
        "iae": metrics.iae(t, ref - w),
        "ise": metrics.ise(t, ref - w),
        "dip": metrics.disturbance_dip(t, w, 0.05, 100.0, 0.5),
        "peak": metrics.peak_phase_current(i_abc),
        "rms": metrics.rms_phase_current(i_abc),
        "switching": metrics.switching_frequency_hz(duties, 1e-4),
        "ripple": metrics.current_ripple_rms_a(w, 11),
        "band": metrics.outside_reference_band(w, ref, 0.02),
    }


def test_numpy_input_gives_numpy_figures_equal_to_the_jax_ones():
    """A recorded run is post-processed in NumPy (nothing compiled: the results are NumPy, not JAX
    arrays) and the same function traced with JAX arrays gives the same figures (float64, 1e-12)."""
    rng = np.random.default_rng(3)
    t, w = second_order_step(0.4, 300.0, 200, 1000)
    w = 100.0 * w + 0.2 * rng.standard_normal(t.shape)
    w[500:] -= 5.0 * np.exp(-(t[500:] - t[500]) / 0.005)  # a load dip at t[500]
    ref = np.full_like(t, 100.0)
    i_abc = rng.standard_normal((1000, 3))
    duties = rng.uniform(-0.2, 1.2, (1000, 3)).clip(0.0, 1.0)
    by_numpy = _figures(t, w, ref, i_abc, duties)
    by_jax = _figures(*(jnp.asarray(x) for x in (t, w, ref, i_abc, duties)))  # float64: tests/conftest.py
    for name, value in by_numpy.items():
        values = value if isinstance(value, tuple) else (value,)
        assert not any(isinstance(v, jax.Array) for v in values), f"{name}: NumPy input gave a JAX array"
        assert any(isinstance(v, jax.Array) for v in jax.tree.leaves(by_jax[name])), name
        np.testing.assert_allclose(
            np.asarray(value, dtype=float),
            np.asarray(by_jax[name], dtype=float),
            rtol=1e-12,
            atol=1e-12,
            err_msg=name,
        )
