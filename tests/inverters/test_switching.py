"""The switching-segment bridge (pmsmjax.inverters.switching) against independent references.

- Volt-second balance: the period average equals ``U_dc (d - mean d)`` (the averaged bridge's formula).
- The brute-force carrier comparison of ``benchmarks/pwm_reference.py`` (fine fixed step, gates from a
  triangular carrier, dead time as a gate delay with the instantaneous current sign) on the book drive at
  steady state, closed loop: the phase-current waveforms agree within 1 % of the ripple peak-to-peak, and
  the difference shrinks as the reference's step does (the segment model is the limit it converges to).
- Averaged vs switching on period-average currents within the bound derived in
  :func:`ripple_bound` (open loop, imposed speed, where the derivation is exact).
- Dead time: the average voltage error ``sign(i) U_dc t_d / Ts`` per leg (analytic), and the carrier
  reference's average; device drop likewise.
- Gradients with respect to the duties against central differences; input checks.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks.pwm_reference import CarrierReferenceBridge, dense_phase_currents
from pmsmjax import ParameterError, Profile, Scenario, simulate
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import abc_to_alpha_beta, dq_to_abc
from pmsmjax.inverters import AveragedBridge, SwitchingBridge, phase_voltages
from pmsmjax.jobs.pwm_comparison import CompareSettings, steady_state
from pmsmjax.machines.base import MachineInput, MachineState
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.pmsm3 import PMSMdq
from pmsmjax.presets.three_phase import book_drive, book_motor

TS = 1e-4
U_DC = 311.0
S3 = np.sqrt(3.0)
SAMPLES = 20  # current samples per PWM period for the waveform comparison
PERIODS = 150  # one fundamental period at 1000 r/min


def np_clarke(u):
    return np.stack([(2 * u[..., 0] - u[..., 1] - u[..., 2]) / 3.0, (u[..., 1] - u[..., 2]) / S3], axis=-1)


def with_bridge(drive, bridge) -> Drive:
    return eqx.tree_at(lambda d: d.bridge, drive, bridge)


@pytest.fixture(scope="module")
def start():
    """The book drive at steady state: 1000 r/min, 10 N m (averaged bridge, SVPWM)."""
    drive = book_drive()
    return drive, steady_state(drive, CompareSettings())


def steady_scenario(periods):
    return Scenario(
        duration_s=periods * TS,
        speed_ref=Profile.constant(1000.0 * np.pi / 30.0),
        load_torque=Profile.constant(10.0),
    )


@pytest.fixture(scope="module")
def waveforms(start):
    """Dense phase currents of closed-loop runs, and of each period re-run from the reference's states."""
    drive, state = start
    out = {}
    for dead in (None, 2e-6):
        bridges = {
            "segments": SwitchingBridge(U_DC, dead_time=dead),
            "carrier4000": CarrierReferenceBridge(U_DC, dead_time=dead or 0.0, n_fine=4000),
        }
        if dead is None:  # the convergence check needs a coarser reference too
            bridges["carrier2000"] = CarrierReferenceBridge(U_DC, n_fine=2000)
        traces = {}
        for name, bridge in bridges.items():
            d = with_bridge(drive, bridge)
            traces[name] = simulate(d, steady_scenario(PERIODS), initial_state=state)
            out[(dead, name)] = dense_phase_currents(d, traces[name], SAMPLES)
        # period by period from the same start states and duties (no accumulation through the loop)
        seg = with_bridge(drive, bridges["segments"])
        out[(dead, "segments_per_period")] = dense_phase_currents(seg, traces["carrier4000"], SAMPLES)
    return out


def ripple_pp(currents):
    return np.ptp(currents.reshape(PERIODS, SAMPLES, 3), axis=1).max()


@pytest.mark.slow
def test_segment_currents_match_fine_step_carrier_reference(waveforms):
    seg = waveforms[(None, "segments")]
    ref2, ref4 = waveforms[(None, "carrier2000")], waveforms[(None, "carrier4000")]
    pp = ripple_pp(ref4)
    err2, err4 = np.abs(seg - ref2).max(), np.abs(seg - ref4).max()
    print(
        f"\nripple p-p {pp:.3f} A; closed loop, |segments - carrier| max: h = Ts/2000: {err2 * 1e3:.2f} mA, "
        f"h = Ts/4000: {err4 * 1e3:.2f} mA ({100 * err4 / pp:.2f} % of the ripple)"
    )
    assert pp > 0.3  # the ripple is resolved (the averaged bridge has none)
    assert err4 < 0.01 * pp
    # the reference converges to the segment model as its step shrinks (first order in h)
    assert err4 < 0.75 * err2


