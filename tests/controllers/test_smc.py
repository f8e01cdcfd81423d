"""Sliding-mode speed control (the book, ch. 3): the block, its design rule, the book drive, gradients.

References, independent of the code under test: the linear identity of the exponential reaching law
(``i_q* = (1/D)[(c + q) x1 + q c int x1]`` when ``eps = 0``), the analytic sliding-surface decay
``x1 ~ exp(-c t)`` and its 10-90 % rise ``ln 9 / c``, the mechanical torque balance, hand-computed
design-rule numbers, and central finite differences for the gradients.
"""

import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import check_gradient

import pmsmjax
from pmsmjax import ParameterError, presets
from pmsmjax.analysis import metrics
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.controllers import SlidingModeSpeed, smc_design
from pmsmjax.estimators import Encoder

RPM = 2.0 * math.pi / 60.0
TS = presets.BOOK_TS
LIMIT = presets.BOOK_CURRENT_LIMIT
SWITCHINGS = ("sign", "saturation", "tanh")
#: Moving-mean window of the chattering metric: 10 ms, four periods of the sign law's 420 Hz limit cycle.
RIPPLE_WINDOW = 101


@functools.cache
def drive(switching="sign", time_constant_s=0.02, encoder=False):
    d = presets.smc_drive(switching=switching, time_constant_s=time_constant_s)
    if encoder:
        d = eqx.tree_at(lambda d: d.estimator, d, Encoder(lines=2500, pole_pairs=4))
    return d


@functools.cache
def book_run(switching="sign", encoder=False):
    return pmsmjax.simulate(drive(switching, encoder=encoder), presets.book_scenario())


@functools.cache
def step_run(switching, time_constant_s):
    """500 r/min step, no load, 0.4 s (the book scenario's shapes: the compiled drive is shared)."""
    scenario = presets.book_scenario(speed_rpm=500.0, load_nm=0.0)
    return pmsmjax.simulate(drive(switching, time_constant_s), scenario)


def np_tr(tr):
    return jax.tree.map(np.asarray, tr)


# --- the block and its design rule ------------------------------------------------------------------------


def test_design_rule_numbers():
    """smc_design on the book motor against the rules evaluated by hand.

    D = 1.5 * 4 * 0.1827 / 0.003 = 365.4 rad/(A s^2); c = 1/20 ms = 50 1/s; q = 5 c = 250 1/s;
    eps = 1.2 (1000 / 0.003 + (0.008/0.003) 365.4 * 15) = 4.1754e5 rad/s^3; boundary = eps / (550 - 250).
    """
    smc = smc_design(presets.book_motor())
    assert float(smc.torque_constant_over_inertia) == pytest.approx(365.4, rel=1e-12)
    assert float(smc.c) == pytest.approx(50.0, rel=1e-12)
    assert float(smc.q) == pytest.approx(250.0, rel=1e-12)
    eps = 1.2 * (1000.0 / 0.003 + 0.008 / 0.003 * 365.4 * 15.0)
    assert float(smc.eps) == pytest.approx(eps, rel=1e-12)
    assert float(smc.boundary) == pytest.approx(eps / 300.0, rel=1e-12)
    assert smc.switching == "sign"
    preset = drive().controller.speed
    assert float(preset.eps) == pytest.approx(eps, rel=1e-6) and float(preset.boundary) == pytest.approx(
        eps / 300.0, rel=1e-6
    )


def test_bad_parameters_are_refused():
    motor = presets.book_motor()
    with pytest.raises(ParameterError, match="below half the current-loop bandwidth"):
        smc_design(motor, 0.002)  # q = 2500 1/s > a_c/2
    with pytest.raises(ParameterError, match="q Ts"):
        smc_design(motor, 0.005, Ts=5e-3, current_bandwidth_rad_s=1e4)  # q = 1000 1/s, q Ts = 5
    with pytest.raises(ParameterError, match="time_constant_s"):
        smc_design(motor, -0.02)
    with pytest.raises(ParameterError, match="switching"):
        SlidingModeSpeed(50.0, 1e5, 250.0, 365.4, 1e3, "relay")
    with pytest.raises(ParameterError, match="boundary"):
        SlidingModeSpeed(50.0, 1e5, 250.0, 365.4, 0.0, "tanh")


