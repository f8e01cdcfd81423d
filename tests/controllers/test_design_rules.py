"""Design rules of the FOC loops (the book, ch. 3) against their formulas and their closed-loop claims.

Current loop (internal-model design): ``Kp_d = a_c L_d``, ``Kp_q = a_c L_q``, ``Ki = a_c R`` should give the
closed loop ``a_c/(s + a_c)`` (10-90 % rise ``ln 9 / a_c``). Speed loop with active damping:
``Kp_w = beta J/K_t``, ``Ki_w = beta Kp_w``, ``B_a = (beta J - B)/K_t`` should give ``beta/(s + beta)``.

Three independent references are used:

1. the formulas themselves, evaluated in NumPy (and the book's printed numbers for beta = 50);
2. for the current loop, an exact discrete-time model of the sampled-data loop written here in NumPy:
   the dq plant at constant speed with the stator-frame voltage held over each period is linear, so the
   period map is the matrix exponential of an augmented system (currents, rotating held voltage, 1);
   the PI, decoupling, angle lead and computational delay are re-implemented from the book's
   equations (docs/book_reference.md, chapter 3). The simulator (RK4 sub-steps, SVPWM, averaged
   bridge) must reproduce it to 1e-9 A;
3. the continuous first-order responses ``1 - exp(-a t)`` the design rules promise, with tolerances derived
   from the sampling: see :func:`first_order_tolerance_current` and :func:`first_order_tolerance_speed`.

Finding: with the one-period computational delay and no compensation, the current-loop rise time is 17 %
(a_c = 1100 rad/s) and 34 % (a_c = 2000 rad/s) shorter than ln9/a_c, because the 1.5 Ts loop delay is not
in the design rule; the exact discrete model predicts the same numbers, so it is the rule, not the
simulator. The FOC's delay compensation (predicting the current one period ahead, the default) restores
the designed rise time; :func:`test_uncompensated_delay_breaks_the_rule` keeps the finding asserted. The
speed loop at beta = 100 rad/s with a 1 ms speed period misses its rule too (strict xfail).
"""

import functools
import math

import numpy as np
import pytest
import scipy.linalg

import pmsmjax
from pmsmjax import Profile, Scenario, presets
from pmsmjax.analysis import metrics
from pmsmjax.controllers import FOC, current_loop_imc, first_order_rise_time, speed_loop_active_damping
from pmsmjax.machines import PMSMParameters

TS = 1e-4  # s, book control period
LN9 = math.log(9.0)
U_MAX = 311.0 / math.sqrt(3.0)  # V, SVPWM linear limit of the book DC link
RPM = 2.0 * math.pi / 60.0

MOTORS = {
    "book": presets.book_motor(),
    "salient": presets.book_motor(salient=True),
    "other": PMSMParameters(R=0.37, L_d=1.9e-3, L_q=2.6e-3, psi_f=0.071, J=4.2e-4, B=1.1e-4, pole_pairs=3),
}


def floats(motor):
    return {k: float(getattr(motor, k)) for k in ("R", "L_d", "L_q", "psi_f", "J", "B")}


# --- 1. the formulas -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(MOTORS))
@pytest.mark.parametrize("a_c", [500.0, 1100.0, 2000.0])
def test_current_gains_equal_formulas(name, a_c):
    m = floats(MOTORS[name])
    g = current_loop_imc(MOTORS[name], a_c)
    np.testing.assert_allclose(float(g.kp_d), a_c * m["L_d"], rtol=1e-15)
    np.testing.assert_allclose(float(g.kp_q), a_c * m["L_q"], rtol=1e-15)
    np.testing.assert_allclose(float(g.ki_d), a_c * m["R"], rtol=1e-15)
    np.testing.assert_allclose(float(g.ki_q), a_c * m["R"], rtol=1e-15)
    # The PI zero ki/kp sits on the winding pole R/L of each axis (the cancellation the design relies on).
    np.testing.assert_allclose(float(g.ki_q / g.kp_q), m["R"] / m["L_q"], rtol=1e-14)