def test_dead_time_currents_match_reference(waveforms):
    ref4 = waveforms[(2e-6, "carrier4000")]
    pp = ripple_pp(ref4)
    closed_loop = np.abs(waveforms[(2e-6, "segments")] - ref4).max()
    per_period = np.abs(waveforms[(2e-6, "segments_per_period")] - ref4).reshape(PERIODS, SAMPLES, 3)
    # Near a zero crossing the ripple makes the current change sign within a period, and which diode
    # conducts in a 2 us window depends on the current at that instant: the segment model takes it at the
    # segment start, the reference at every fine step. Periods whose currents stay clear of zero must
    # agree as without dead time; the others by less than one window's volt-seconds, U_dc t_d / L.
    clear = np.all(np.abs(ref4.reshape(PERIODS, SAMPLES, 3)).min(axis=1) > 0.05, axis=1)
    window = U_DC * 2e-6 / 5.25e-3
    err_clear = per_period[clear].max()
    print(
        f"\ndead time 2 us, per period from the reference's states: {err_clear * 1e3:.2f} mA in the "
        f"{clear.sum()} periods clear of zero, {per_period.max() * 1e3:.1f} mA in all (U_dc t_d / L = "
        f"{window * 1e3:.0f} mA); closed loop {closed_loop * 1e3:.1f} mA ({100 * closed_loop / pp:.1f} % of "
        f"the ripple)"
    )
    assert clear.sum() > 0.8 * PERIODS
    assert err_clear < 0.01 * pp
    assert per_period.max() < window


# --- averaged vs switching: the bound ---------------------------------------------------------------


def ripple_bound(duties, u_dc, R, L, Ts):
    """Bound on |i_switching - i_averaged| (A) at every period start, and on period-mean differences.

    Surface PMSM, stator frame, speed imposed (so both models see the same EMF e(t)):
    ``L di/dt = u(t) - R i - e(t)``. The difference ``delta = i_sw - i_avg`` obeys ``L d delta/dt =
    (u - u_avg) - R delta``. Over a period, with the ideal ripple ``r(t) = int_0^t (u - u_avg)/L``
    (``r(0) = r(Ts) = 0``) and ``a = R/L``, integration by parts gives
    ``delta_{k+1} = e^{-a Ts} delta_k - a int_0^Ts e^{-a (Ts - t)} r(t) dt``. Centre-aligned PWM is
    symmetric about ``Ts/2``, so ``r`` is odd about it and only the odd part ``sinh`` of the weight
    survives: ``|eps_k| <= 2 e^{-a Ts/2} (cosh(a Ts/2) - 1) max|r_k|``, about ``(a Ts)^2/4 max|r_k|``.
    Hence ``b_{k+1} = e^{-a Ts} b_k + eps_k`` bounds ``|delta_k|``. The period means: integrating the
    machine equation over the period, ``R (mean_sw - mean_avg) Ts = -L (delta_{k+1} - delta_k)``
    (same ``u`` and ``e`` integrals), so ``|mean difference| <= ((1 - e^{-a Ts}) b_k + eps_k) / (a Ts)``.

    ``max|r_k|`` is computed here from the duties (edges ``(1 -+ d) Ts/2``; r is piecewise linear, so
    its maximum is at an edge). Returns ``(b (N+1,), mean_bound (N,))``.
    """
    a = R / L
    n = duties.shape[0]
    r_max = np.empty(n)
    for k in range(n):
        d = duties[k]
        edges = np.sort(np.concatenate([[0.0, Ts], (1 - d) * Ts / 2, (1 + d) * Ts / 2]))
        mids = 0.5 * (edges[1:] + edges[:-1])
        high = ((1 - d)[None, :] * Ts / 2 <= mids[:, None]) & (mids[:, None] < (1 + d)[None, :] * Ts / 2)
        u = u_dc * (high - high.mean(axis=1, keepdims=True))
        u_ab = np_clarke(u)
        u_avg = np_clarke(u_dc * (d - d.mean()))
        r = np.concatenate([[[0.0, 0.0]], np.cumsum((u_ab - u_avg) * np.diff(edges)[:, None], axis=0) / L])
        r_max[k] = np.linalg.norm(r, axis=1).max()
    eps = 2.0 * np.exp(-a * Ts / 2) * (np.cosh(a * Ts / 2) - 1.0) * r_max
    b = np.zeros(n + 1)
    for k in range(n):
        b[k + 1] = np.exp(-a * Ts) * b[k] + eps[k]
    mean_bound = ((1 - np.exp(-a * Ts)) * b[:-1] + eps) / (a * Ts)
    return b, mean_bound, r_max


