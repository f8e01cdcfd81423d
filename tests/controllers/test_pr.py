"""Proportional-resonant current control (pmsmjax.controllers.pr) against independent references.

- Steady state: the fundamental alpha-beta current error of the PR drive at 1000 r/min and 10 N m equals
  the exact sampled-data prediction (the alpha-beta RL + back-EMF plant solved over one period with the
  voltage held, the 1.5 Ts command delay, and the continuous design ``G(j w_0)``), written here in NumPy
  from the equations; and it is below 1 % of the current amplitude on the book drive.
- Frequency response: the discrete coefficients evaluated at ``z = exp(j w Ts)`` equal ``G(j w)`` at
  ``w_0`` and the Tustin-warped ``G(j (2/T) tan(w Ts/2))`` everywhere; the controller driven step by
  step with a sinusoid produces that phasor.
- The book scenario with the PR current loop, compared with the dq PI drive.
- Anti-windup: recovery from voltage saturation with and without back-calculation.
- Gradients: ``jax.grad`` of the book ITAE against central differences (float64), finite over a
  vmapped batch of 1000 random gain draws.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import check_gradient

import pmsmjax
from pmsmjax import Profile, Scenario, presets
from pmsmjax.analysis import metrics
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.controllers import CurrentLoopContext, ProportionalResonant, pr_design
from pmsmjax.frames.three_phase import inverse_park
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s

MOTOR = presets.book_motor()
BASE = presets.pr_drive()
PI = presets.book_drive()
DEMO = presets.book_scenario()
TS = BASE.Ts
W_1000 = MOTOR.pole_pairs * rpm_to_rad_s(1000.0)  # electrical rad/s
IQ_10NM = 10.0 / float(MOTOR.torque_constant)  # A


# ----------------------------------------------------------------------------------------------------
# Independent references (NumPy, from the equations)


def design_response(w, w0, kp, kr, w_c, phi):
    """Continuous ``G(j w) = Kp + 2 Kr w_c (s cos(phi) - w0 sin(phi)) / (s^2 + 2 w_c s + w0^2)``."""
    s = 1j * w
    return kp + 2 * kr * w_c * (s * np.cos(phi) - w0 * np.sin(phi)) / (s * s + 2 * w_c * s + w0 * w0)


def design_slope(w, w0, kr, w_c, phi):
    """``d G(j w) / d w`` (V/A per rad/s), from the quotient rule."""
    s = 1j * w
    num = 2 * kr * w_c * (s * np.cos(phi) - w0 * np.sin(phi))
    den = s * s + 2 * w_c * s + w0 * w0
    return 1j * (2 * kr * w_c * np.cos(phi) * den - num * (2 * s + 2 * w_c)) / den**2


def discrete_response(w, coefficients, kp):
    """``Kp + Cd (zI - Ad)^-1 Bd + Dd`` at ``z = exp(j w Ts)``."""
    Ad, Bd, Cd, Dd = (np.asarray(a) for a in coefficients)
    z = np.exp(1j * w * TS)
    return kp + Cd @ np.linalg.solve(z * np.eye(2) - Ad, Bd) + Dd


def predicted_fundamental_error(w, i_dq_ref, kp, kr, feedforward, motor=MOTOR, lead=1.5 * TS):
    """Exact sampled-data steady-state error phasor (rotor frame, A) of the PR drive at speed ``w``.

    Rotor-frame phasors at the sampling instants (``x_k = X exp(j theta_k)``, ``z = exp(j w Ts)``). The
    surface machine in alpha-beta, ``L di/dt = u - R i - e``, ``e = j w psi_f exp(j theta)``, with the
    command ``u_{k-1}`` held over period k (one period of computational delay) integrates exactly to
    ``(z - a) I = (1 - a)/R U/z - j w psi_f (z - a)/(R + j w L)``, ``a = exp(-R Ts/L)``. The controller
    at ``w_0 = w`` is ``U = G(j w)(I* - I) + U_ff``, with ``G(j w_0) = Kp + Kr exp(j w lead)`` (the
    prewarped design; exactness checked below) and ``U_ff = j w psi_f exp(j w lead)``.
    """
    R, L, psi = float(motor.R), float(motor.L_d), float(motor.psi_f)
    z, a = np.exp(1j * w * TS), np.exp(-R * TS / L)
    C = kp + kr * np.exp(1j * w * lead)
    emf = 1j * w * psi
    u_ff = emf * np.exp(1j * w * lead) if feedforward else 0.0
    g = (1 - a) / R / z
    i_ss = (g * (C * i_dq_ref + u_ff) - emf * (z - a) / (R + 1j * w * L)) / ((z - a) + g * C)
    return i_dq_ref - i_ss


def fundamental_error(trace, t_start, n_periods):
    """Per-axis DFT amplitude (A) of ``i_ab* - i_ab`` at the electrical frequency, over whole periods.

    Returns ``(|E_alpha|, |E_beta|, mean |i_dq*|)``; the window starts at ``t_start`` (s) and spans
    ``n_periods`` electrical revolutions of the measured angle.
    """
    t = np.asarray(trace.t)
    theta = np.unwrap(np.asarray(trace.theta_e))
    k0 = int(np.searchsorted(t, t_start))
    per_sample = (theta[-1] - theta[k0]) / (len(t) - 1 - k0)  # rad per period, mean over the rest
    k1 = k0 + int(round(2 * np.pi * n_periods / per_sample))
    assert k1 <= len(t), "window runs past the trace"
    e = np.asarray(inverse_park(trace.i_dq_ref, trace.theta_e) - inverse_park(trace.i_dq, trace.theta_e))
    kernel = np.exp(-1j * theta[k0:k1]) * 2 / (k1 - k0)
    amplitude = np.mean(np.hypot(*np.asarray(trace.i_dq_ref)[k0:k1].T))
    return abs(e[k0:k1, 0] @ kernel), abs(e[k0:k1, 1] @ kernel), amplitude


# ----------------------------------------------------------------------------------------------------
# (a) steady-state fundamental error


@pytest.fixture(scope="module")
def book_traces():
    return pmsmjax.simulate(BASE, DEMO), pmsmjax.simulate(PI, DEMO)


@pytest.mark.parametrize("feedforward", [True, False])
def test_steady_state_error_equals_the_sampled_data_prediction(feedforward):
    """Dynamometer at 1000 r/min, i_q* = 10 N m / K_t: the fundamental error is the predicted one.

    Measured (default design, w_c = 2 rad/s): 0.4495 % with the back-EMF feed-forward, 1.799 % without
    (the finite resonant gain Kp + Kr = 533 V/A must then carry the 76 V back-EMF); agreement with the
    prediction 1e-7 relative after 0.09 s (the transient decays below 1e-11 by 0.15 s).
    """
    drive = presets.pr_drive(mode="current", mechanics="imposed", back_emf_feedforward=feedforward)
    scenario = Scenario(
        duration_s=0.15, speed_ref=Profile.constant(rpm_to_rad_s(1000.0)), iq_ref=Profile.constant(IQ_10NM)
    )
    tr = pmsmjax.simulate(drive, scenario)
    e_a, e_b, amplitude = fundamental_error(tr, 0.09, 4)
    c = drive.controller.current
    expected = abs(predicted_fundamental_error(W_1000, 1j * IQ_10NM, float(c.kp), float(c.kr), feedforward))
    assert amplitude == pytest.approx(IQ_10NM, rel=1e-12)
    assert e_a == pytest.approx(expected, rel=1e-5)
    assert e_b == pytest.approx(expected, rel=1e-5)
    if feedforward:
        assert e_a / amplitude < 0.01 and e_b / amplitude < 0.01


@pytest.mark.slow
def test_book_drive_fundamental_error_below_one_percent(book_traces):
    """Book drive with PR, 10 N m load, last five electrical periods (0.32-0.395 s): measured 0.44 %."""
    tr, _ = book_traces
    e_a, e_b, amplitude = fundamental_error(tr, 0.32, 5)
    assert amplitude > 9.0  # the loaded operating point (about 9.9 A)
    assert e_a / amplitude < 0.01 and e_b / amplitude < 0.01


# ----------------------------------------------------------------------------------------------------
# (b) frequency response of the discrete controller


@pytest.mark.parametrize("w0", [100.0, W_1000, 3 * W_1000])
def test_tustin_prewarp_response_equals_the_design(w0):
    """Exact at w_0; elsewhere exactly the Tustin-warped design; within the warping error at +-20 %.

    The bilinear map with step ``T = 2 tan(w_0 Ts/2)/w_0`` sends ``z = exp(j w Ts)`` to
    ``s = j w_a``, ``w_a = (2/T) tan(w Ts/2)``, so ``H(z) = G(j w_a)`` (checked to 1e-10) and
    ``|H - G(j w)| <= |dG/dw| |w_a - w|`` to first order in ``w_a - w`` (0.03 rad/s at 1000 r/min,
    +20 %; a relative deviation of 3e-4 there).
    """
    c = pr_design(MOTOR)
    kp, kr, w_c = float(c.kp), float(c.kr), float(c.w_c)
    phi = 1.5 * TS * w0
    co = c.coefficients(jnp.asarray(w0), TS, delayed=True)
    T = 2 * np.tan(w0 * TS / 2) / w0
    for f in (1.0, 0.8, 1.2):
        w = f * w0
        h = discrete_response(w, co, kp)
        g = design_response(w, w0, kp, kr, w_c, phi)
        w_a = 2 / T * np.tan(w * TS / 2)
        assert abs(h - design_response(w_a, w0, kp, kr, w_c, phi)) <= 1e-10 * abs(g)
        if f == 1.0:
            assert abs(h - g) <= 1e-10 * abs(g)
        else:
            bound = 1.05 * abs(design_slope(w, w0, kr, w_c, phi)) * abs(w_a - w)
            assert abs(h - g) <= bound + 1e-12 * abs(g)
            assert bound < 0.01 * abs(g)


@pytest.mark.parametrize("w0", [100.0, W_1000, 3 * W_1000])
def test_sogi_response_is_exact_at_w0_and_half_a_sample_late_around_it(w0):
    """SOGI form: exact at w_0; around it the resonant term carries the forward-Euler integrator's
    half-sample delay, ``|H - G| ~= (w Ts/2) |G_r(j w)|`` (measured 0.98-1.02 x that at 0.8-1.2 w_0).
    """
    c = pr_design(MOTOR, discretisation="sogi")
    kp, kr, w_c = float(c.kp), float(c.kr), float(c.w_c)
    phi = 1.5 * TS * w0
    co = c.coefficients(jnp.asarray(w0), TS, delayed=True)
    g0 = design_response(w0, w0, kp, kr, w_c, phi)
    assert abs(discrete_response(w0, co, kp) - g0) <= 1e-10 * abs(g0)
    for f in (0.8, 0.9, 1.1, 1.2):
        w = f * w0
        g = design_response(w, w0, kp, kr, w_c, phi)
        deviation = abs(discrete_response(w, co, kp) - g)
        assert deviation <= 1.05 * (w * TS / 2) * abs(g - kp)


@pytest.mark.parametrize("discretisation", ["tustin-prewarp", "sogi"])
def test_controller_driven_by_a_sinusoid_gives_the_predicted_phasor(discretisation):
    """Run ``ProportionalResonant.step`` period by period on a positive-sequence error ``exp(j w t)``.

    The output's steady phasor (the mean of ``u exp(-j w t)`` after the resonator's transient,
    ``exp(-w_c t)``, has decayed to 2e-9 after 1 s) equals the coefficients' response, and (Tustin) the
    design. w_c = 20 rad/s here so that 2 s suffice.
    """
    c = pr_design(MOTOR, w_c=20.0, discretisation=discretisation, back_emf_feedforward=False)
    kp, kr, w_c = float(c.kp), float(c.kr), float(c.w_c)
    w0 = W_1000
    ctx = CurrentLoopContext(MOTOR, TS, jnp.asarray(1e9), True, jnp.zeros(2), True, True)
    n = 20000
    t = np.arange(n) * TS

    @jax.jit
    def run(w):
        def body(state, tk):
            i_ab = -jnp.stack([jnp.cos(w * tk), jnp.sin(w * tk)])  # i_dq* = 0: error = exp(j w t)
            state, u_ab, _ = c.step(state, jnp.zeros(2), i_ab, 0.3, jnp.asarray(w0), ctx)
            return state, u_ab

        return jax.lax.scan(body, c.init(jnp.float64), jnp.asarray(t))[1]

    co = c.coefficients(jnp.asarray(w0), TS, delayed=True)
    for f in (1.0, 0.8, 1.2):
        w = f * w0
        u = np.asarray(run(w))
        tail = slice(n // 2, n)
        phasor = np.mean((u[tail, 0] + 1j * u[tail, 1]) * np.exp(-1j * w * t[tail]))
        h = discrete_response(w, co, kp)
        assert abs(phasor - h) <= 1e-8 * abs(h)
        if discretisation == "tustin-prewarp":
            g = design_response(w, w0, kp, kr, w_c, 1.5 * TS * w0)
            assert abs(phasor - g) <= 1e-3 * abs(g)  # warping error at +-20 % (see above): < 3e-4


# ----------------------------------------------------------------------------------------------------
# (c) the book scenario


@pytest.mark.slow
def test_book_scenario_with_pr_matches_the_pi_drive(book_traces):
    """1000 r/min step, 10 N m at 0.2 s. Measured: rise 42.4 ms (PI 41.9), dip 242.7 r/min (PI 243.5),
    recovery to 10 r/min in 117 ms (PI 117), peak current 13.0 A (PI 12.1) inside the 15 A limit."""
    tr, tr_pi = book_traces
    s = speed_step_summary(tr, load_time_s=0.2, current_limit_a=15.0)
    s_pi = speed_step_summary(tr_pi, load_time_s=0.2, current_limit_a=15.0)
    assert abs(s["steady_state_error_rpm"]) < 1.0  # reached 1000 r/min before the load
    assert abs(s["final_error_rpm"]) < 1.0  # and after recovering from it
    assert s["recovery_time_s"] is not None and s["recovery_time_s"] < 0.15
    assert s["current_limit_respected"]
    assert s["rise_time_s"] == pytest.approx(s_pi["rise_time_s"], rel=0.05)
    assert s["speed_dip_rpm"] == pytest.approx(s_pi["speed_dip_rpm"], rel=0.05)
    assert s["itae_rad_s"] == pytest.approx(s_pi["itae_rad_s"], rel=0.05)


# ----------------------------------------------------------------------------------------------------
# Anti-windup


@pytest.mark.slow
def test_back_calculation_recovers_from_voltage_saturation():
    """U_dc = 150 V (limit 86.6 V) at 1000 r/min: i_q* = 15 A is out of reach (the limiter holds
    i_q near 5.7 A); at 0.05 s i_q* drops to a reachable 5 A. With back-calculation the error is inside
    0.1 A after 10.8 ms (peak 1.9 A); without, the wound-up resonators overshoot by 4.4 A and have not
    settled 50 ms later.
    """
    scenario = Scenario(
        duration_s=0.1,
        speed_ref=Profile.constant(rpm_to_rad_s(1000.0)),
        iq_ref=Profile.piecewise([0.0, 0.005, 0.05], [0.0, 15.0, 5.0]),
    )
    results = {}
    for anti_windup in (True, False):
        drive = presets.pr_drive(mode="current", mechanics="imposed", u_dc=150.0)
        current = pr_design(MOTOR, anti_windup=anti_windup)
        tr = pmsmjax.simulate(eqx.tree_at(lambda d: d.controller.current, drive, current), scenario)
        u = np.hypot(*np.asarray(tr.u_dq_ref).T)
        assert np.all(u[100:500] > 0.999 * 150.0 / np.sqrt(3))  # saturated throughout
        i_dq = np.asarray(tr.i_dq)[500:]
        err = np.hypot(i_dq[:, 0], i_dq[:, 1] - 5.0)
        outside = np.nonzero(err > 0.1)[0]
        results[anti_windup] = (err.max(), (outside[-1] + 1) * TS if len(outside) else 0.0)
    assert results[True][1] < 0.02
    assert results[False][1] > 0.04
    assert results[True][0] < 0.5 * results[False][0]


# ----------------------------------------------------------------------------------------------------
# (d) gradients

NAMES = ("kp", "kr", "w_c")
P0 = {k: getattr(BASE.controller.current, k) for k in NAMES}
# The book scenario shortened to 0.04 s (load step at 0.02 s): one reverse-mode compile serves both the
# finite-difference check and the 1000-draw batch.
SHORT = presets.book_scenario(load_time_s=0.02, duration_s=0.04)
FD_REL_STEP = 1e-4


def book_itae(params, scenario):
    drive = eqx.tree_at(
        lambda d: [getattr(d.controller.current, k) for k in NAMES], BASE, [params[k] for k in NAMES]
    )
    tr = pmsmjax.simulate(drive, scenario)
    return metrics.itae(tr.t, tr.speed_ref - tr.omega_m)


@pytest.mark.slow
def test_gradients_match_finite_differences_and_stay_finite_over_1000_draws():
    """jax.grad (under vmap) of the ITAE w.r.t. kp, kr, w_c vs central differences, within 1e-4.

    Step ``h = 1e-4 |p|``: truncation ``h^2 f'''/6`` about 1e-8 relative, round-off about
    ``1e-14 f / (h |f'|)`` below 1e-7 for these sensitivities (``|p f'|/f`` 2e-3 to 6e-3); measured
    agreement 1e-9 to 1.1e-8. Draw 0 is the nominal design; draws 1-999 are log-uniform in kp 0.5-2x,
    kr 0.3-3x, w_c 0.5-20 rad/s (all stable, valid controllers).
    """
    rng = np.random.default_rng(0)
    n = 1000

    def draw(nominal, low, high):
        x = nominal * np.exp(rng.uniform(np.log(low), np.log(high), n))
        x[0] = nominal
        return jnp.asarray(x)

    draws = {
        "kp": draw(float(P0["kp"]), 0.5, 2.0),
        "kr": draw(float(P0["kr"]), 0.3, 3.0),
        "w_c": draw(1.0, 0.5, 20.0).at[0].set(float(P0["w_c"])),
    }
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(book_itae), in_axes=(0, None)))(draws, SHORT)
    values = np.asarray(values)
    assert np.all(np.isfinite(values)) and np.all(values > 0)
    for k in NAMES:
        assert np.all(np.isfinite(np.asarray(grads[k]))), k
    assert values.max() > 1.05 * values.min()  # the draws really differ
    assert values.max() < 1.5 * values[0]  # and none of them is unstable

    f = jax.jit(book_itae)
    nominal = {k: g[0] for k, g in grads.items()}  # draw 0, from the vmapped reverse pass
    r = check_gradient(
        lambda p: f(p, SHORT), P0, grad=nominal, rel_step=FD_REL_STEP, step_floor=0.0, rtol=1e-4
    )
    assert values[0] == pytest.approx(r.value, rel=1e-12)
    assert np.all(r.sensitivity > 1e-4), dict(zip(r.names, r.sensitivity, strict=True))  # real sensitivities


# ----------------------------------------------------------------------------------------------------
# Validation


def test_invalid_parameters_are_refused():
    with pytest.raises(ParameterError, match="w_c"):
        ProportionalResonant(kp=5.0, kr=500.0, w_c=0.0)
    with pytest.raises(ParameterError, match="kp"):
        ProportionalResonant(kp=-1.0, kr=500.0, w_c=2.0)
    with pytest.raises(ParameterError, match="discretisation"):
        ProportionalResonant(kp=5.0, kr=500.0, w_c=2.0, discretisation="euler")
    with pytest.raises(ParameterError, match="bandwidth"):
        pr_design(MOTOR, bandwidth_rad_s=-1.0)


def test_design_rule_matches_the_pi_equivalence():
    """Kp = a_c L and Kr w_c = a_c R (the PI's Ki); the designed resonant term at ``w_0 + delta`` is the
    synchronous-frame leaky integrator ``Ki/(w_c + j delta)`` plus its negative-sequence mirror
    ``Ki/(w_c + j(2 w_0 + delta))`` within 1 % (the residue differs from Ki by ``O(w_c/w_0)``: measured
    at most 0.9 %), whereas the positive-sequence term alone is 16-46 % off at delta = +-200 rad/s.
    """
    c = pr_design(MOTOR, 1100.0, 2.0)
    pi = presets.book_drive().controller.current
    assert float(c.kp) == pytest.approx(float(pi.kp_q), rel=1e-14)
    assert float(c.kr) * float(c.w_c) == pytest.approx(float(pi.ki_q), rel=1e-14)
    ki, w_c = float(pi.ki_q), float(c.w_c)
    for delta in (0.0, 5.0, 40.0, 200.0, -200.0):
        resonant = design_response(W_1000 + delta, W_1000, 0.0, float(c.kr), w_c, 0.0)
        equivalent = ki / (w_c + 1j * delta) + ki / (w_c + 1j * (2 * W_1000 + delta))
        assert abs(resonant - equivalent) <= 0.01 * abs(resonant), delta