@pytest.mark.parametrize("name", sorted(MOTORS))
@pytest.mark.parametrize("beta", [20.0, 50.0, 100.0])
def test_speed_gains_equal_formulas(name, beta):
    motor = MOTORS[name]
    m = floats(motor)
    k_t = 1.5 * motor.pole_pairs * m["psi_f"]
    g = speed_loop_active_damping(motor, beta)
    np.testing.assert_allclose(float(g.kp), beta * m["J"] / k_t, rtol=1e-15)
    np.testing.assert_allclose(float(g.ki), beta * beta * m["J"] / k_t, rtol=1e-15)
    np.testing.assert_allclose(float(g.active_damping), (beta * m["J"] - m["B"]) / k_t, rtol=1e-14)


def test_book_speed_gains_beta_50():
    """The book's printed values for beta = 50 rad/s: Kp 0.137, Ki 6.84, B_a 0.13 (to the printed digits)."""
    g = speed_loop_active_damping(presets.book_motor(), 50.0)
    assert round(float(g.kp), 3) == 0.137  # 0.13684
    assert round(float(g.ki), 2) == 6.84  # 6.8418
    assert round(float(g.active_damping), 2) == 0.13  # 0.12954
    assert presets.book_motor().torque_constant == pytest.approx(1.0962, abs=5e-5)


def test_book_drive_uses_the_design_rules():
    drive = presets.book_drive(current_bandwidth=800.0, speed_bandwidth=30.0)
    motor = presets.book_motor()
    assert float(drive.controller.current.kp_q) == pytest.approx(800.0 * 5.25e-3, rel=1e-15)
    assert float(drive.controller.speed.kp) == pytest.approx(float(speed_loop_active_damping(motor, 30.0).kp))
    assert first_order_rise_time(1100.0) == pytest.approx(LN9 / 1100.0, rel=1e-15)


# --- 2. current loop: exact discrete reference and the first-order claim --------------------------------


def exact_current_loop(
    motor, gains, omega_m, i_ref, *, delay, decoupling, compensation=True, Ts=TS, u_max=U_MAX
):
    """The sampled-data current loop at constant mechanical speed ``omega_m`` (rad/s), exactly, in NumPy.

    Per period k: sample ``i_dq`` at ``t_k``; PI with back-calculation and the decoupling feed-forward;
    circular voltage limit; inverse Park at ``theta_k + omega_e * lead`` (lead 0.5 Ts, 1.5 Ts with delay);
    the stator-frame voltage is held over the period (the previous period's with delay; zero at start).
    With delay and ``compensation`` the PI and decoupling act on the current predicted one period ahead by
    a forward-Euler step of the dq model under the previous dq command.
    The dq plant with a held stator voltage is linear: augmented state ``[i_d, i_q, v_d, v_q, 1]`` with
    ``dv_d/dt = w_e v_q``, ``dv_q/dt = -w_e v_d`` (a fixed stator vector seen from the rotor), so one
    period is one matrix exponential. Returns ``(N, 2)`` dq currents at the period starts, A.
    """
    p = motor.pole_pairs
    m = floats(motor)
    R, L_d, L_q, psi = m["R"], m["L_d"], m["L_q"], m["psi_f"]
    w = p * omega_m
    M = np.zeros((5, 5))
    M[0, :3] = [-R / L_d, w * L_q / L_d, 1.0 / L_d]
    M[1, [0, 1, 3, 4]] = [-w * L_d / L_q, -R / L_q, 1.0 / L_q, -w * psi / L_q]
    M[2, 3], M[3, 2] = w, -w
    Phi = scipy.linalg.expm(M * Ts)
    kp = np.array([float(gains.kp_d), float(gains.kp_q)])
    ki = np.array([float(gains.ki_d), float(gains.ki_q)])
    lead = (1.5 if delay else 0.5) * Ts
    i, x, pending, u_prev = np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2)
    out = np.empty((len(i_ref), 2))
    for k in range(len(i_ref)):
        th = w * k * Ts
        out[k] = i
        i_c = i
        if delay and compensation:
            di_d = (u_prev[0] - R * i[0] + w * L_q * i[1]) / L_d
            di_q = (u_prev[1] - R * i[1] - w * (L_d * i[0] + psi)) / L_q
            i_c = i + Ts * np.array([di_d, di_q])
        e = i_ref[k] - i_c
        ff = np.array([-w * L_q * i_c[1], w * (L_d * i_c[0] + psi)]) if decoupling else np.zeros(2)
        v = kp * e + x + ff
        norm = math.hypot(*v)
        u = v * min(1.0, u_max / norm) if norm > 0 else v
        x = x + Ts * ki * e + (u - v)
        u_prev = u
        a = th + w * lead
        u_ab = np.array([u[0] * math.cos(a) - u[1] * math.sin(a), u[0] * math.sin(a) + u[1] * math.cos(a)])
        applied, pending = (pending, u_ab) if delay else (u_ab, u_ab)
        c, s = math.cos(th), math.sin(th)
        v_dq = np.array([c * applied[0] + s * applied[1], -s * applied[0] + c * applied[1]])
        i = (Phi @ np.concatenate([i, v_dq, [1.0]]))[:2]
    return out