def scan_block(smc, x1, iq_max):
    """Run the speed block alone over a speed-error sequence ``x1 (N,)`` (reference x1, speed 0)."""

    def body(state, x):
        return smc.step(state, x, 0.0, iq_max, TS)

    _, iq = jax.lax.scan(body, smc.init(jnp.float64), jnp.asarray(x1))
    return np.asarray(iq)


def test_linear_part_is_a_pi_with_poles_c_and_q():
    """With ``eps = 0`` and no limit, the integral form equals ``(1/D)[(c + q) x1 + q c Ts sum x1]``.

    The identity follows from ``x2 = dx1/dt`` (``int c x2 = c x1``, ``int q s = q x1 + q c int x1``); it
    holds exactly in discrete time because the backward difference telescopes. A random error sequence
    (with the implicit ``x1[-1] = 0`` start) is the input.
    """
    rng = np.random.default_rng(3)
    x1 = rng.normal(0.0, 20.0, 400)
    c, q, D = 50.0, 250.0, 365.4
    smc = SlidingModeSpeed(c, 0.0, q, D, 1.0, "sign")
    iq = scan_block(smc, x1, 1e9)
    expected = ((c + q) * x1 + q * c * TS * np.cumsum(x1)) / D
    np.testing.assert_allclose(iq, expected, rtol=1e-10, atol=1e-10 * np.max(np.abs(expected)))


def test_anti_windup_leaves_the_limit_at_once():
    """Clamped integral: on the limit while pushed outwards, off it in the first period pushed inwards.

    100 rad/s of error for 50 periods drives i_q* to the 15 A limit (the unclamped integral would reach
    15 + 49 Ts (q c 100 + eps)/D = 18.9 A); at period 50 the error drops to 80 rad/s: x2 = -2e5 rad/s^2,
    s < 0, and the increment ``Ts (c x2 - eps + q s) / D`` is computed by hand from there.
    """
    c, eps, q, D = 50.0, 4e5, 250.0, 365.4
    smc = SlidingModeSpeed(c, eps, q, D, 1.0, "sign")
    x1 = np.r_[np.full(50, 100.0), np.full(10, 80.0)]
    iq = scan_block(smc, x1, LIMIT)
    assert np.all(iq[:50] == LIMIT)
    x2 = (80.0 - 100.0) / TS
    s = c * 80.0 + x2
    expected = LIMIT + TS * (c * x2 - eps + q * s) / D  # 15 - 1.57 A
    assert iq[50] == pytest.approx(expected, rel=1e-12)
    assert iq[50] < LIMIT - 1.0


# --- (a) the book scenario --------------------------------------------------------------------------------


@pytest.mark.slow
def test_book_scenario_reaches_speed_and_recovers_from_the_load():
    """1000 r/min step, 10 N m at 0.2 s, 0.4 s, design-rule gains, sign switching (the book's law).

    Measured (float64): rise 44.0 ms, overshoot 0.03 %, steady-state error 0.10 r/min before the load,
    dip 64.4 r/min, back within 10 r/min after 40.6 ms, final 999.9 r/min, peak phase current 12.4 A.
    (The book PI with beta = 50 rad/s on the same scenario: rise 41.9 ms, dip 243 r/min, recovery 117 ms.)
    The rise time is the surface's: sliding starts within 1 ms (the first period's kick, clipped at 15 A)
    and on the surface ``x1 = x1(0) exp(-c t)`` rises 10-90 % in ``ln 9 / c`` = 43.9 ms; it stays below the
    limit because ``c x1 / D`` = 14.3 A < 15 A.
    """
    tr = book_run("sign")
    s = speed_step_summary(tr, load_time_s=0.2, current_limit_a=LIMIT)
    assert s["final_speed_rpm"] == pytest.approx(1000.0, rel=0.01)
    assert abs(s["steady_state_error_rpm"]) < 1.0
    assert s["rise_time_s"] == pytest.approx(math.log(9.0) / 50.0, rel=0.05)
    assert s["overshoot_pct"] < 1.0
    assert s["speed_dip_rpm"] > 10.0  # a real disturbance
    assert s["recovery_time_s"] is not None and s["recovery_time_s"] < 0.1
    assert s["current_limit_respected"]
    t = np.asarray(tr.t)
    # Loaded steady state: K_t i_q = T_L + B w on the average over the chattering (last 0.1 s).
    m = presets.book_motor()
    late = t >= 0.3
    iq = float(np.mean(np.asarray(tr.i_dq[late, 1])))
    w = float(np.mean(np.asarray(tr.omega_m[late])))
    assert float(m.torque_constant) * iq == pytest.approx(10.0 + float(m.B) * w, rel=2e-3)