def test_averaged_and_switching_agree_within_the_derived_bound(start):
    drive, state = start
    # The duty sequence of one fundamental period at steady state, applied open loop to both bridges.
    trace = simulate(with_bridge(drive, SwitchingBridge(U_DC)), steady_scenario(PERIODS), initial_state=state)
    duties = np.asarray(trace.duties)
    machine = PMSMdq(book_motor(), mechanics="imposed")
    s0 = state.machine
    n_mean = 256  # samples per period for the period means (trapezoid error ~1e-5 A at the kinks)

    def run(bridge, n_substeps):
        @jax.jit
        def go(s0, duties):
            def body(s, d):
                s_next, _ = bridge.advance(machine, s, d, 10.0, TS, n_substeps)
                if isinstance(bridge, SwitchingBridge):
                    dense = bridge.sample_period(machine, s, d, 10.0, TS, n_mean)[0]
                else:
                    dense = _held_samples(machine, s, d, n_mean)
                i = jnp.concatenate([s.currents[None], dense.currents])
                i_ab = jax.vmap(lambda x, th: dq_to_ab(x, th))(
                    i, jnp.concatenate([s.theta_e[None], dense.theta_e])
                )
                mean = (0.5 * (i_ab[0] + i_ab[-1]) + i_ab[1:-1].sum(0)) / n_mean
                return s_next, (dq_to_ab(s.currents, s.theta_e), mean)

            return jax.lax.scan(body, s0, duties)[1]

        return [np.asarray(x) for x in go(s0, jnp.asarray(duties))]

    i_sw, mean_sw = run(SwitchingBridge(U_DC), 1)
    i_avg, mean_avg = run(AveragedBridge(U_DC), 10)
    m = book_motor()
    b, mean_bound, r_max = ripple_bound(duties, U_DC, float(m.R), float(m.L_d), TS)
    numerics = 1e-6  # RK4 error of either model over the run, A (1e-9 relative per period)
    delta = np.linalg.norm(i_sw - i_avg, axis=1)
    mean_diff = np.linalg.norm(mean_sw - mean_avg, axis=1)
    print(
        f"\nmax ripple {r_max.max():.3f} A; period-start |i_sw - i_avg| max {delta.max() * 1e6:.1f} uA "
        f"(bound {b[:-1].max() * 1e6:.1f} uA); period-mean difference max {mean_diff.max() * 1e6:.1f} uA "
        f"(bound {mean_bound.max() * 1e6:.1f} uA)"
    )
    assert np.all(delta <= b[:-1] + numerics)
    assert np.all(mean_diff <= mean_bound + numerics + 2e-5)
    # the bound is not vacuous: within a factor 20 of what happens
    assert delta.max() > b.max() / 20


def dq_to_ab(i_dq, theta):
    c, s = jnp.cos(theta), jnp.sin(theta)
    return jnp.stack([c * i_dq[0] - s * i_dq[1], s * i_dq[0] + c * i_dq[1]])


def _held_samples(machine, s, d, n):
    """States at ``j Ts/n`` under the averaged bridge's period-average voltage."""
    u_ab = abc_to_alpha_beta(phase_voltages(d, U_DC))
    step = lambda x, _: (advance(machine, x, MachineInput(u_ab, 10.0), TS / n, 1),) * 2
    return jax.lax.scan(step, s, None, length=n)[1]


# --- one period: volt-seconds, dead time, device drop ------------------------------------------------

MACHINE = PMSMdq(book_motor(), mechanics="imposed")


def period_average(bridge, duties, i_dq, theta):
    """Period-average phase voltages ``(3,)`` V that ``bridge`` applies from a state with these currents."""
    s = MACHINE.initial_state(i_dq, 104.72, theta)
    u = np.asarray(_advance_voltage(bridge, s, jnp.asarray(duties)))
    return np.array([u[0], -0.5 * u[0] + 0.5 * S3 * u[1], -0.5 * u[0] - 0.5 * S3 * u[1]]), s


@eqx.filter_jit
def _advance_voltage(bridge, s, duties):
    return bridge.advance(MACHINE, s, duties, 0.0, TS, 10)[1]


def random_duties(rng, n, low=0.05, high=0.95):
    return rng.uniform(low, high, (n, 3))