STEP_T = 0.005  # s, time of the i_q reference step
STEP_A = 5.0  # A
N_CURRENT = 200  # periods (20 ms)


def current_drive(a_c, delay, decoupling=True, compensation=True):
    drive = presets.book_drive(
        mode="current", mechanics="imposed", current_bandwidth=a_c, computation_delay=delay
    )
    if decoupling and compensation:
        return drive
    c = drive.controller
    controller = FOC(
        c.model,
        c.speed,
        c.current,
        c.current_limit,
        mode="current",
        decoupling=decoupling,
        delay_compensation=compensation,
    )
    return type(drive)(
        drive.machine, controller, drive.modulator, drive.bridge, drive.Ts, drive.n_substeps, delay
    )


@functools.cache
def current_step(a_c, speed_rpm, delay, decoupling=True, compensation=True):
    """Simulated q step at imposed speed, with its exact reference.

    Returns ``(tau, di, i, i_exact)``: time since the step (s), the step response (the run with the step
    minus the run without it: the loop is linear at constant speed, so this removes the start-up
    transient of the delayed back-EMF compensation), the raw run and the exact model's run.
    """
    drive = current_drive(a_c, delay, decoupling, compensation)
    w = speed_rpm * RPM
    duration = N_CURRENT * TS
    with_step = Scenario(duration, speed_ref=Profile.constant(w), iq_ref=Profile.step(STEP_T, 0.0, STEP_A))
    without = Scenario(duration, speed_ref=Profile.constant(w))
    tr, tr0 = pmsmjax.simulate(drive, with_step), pmsmjax.simulate(drive, without)
    t = np.asarray(tr.t)
    i = np.asarray(tr.i_dq)
    i_ref = np.stack([np.zeros_like(t), np.where(t >= STEP_T - 1e-12, STEP_A, 0.0)], axis=1)
    exact = exact_current_loop(
        drive.machine.motor,
        drive.controller.current,
        w,
        i_ref,
        delay=delay,
        decoupling=decoupling,
        compensation=compensation,
    )
    after = t >= STEP_T - 1e-12
    di = (i - np.asarray(tr0.i_dq))[after]
    return t[after] - STEP_T, di, i, exact


def first_order_tolerance_current(a_c, delay):
    """Largest deviation (per unit of the step) allowed from ``1 - exp(-a_c t)`` at the sampling instants.

    Without computational delay the sampled loop is first order with pole ``1 - g``, ``g = a_c Ts``
    (PI zero on the plant pole, forward-Euler integral, ZOH plant); ``(1 - g)^k`` differs from
    ``exp(-g k)`` by at most ``g (1 + g) / (2 e)`` (max over k of ``k g^2/2 exp(-g k)``). With the delay
    the voltage acts 1.5 Ts after sampling; a shift of the response by ``T_d`` changes a curve of maximum
    slope ``a_c`` by at most ``a_c T_d``. Plus 1e-3 for the imperfect pole-zero cancellation.
    """
    g = a_c * TS
    return (a_c * 1.5 * TS if delay else g * (1 + g) / (2 * math.e)) + 1e-3


CURRENT_CASES = [(a_c, delay) for a_c in (500.0, 1100.0, 2000.0) for delay in (False, True)]


@pytest.mark.parametrize("speed_rpm", [0.0, 1000.0])
@pytest.mark.parametrize("delay, compensation", [(False, True), (True, True), (True, False)])
@pytest.mark.parametrize("a_c", [500.0, 1100.0, 2000.0])
def test_current_loop_matches_exact_discrete_model(a_c, delay, compensation, speed_rpm):
    """The whole simulated loop equals the exact sampled-data model (RK4 error only)."""
    _, _, i, exact = current_step(a_c, speed_rpm, delay, True, compensation)
    assert np.max(np.abs(i - exact)) < 1e-9  # A; measured 2e-13 at rest, 5e-11 at 1000 r/min