# --- (b) the surface's time constant ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "switching,time_constant_s",
    [("sign", 0.02), ("saturation", 0.02), ("tanh", 0.02), ("saturation", 0.01), ("saturation", 0.05)],
)
def test_sliding_phase_decays_with_time_constant_one_over_c(switching, time_constant_s):
    """On the surface ``x1`` decays as ``exp(-c t)``: the fitted time constant is ``1/c`` within 10 %.

    Scenario: 500 r/min step, no load. The sliding phase needs ``D i_q* = c x1`` inside the limit:
    ``c x1 / D`` = 7.2 A at c = 50 1/s, 14.3 A at c = 100 1/s (52.4 rad/s), so the current limit is not
    hit while sliding (checked below); only the first period's kick is clipped. Fit window: from 10 ms
    (the reaching phase is over: the kick leaves the limit within 2 ms, ``s`` then converges at
    ``q + eps/boundary`` = 550 1/s and the current loop at 1100 rad/s, five time constants of either is
    under 10 ms) until ``x1`` falls to 2 % of the step; least squares on ``ln x1``.

    Measured fitted ``1/c`` against the design: sign 2.0 % long, saturation and tanh 1.3 % long at 20 ms,
    saturation 3.3 % at 10 ms and 0.7 % at 50 ms. The residue is the current loop's lag and friction
    (with ``eps/boundary`` linear, the slow root of ``p^2 + (c + k + B/J) p + c k``, k = 550 1/s, is
    49.7 1/s; the current loop takes it to 49.4 1/s).
    """
    tr = np_tr(step_run(switching, time_constant_s))
    x1 = tr.speed_ref - tr.omega_m
    window = (tr.t >= 0.01) & (x1 > 0.02 * x1[0])
    assert np.count_nonzero(window) > 300
    assert np.all(np.abs(tr.i_dq_ref[window, 1]) < 0.99 * LIMIT)
    slope, _ = np.polyfit(tr.t[window], np.log(x1[window]), 1)
    assert -1.0 / slope == pytest.approx(time_constant_s, rel=0.10)
    # The fit is a good one: the decay is exponential (log-linear) over the window.
    resid = np.log(x1[window]) - np.polyval(np.polyfit(tr.t[window], np.log(x1[window]), 1), tr.t[window])
    assert np.max(np.abs(resid)) < 0.1


# --- (c) chattering ----------------------------------------------------------------------------------------


def ripple(tr, t0=0.3):
    iq = np.asarray(tr.i_dq_ref[:, 1])[np.asarray(tr.t) >= t0]
    return (
        float(metrics.current_ripple_rms_a(iq, RIPPLE_WINDOW)),
        float(metrics.current_ripple_peak_to_peak_a(iq, RIPPLE_WINDOW)),
    )