def test_period_average_is_the_duty_average():
    rng = np.random.default_rng(11)
    bridge = SwitchingBridge(U_DC)
    for d in random_duties(rng, 30, 0.0, 1.0):
        u, _ = period_average(bridge, d, (1.0, 5.0), 0.4)
        np.testing.assert_allclose(u, U_DC * (d - d.mean()), rtol=0, atol=1e-12 * U_DC)


def test_segments_are_the_seven_segment_sequence():
    d = jnp.asarray([0.8, 0.45, 0.2])
    times, high, dead, _ = SwitchingBridge(U_DC).segments(d, TS)
    durations = np.diff(np.asarray(times))
    np.testing.assert_allclose(durations, durations[::-1], atol=1e-18)  # symmetric about Ts/2
    np.testing.assert_array_equal(np.asarray(high).sum(axis=1), [0, 1, 2, 3, 2, 1, 0])  # 0-x-y-7-y-x-0
    np.testing.assert_allclose(durations @ np.asarray(high), np.asarray(d) * TS, rtol=1e-12)
    assert not np.any(np.asarray(dead))


@pytest.mark.parametrize("t_d", [0.5e-6, 2e-6, 4e-6])
def test_dead_time_average_voltage_error(t_d):
    # Currents of 9 A peak at angles where every phase carries more than 2 A, far above the 0.3 A ripple
    # peak, so no current changes sign within the period: the loss is exactly sign(i) U_dc t_d / Ts per
    # leg (common mode removed by the isolated neutral).
    rng = np.random.default_rng(12)
    bridge = SwitchingBridge(U_DC, dead_time=t_d)
    reference = CarrierReferenceBridge(U_DC, dead_time=t_d, n_fine=4000)
    worst_ref = 0.0
    for k, theta in enumerate(np.pi / 6 + np.pi / 3 * np.arange(5)):  # mid-way between zero crossings
        d = random_duties(rng, 1, 0.15, 0.85)[0]
        u, s = period_average(bridge, d, (0.0, 9.0), theta)
        i_abc = np.asarray(dq_to_abc(MACHINE.currents_dq(s), s.theta_e))
        assert np.all(np.abs(i_abc) > 2.0)
        sign = np.sign(i_abc)
        expected = U_DC * (d - d.mean()) - U_DC * t_d / TS * (sign - sign.mean())
        np.testing.assert_allclose(u, expected, rtol=0, atol=1e-9 * U_DC)
        if k < 2:  # the brute-force reference, with a real gate delay and the instantaneous current sign
            u_ref, _ = period_average(reference, d, (0.0, 9.0), theta)
            worst_ref = max(worst_ref, np.abs(u_ref - expected).max())
    print(
        f"\nt_d = {t_d * 1e6} us: error {U_DC * t_d / TS:.2f} V per leg; "
        f"the carrier reference's differs by {worst_ref:.3f} V"
    )
    assert worst_ref < 0.2  # edge quantisation of the reference: U_dc h / Ts per edge = 0.08 V


def test_device_drop_average():
    bridge = SwitchingBridge(U_DC, device_drop=1.5)
    d = np.array([0.7, 0.4, 0.3])
    u, s = period_average(bridge, d, (0.0, 9.0), np.pi / 6)
    sign = np.sign(np.asarray(dq_to_abc(MACHINE.currents_dq(s), s.theta_e)))
    np.testing.assert_allclose(u, U_DC * (d - d.mean()) - 1.5 * (sign - sign.mean()), atol=1e-9 * U_DC)


def test_idle_legs_have_no_dead_time():
    bridge = SwitchingBridge(U_DC, dead_time=2e-6)
    d = np.array([1.0, 0.0, 0.5])
    u, s = period_average(bridge, d, (0.0, 9.0), np.pi / 6)
    sign_c = np.sign(np.asarray(dq_to_abc(MACHINE.currents_dq(s), s.theta_e)))[2]
    loss = np.array([0.0, 0.0, U_DC * 2e-6 / TS * sign_c])
    np.testing.assert_allclose(u, U_DC * (d - d.mean()) - (loss - loss.mean()), atol=1e-9 * U_DC)