@pytest.mark.parametrize("speed_rpm", [0.0, 1000.0])
@pytest.mark.parametrize("a_c, delay", CURRENT_CASES)
def test_current_loop_rise_time(a_c, delay, speed_rpm):
    """10-90 % rise of i_q within 10 % of ln9/a_c.

    Measured ratios 0.977, 0.949, 0.903 (a_c = 500, 1100, 2000) without delay, 0.978, 0.951, 0.906 with
    the delay and its compensation.
    """
    tau, di, _, _ = current_step(a_c, speed_rpm, delay)
    rise = float(metrics.rise_time(tau, di[:, 1], 0.0, STEP_A))
    assert rise == pytest.approx(LN9 / a_c, rel=0.10)


@pytest.mark.parametrize("speed_rpm", [0.0, 1000.0])
@pytest.mark.parametrize("delay", [False, True])
@pytest.mark.parametrize("a_c", [500.0, 1100.0, 2000.0])
def test_current_loop_first_order_response(a_c, delay, speed_rpm):
    """The whole i_q response against ``1 - exp(-a_c t)``, within the tolerance derived from the sampling."""
    tau, di, _, _ = current_step(a_c, speed_rpm, delay)
    deviation = np.max(np.abs(di[:, 1] / STEP_A - (1.0 - np.exp(-a_c * tau))))
    assert deviation <= first_order_tolerance_current(a_c, delay)
    # Integral action: the step is reached. The forward-Euler PI zero 1 - R Ts/L misses the ZOH plant pole
    # exp(-R Ts/L) by (R Ts/L)^2/2 = 1.7e-4, leaving a slow L/R tail of that order (measured 1.4e-4).
    assert di[-1, 1] == pytest.approx(STEP_A, rel=5e-4)


@pytest.mark.parametrize("a_c, expected_ratio", [(1100.0, 0.826), (2000.0, 0.658)])
def test_uncompensated_delay_breaks_the_rule(a_c, expected_ratio):
    """Without delay compensation the 1.5 Ts loop delay makes the rise much shorter than ln9/a_c.

    The ratios are those of the exact discrete model (a prediction of the model, not of the simulator).
    """
    tau, di, _, _ = current_step(a_c, 0.0, True, True, False)
    rise = float(metrics.rise_time(tau, di[:, 1], 0.0, STEP_A))
    assert rise * a_c / LN9 < 0.9
    assert rise * a_c / LN9 == pytest.approx(expected_ratio, abs=0.01)


@pytest.mark.parametrize("delay", [False, True])
@pytest.mark.parametrize("a_c", [500.0, 1100.0, 2000.0])
def test_decoupling_keeps_d_axis_quiet_and_its_absence_shows(a_c, delay):
    """q step at 1000 r/min: with decoupling i_d stays within the bound below; without it, it does not.

    With decoupling the remaining d-axis voltage error is ``w_e L_q`` times the change of i_q between
    sampling and application (``T_d`` = 0.5 Ts, 1.5 Ts with delay); it produces at most ``w_e T_d L_q/L_d``
    times the step on i_d. Without decoupling the whole ``w_e L_q i_q`` drives the d axis.
    """
    w_e = 4 * 1000.0 * RPM
    bound = w_e * (1.5 if delay else 0.5) * TS * STEP_A  # 0.31 A / 0.10 A
    _, di_on, _, _ = current_step(a_c, 1000.0, delay, True)
    _, di_off, i_off, exact_off = current_step(a_c, 1000.0, delay, False)
    assert np.max(np.abs(i_off - exact_off)) < 1e-9  # the uncoupled loop is modelled exactly too
    peak_on, peak_off = np.max(np.abs(di_on[:, 0])), np.max(np.abs(di_off[:, 0]))
    assert peak_on <= bound
    assert peak_on <= 0.04 * STEP_A  # measured 0.10-0.16 A with delay, 0.03-0.04 A without
    assert peak_off >= 0.15 * STEP_A  # measured 0.78-1.72 A
    assert peak_off >= 4.0 * peak_on
    # At rest there is nothing to decouple: i_d stays at round-off.
    _, di_rest, _, _ = current_step(a_c, 0.0, delay, True)
    assert np.max(np.abs(di_rest[:, 0])) < 1e-12