def test_ripple_metric_on_known_signals():
    """A sampled triangle wave on an offset and a ramp: the metric returns the triangle's own RMS and
    peak-to-peak (computed directly over one period), since a centred moving mean over whole periods is
    the triangle's zero mean plus the ramp's value at the centre."""
    period, a = 21, 0.7
    window = 5 * period  # odd: exactly centred
    n = 100 * period + window - 1  # the compared stretch is 100 whole periods
    k = np.arange(n)
    tri = a * (4.0 * np.abs((k / period) % 1.0 - 0.5) - 1.0)
    tri = tri - np.mean(tri[:period])
    y = tri + 3.0 + 1e-3 * k
    assert float(metrics.current_ripple_rms_a(y, window)) == pytest.approx(
        np.sqrt(np.mean(tri[:period] ** 2)), rel=1e-9
    )
    assert float(metrics.current_ripple_peak_to_peak_a(y, window)) == pytest.approx(np.ptp(tri), rel=1e-9)
    assert float(metrics.current_ripple_rms_a(3.0 + 1e-3 * k, 101)) < 1e-12
    with pytest.raises(ParameterError, match="window"):
        metrics.current_ripple_rms_a(y, 0)


@pytest.mark.slow
def test_boundary_layer_removes_the_chattering():
    """i_q* ripple about its 10 ms moving mean, loaded steady state of the book scenario (0.3-0.4 s).

    Measured (float64, design-rule gains, A):

    ============  ==========  ==========  =====================  =====================
    switching     RMS exact   p-p exact   RMS 2500-line encoder  p-p 2500-line encoder
    ============  ==========  ==========  =====================  =====================
    sign          0.398       1.37        2.40                   7.75
    saturation    2.0e-5      5.8e-5      0.059                  0.295
    tanh          2.0e-5      6.0e-5      0.059                  0.300
    ============  ==========  ==========  =====================  =====================

    The sign law is a relay inside the loop: i_q* moves by ``eps Ts / D`` = 0.114 A every period (it can
    never stand still) and the 1.5-period delay plus the current loop's lag turn that into a 420 Hz
    triangle limit cycle of about +-0.7 A. With a boundary layer the switching term is linear near the
    surface and the loop is asymptotically stable: with an exact sensor nothing excites it in steady
    state, so what the metric sees is the curvature of the load transient's slow tail. Asserted: a factor
    100 (the measured ratio is 2e4), and the sign law's peak-to-peak at least one switching step. With the
    encoder (counted angle, type-2 tracking loop at 1000 rad/s) the backward-differenced speed estimate puts
    about 190 rad/s^2 of noise on ``s``, which the boundary layer passes linearly: the ripple is then not
    zero, and the sign law also wanders at low frequency (979-1020 r/min over 0.3-0.4 s, 983 r/min at
    the end). Asserted there: a factor 5 (measured 40 on RMS, 26 on peak-to-peak).
    """
    eps_step = (
        float(drive().controller.speed.eps)
        * TS
        / float(drive().controller.speed.torque_constant_over_inertia)
    )
    sign_rms, sign_pp = ripple(book_run("sign"))
    assert sign_pp > eps_step
    for switching in ("saturation", "tanh"):
        rms, pp = ripple(book_run(switching))
        assert rms < sign_rms / 100 and pp < sign_pp / 100, switching
    enc_sign_rms, enc_sign_pp = ripple(book_run("sign", encoder=True))
    for switching in ("saturation", "tanh"):
        rms, pp = ripple(book_run(switching, encoder=True))
        assert rms < enc_sign_rms / 5 and pp < enc_sign_pp / 5, switching


# --- (d), (e) gradients -----------------------------------------------------------------------------------

GRAD_NAMES = ("c", "eps", "q")
#: Shortened book scenario: 1000 r/min step, 10 N m at 25 ms, 50 ms (500 periods). The load step throws
#: s to 3.3e3 rad/s^2, beyond the 1.4e3 rad/s^2 boundary: the tanh is exercised in its nonlinear part.
SHORT = presets.book_scenario(load_time_s=0.025, duration_s=0.05)
GRAD_BASE = presets.smc_drive(switching="tanh")