# --- gradients and input checks -----------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    "bridge",
    # (exact sign with dead time: test_gradient_with_respect_to_bridge_parameters_matches_differences)
    [SwitchingBridge(U_DC), SwitchingBridge(U_DC, 2e-6, 1.0, 0.5, "smooth")],
    ids=["ideal", "dead_time_smooth_sign"],
)
def test_gradient_with_respect_to_duties_matches_differences(bridge):
    s0 = MACHINE.initial_state((0.5, 6.0), 104.72, 0.3)

    def final_current(d):
        s = s0
        for _ in range(3):  # three periods, so the state's dependence on earlier duties counts too
            s, _ = bridge.advance(MACHINE, s, d, 0.0, TS, 1)
        return s.currents @ jnp.asarray([1.0, -0.7])

    d0 = jnp.asarray([0.62, 0.41, 0.27])
    g = np.asarray(jax.jit(jax.grad(final_current))(d0))
    final_current = jax.jit(final_current)
    h = 1e-6
    fd = np.array([(final_current(d0 + h * e) - final_current(d0 - h * e)) / (2 * h) for e in jnp.eye(3)])
    print(f"\ngradient {g}, central differences {fd}")
    assert np.all(np.abs(g) > 1e-3)
    np.testing.assert_allclose(g, fd, rtol=1e-6)


def test_gradient_with_respect_to_bridge_parameters_matches_differences():
    # u_dc, dead time and device drop are array leaves: tunable and differentiable (currents clear of zero)
    s0 = MACHINE.initial_state((0.0, 9.0), 104.72, np.pi / 6)
    d = jnp.asarray([0.62, 0.41, 0.27])

    def final_current(p):
        bridge = SwitchingBridge(p[0], dead_time=p[1], device_drop=p[2])
        s = s0
        for _ in range(2):
            s, _ = bridge.advance(MACHINE, s, d, 0.0, TS, 1)
        return s.currents @ jnp.asarray([1.0, -0.7])

    p0 = jnp.asarray([311.0, 2e-6, 1.2])
    g = np.asarray(jax.jit(jax.grad(final_current))(p0))
    f = jax.jit(final_current)
    steps = np.array([1e-3, 1e-9, 1e-4])
    fd = np.array([(f(p0 + h * e) - f(p0 - h * e)) / (2 * h) for h, e in zip(steps, jnp.eye(3), strict=True)])
    print(f"\ngradient {g}, central differences {fd}")
    assert np.all(np.abs(g) > 0)
    np.testing.assert_allclose(g, fd, rtol=1e-5)


def test_smooth_sign_gives_finite_current_gradient_at_zero_current():
    bridge = SwitchingBridge(U_DC, dead_time=2e-6, current_sign="smooth", sign_smoothing=0.2)

    def out(i_d):
        s = MACHINE.initial_state((0.0, 0.0), 104.72, 0.0)
        s = MachineState(jnp.stack([i_d, 0.0]), s.omega_m, s.theta_e)
        return bridge.advance(MACHINE, s, jnp.asarray([0.6, 0.4, 0.5]), 0.0, TS, 1)[1][0]

    g = float(jax.jit(jax.grad(out))(jnp.asarray(0.0)))
    assert np.isfinite(g) and g != 0.0


def test_vmap_over_dead_time():
    d = jnp.asarray([0.62, 0.41, 0.27])
    s0 = MACHINE.initial_state((0.0, 9.0), 104.72, 0.3)
    f = lambda t_d: SwitchingBridge(U_DC, dead_time=t_d).advance(MACHINE, s0, d, 0.0, TS, 1)[1]
    u = np.asarray(jax.jit(jax.vmap(f))(jnp.asarray([0.0, 1e-6, 2e-6])))
    np.testing.assert_allclose(u[2] - u[0], 2 * (u[1] - u[0]), atol=1e-9)  # the loss is linear in t_d


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"dead_time": -1e-6}, "dead_time"),
        ({"u_dc": 0.0}, "u_dc"),
        ({"device_drop": -0.1}, "device_drop"),
        ({"current_sign": "soft"}, "current_sign"),
        ({"segment_substeps": 0}, "segment_substeps"),
    ],
)
def test_bad_settings_are_rejected(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        SwitchingBridge(**kwargs)


def test_dead_time_must_fit_the_period():
    drive = book_drive()
    with pytest.raises(ParameterError, match="Ts/2"):
        Drive(drive.machine, drive.controller, drive.modulator, SwitchingBridge(U_DC, dead_time=60e-6), TS)
    with pytest.raises(ParameterError, match="Ts/2"):  # swapped in without __init__: simulate checks
        simulate(with_bridge(drive, SwitchingBridge(U_DC, dead_time=50e-6)), steady_scenario(10))


def test_duties_must_have_three_legs():
    s = MACHINE.initial_state()
    with pytest.raises(ParameterError, match=r"shape \(3,\)"):
        SwitchingBridge(U_DC).advance(MACHINE, s, jnp.ones(2) * 0.5, 0.0, TS, 1)