# --- 3. speed loop ---------------------------------------------------------------------------------------

SPEED_STEP = 20.0  # rad/s: Kp_w * 20 <= 5.5 A for beta <= 100, far from the 15 A limit
SPEED_DURATION = 0.5  # s: >= 10 / beta


@functools.cache
def speed_step(beta, delay, divider):
    drive = presets.book_drive(speed_bandwidth=beta, computation_delay=delay, speed_divider=divider)
    tr = pmsmjax.simulate(drive, Scenario(SPEED_DURATION, speed_ref=Profile.constant(SPEED_STEP)))
    return np.asarray(tr.t), np.asarray(tr.omega_m), np.asarray(tr.i_dq_ref)


def first_order_tolerance_speed(beta, delay, divider, a_c=presets.BOOK_CURRENT_BANDWIDTH):
    """Allowed deviation (per unit) from ``1 - exp(-beta t)``: ``beta * tau``.

    ``tau`` sums the lags the design neglects inside the speed loop: the current loop (``1/a_c``), its
    voltage delay (0.5 or 1.5 Ts) and the hold of ``i_q*`` over the speed period (half of it). A lag
    ``tau`` shifts a curve of maximum slope ``beta`` by at most ``beta tau``.
    """
    tau = 1.0 / a_c + (1.5 if delay else 0.5) * TS + 0.5 * divider * TS
    return beta * tau


BETA_XFAIL = pytest.mark.xfail(
    strict=True,
    reason="beta = 100 rad/s with a 1 ms speed period: the neglected lags (1/a_c + hold) make the rise "
    "0.86 ln9/beta; time-scale separation of the design is lost",
)
# (beta rad/s, computation delay, speed divider)
SPEED_CASES = [
    (20.0, True, 1),
    (50.0, True, 1),
    (100.0, True, 1),
    (20.0, False, 1),
    (50.0, False, 1),
    (100.0, False, 1),
    (100.0, True, 2),
    (20.0, True, 10),
    (50.0, True, 10),
    (100.0, True, 10),
]
SPEED_RISE_CASES = [pytest.param(*c, marks=BETA_XFAIL) if c == (100.0, True, 10) else c for c in SPEED_CASES]


@pytest.mark.parametrize("beta, delay, divider", SPEED_RISE_CASES)
def test_speed_loop_rise_time(beta, delay, divider):
    """Measured ratios rise * beta / ln9: 0.98, 0.96, 0.92 (beta 20, 50, 100); 0.97, 0.93 with divider 10."""
    t, w, _ = speed_step(beta, delay, divider)
    rise = float(metrics.rise_time(t, w, 0.0, SPEED_STEP))
    assert rise == pytest.approx(LN9 / beta, rel=0.10)


@pytest.mark.parametrize("beta, delay, divider", SPEED_CASES)
def test_speed_loop_first_order_response(beta, delay, divider):
    """Whole response against ``beta/(s + beta)`` within ``beta * tau``; no current limiting; final value."""
    t, w, i_ref = speed_step(beta, delay, divider)
    deviation = np.max(np.abs(w / SPEED_STEP - (1.0 - np.exp(-beta * t))))
    assert deviation <= first_order_tolerance_speed(beta, delay, divider)
    assert np.max(np.abs(i_ref[:, 1])) < 0.5 * presets.BOOK_CURRENT_LIMIT  # the linear design applies
    # Integral action and active damping (B is compensated by the design): no steady-state error; what is
    # left at t_end is the decaying transient, of the order of the first-order curve's exp(-beta t_end).
    assert abs(w[-1] / SPEED_STEP - 1.0) <= 2.0 * math.exp(-beta * t[-1]) + 1e-5


def test_speed_divider_holds_the_current_reference():
    """With divider 10 the speed loop output changes only every 10th period (the loop really is slower)."""
    _, _, i_ref = speed_step(50.0, True, 10)
    changes = np.flatnonzero(np.diff(i_ref[:, 1]) != 0.0) + 1
    assert changes.size > 10
    assert np.all(changes % 10 == 0)
    _, _, i_ref1 = speed_step(50.0, True, 1)
    assert np.count_nonzero(np.diff(i_ref1[:200, 1])) > 150