def build(params):
    smc = GRAD_BASE.controller.speed
    names = [k for k in ("c", "eps", "q", "boundary") if k in params]
    new = eqx.tree_at(lambda m: [getattr(m, k) for k in names], smc, [params[k] for k in names])
    return eqx.tree_at(lambda d: d.controller.speed, GRAD_BASE, new)


def itae(params, scenario=SHORT):
    tr = pmsmjax.simulate(build(params), scenario)
    return metrics.itae(tr.t, tr.speed_ref - tr.omega_m)


itae_jit = jax.jit(itae)


@pytest.mark.slow
def test_grad_matches_central_differences():
    """jax.grad of the ITAE (metrics.itae of speed_ref - omega_m) w.r.t. c, eps, q vs central differences.

    tanh switching, shortened scenario, float64, ``h = 1e-5 |p|``. Truncation error ``h^2 f'''/6``: at
    ``h = 1e-3 |p|`` the differences are 2-3e-7 off and shrink as h^2 (3e-9 at 1e-4); round-off
    ``1e-14 |f| / (h |df/dp|)`` stays below 1e-9 for the sensitivities here (``|p df/dp| / f``: c 1.02,
    eps 0.038, q 0.063). Measured agreement at 1e-5: better than 1e-9 for all three.
    """
    p0 = {k: getattr(GRAD_BASE.controller.speed, k) for k in GRAD_NAMES}
    # The tanh's nonlinear range is visited (|s| > boundary after the load step).
    tr = np_tr(pmsmjax.simulate(GRAD_BASE, SHORT))
    x1 = tr.speed_ref - tr.omega_m
    s = 50.0 * x1 + np.diff(np.r_[0.0, x1]) / TS
    after = tr.t >= 0.025
    assert np.max(np.abs(s[after])) > 2.0 * float(GRAD_BASE.controller.speed.boundary)
    grad = jax.jit(jax.grad(itae))(p0)
    r = check_gradient(itae_jit, p0, grad=grad, rel_step=1e-5, step_floor=0.0, rtol=1e-4)
    assert np.all(r.sensitivity > 1e-2), dict(zip(r.names, r.sensitivity, strict=True))  # real sensitivities


def random_draws(n, seed=0):
    """``n`` valid designs: c log-uniform in [25, 100] 1/s, q = (2..5) c (so q < a_c/2 = 550 1/s), eps
    log-uniform in [1e5, 1e6] rad/s^3, and the design rule's boundary ``eps / (a_c/2 - q)``."""
    rng = np.random.default_rng(seed)
    c = np.exp(rng.uniform(np.log(25.0), np.log(100.0), n))
    q = c * rng.uniform(2.0, 5.0, n)
    eps = np.exp(rng.uniform(np.log(1e5), np.log(1e6), n))
    boundary = eps / (0.5 * presets.BOOK_CURRENT_BANDWIDTH - q)
    return {k: jnp.asarray(v) for k, v in dict(c=c, eps=eps, q=q, boundary=boundary).items()}


@pytest.mark.slow
def test_gradients_finite_for_1000_random_draws():
    """1000 random valid designs in one vmapped reverse pass on the shortened scenario (26 s on 2 cores).

    Every value and gradient (w.r.t. c, eps, q and boundary) is finite; two draws are checked against
    single unbatched runs.
    """
    n = 1000
    draws = random_draws(n)
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(itae)))(draws)
    values = np.asarray(values)
    assert values.shape == (n,) and np.all(np.isfinite(values)) and np.all(values > 0)
    for k, g in grads.items():
        assert np.all(np.isfinite(np.asarray(g))), k
    assert values.max() > 1.5 * values.min()  # the draws differ
    single = jax.jit(jax.value_and_grad(itae))
    for i in (0, 731):
        v, g = single({k: x[i] for k, x in draws.items()})
        assert float(v) == pytest.approx(values[i], rel=1e-10)
        for k in draws:
            assert float(g[k]) == pytest.approx(float(grads[k][i]), rel=1e-8), (i, k)
