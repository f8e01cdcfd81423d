"""Six-phase PWM (BOOK.md chapter 8): the 64 states, volt-second balance on alpha-beta and z1-z2, linear
ranges, the six-leg bridges, and the 5th/7th harmonic currents of two-vector SVPWM.

Independent references: the states' voltages and every period average are recomputed here from the leg
duties with the VSD table written out (pole voltages, each star's mean removed); decoupled SVPWM (two
book SVPWMs) and double zero-sequence carrier PWM are two different constructions that must give the same
duties; the linear limits are the geometric values (inscribed circles), checked by bisection on the
modulators.

Modules: pmsmjax/inverters/six_phase_vectors.py, six_phase_svpwm.py, six_phase_carrier.py,
multiphase_bridges.py.
"""

import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import ParameterError
from pmsmjax.inverters import (
    DecoupledSVPWM,
    DoubleZeroSequencePWM,
    FourVectorSVPWM,
    MultiPhaseAveragedBridge,
    MultiPhaseSwitchingBridge,
    TwoVectorSVPWM,
)
from pmsmjax.inverters.six_phase_vectors import switching_vectors
from pmsmjax.studies.pwm_comparison_multiphase import SixPhaseCompareSettings, compare_six_phase

U_DC = 311.0
S3 = math.sqrt(3.0)
T_TABLE = (1.0 / 3.0) * np.array(
    [
        [1, -0.5, -0.5, S3 / 2, -S3 / 2, 0],
        [0, S3 / 2, -S3 / 2, 0.5, 0.5, -1],
        [1, -0.5, -0.5, -S3 / 2, S3 / 2, 0],
        [0, -S3 / 2, S3 / 2, 0.5, 0.5, -1],
    ]
)
MODULATORS = {
    "four-vector": FourVectorSVPWM(),
    "two-vector": TwoVectorSVPWM(),
    "decoupled": DecoupledSVPWM(),
    "double-zs": DoubleZeroSequencePWM(),
}
#: The geometric linear limits (alpha-beta peak per unit of U_dc): the inscribed circle of the L-vector
#: 12-gon, (2/3) cos^2(15 deg), for two-vector; each set's hexagon, 1/sqrt(3), for the others.
LIMITS = {"two-vector": (2 / 3) * math.cos(math.pi / 12) ** 2, "four-vector": 1 / S3, "decoupled": 1 / S3}
LIMITS["double-zs"] = 1 / S3


def period_average(duties):
    """``(..., 4)`` period-average [alpha, beta, z1, z2] V of leg duties ``(..., 6)`` (written out)."""
    v = U_DC * np.asarray(duties, float)
    v[..., :3] -= v[..., :3].mean(-1, keepdims=True)
    v[..., 3:] -= v[..., 3:].mean(-1, keepdims=True)
    return v @ T_TABLE.T


duties_of = {name: jax.jit(jax.vmap(m.duties, in_axes=(0, None))) for name, m in MODULATORS.items()}


def test_the_64_states_on_alpha_beta_and_z():
    states, vectors = switching_vectors(U_DC)
    expect = []
    for bits in itertools.product((0, 1), repeat=6):
        expect.append(period_average(np.asarray(bits[::-1], float)))  # state index: leg A = bit 0
    np.testing.assert_allclose(vectors, np.asarray(expect), atol=1e-12)
    np.testing.assert_allclose(period_average(states), vectors, atol=1e-12)
    ab = np.round(np.hypot(vectors[:, 0], vectors[:, 1]) / U_DC, 6)
    z = np.round(np.hypot(vectors[:, 2], vectors[:, 3]) / U_DC, 6)
    c15 = math.cos(math.pi / 12)
    groups = {}
    for a, b in zip(ab, z, strict=True):
        groups[(a, b)] = groups.get((a, b), 0) + 1
    # (alpha-beta length, z1-z2 length) per unit of U_dc -> count: zero, small, medium, ML, L.
    expected = {
        (0.0, 0.0): 4,
        (round((2 / 3) * math.sin(math.pi / 12), 6), round((2 / 3) * c15, 6)): 12,
        (round(1 / 3, 6), round(1 / 3, 6)): 24,
        (round(math.sqrt(2) / 3, 6), round(math.sqrt(2) / 3, 6)): 12,
        (round((2 / 3) * c15, 6), round((2 / 3) * math.sin(math.pi / 12), 6)): 12,
    }
    assert groups == expected
    large = np.isclose(ab, (2 / 3) * c15)
    angles = np.degrees(np.arctan2(vectors[large, 1], vectors[large, 0])) % 360
    np.testing.assert_allclose(np.sort(angles), 15 + 30 * np.arange(12), atol=1e-9)  # 12 sectors


def random_references(n, limit, seed):
    rng = np.random.default_rng(seed)
    r = limit * np.sqrt(rng.uniform(0, 1, n)) * 0.999999
    a = rng.uniform(-np.pi, np.pi, n)
    r[:24] = limit * 0.999999  # on the limit circle, at all angles
    return np.stack([r * np.cos(a), r * np.sin(a)], 1)


@pytest.mark.parametrize("name", list(MODULATORS))
def test_volt_second_balance_inside_the_linear_range(name):
    modulator = MODULATORS[name]
    limit = float(modulator.linear_limit(U_DC))
    assert abs(limit - LIMITS[name] * U_DC) < 1e-9
    refs = random_references(500, limit, seed=len(name))
    d = np.asarray(duties_of[name](jnp.asarray(refs), U_DC))
    assert d.min() >= -1e-12 and d.max() <= 1 + 1e-12
    avg = period_average(d)
    np.testing.assert_allclose(avg[:, :2], refs, atol=1e-9)
    z = np.hypot(avg[:, 2], avg[:, 3])
    if name == "two-vector":
        # z1-z2 left uncontrolled: the L vectors' z components, 0.1725 U_dc per unit of dwell time, add up.
        big = np.hypot(refs[:, 0], refs[:, 1]) > 10.0
        assert np.all(z[big] > 0.01 * np.hypot(refs[big, 0], refs[big, 1]))
    else:
        assert np.max(z) < 1e-9


@pytest.mark.parametrize("name", list(MODULATORS))
def test_linear_limit_is_the_largest_reproducible_circle(name):
    """Bisect the largest radius reproduced to 1e-9 V at each of 241 angles: its minimum is the limit."""
    angles = np.linspace(0, 2 * np.pi, 241)
    lo, hi = np.full(angles.shape, 0.3 * U_DC), np.full(angles.shape, 0.8 * U_DC)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        refs = np.stack([mid * np.cos(angles), mid * np.sin(angles)], 1)
        ok = np.max(np.abs(period_average(duties_of[name](jnp.asarray(refs), U_DC))[:, :2] - refs), 1) < 1e-9
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    assert abs(lo.min() - LIMITS[name] * U_DC) < 1e-6 * U_DC
    # 2 % beyond it the average falls short of the reference at the worst angles (over-modulation).
    radius = 1.02 * LIMITS[name] * U_DC
    refs = radius * np.stack([np.cos(angles), np.sin(angles)], 1)
    reached = np.hypot(*period_average(duties_of[name](jnp.asarray(refs), U_DC))[:, :2].T)
    assert np.min(reached) < radius - 1.0


def test_decoupled_svpwm_equals_double_zero_sequence_and_both_apply_z():
    rng = np.random.default_rng(5)
    r = rng.uniform(0, 0.75 / S3 * U_DC, 300)
    a = rng.uniform(-np.pi, np.pi, 300)
    z = rng.uniform(-0.2 / S3 * U_DC, 0.2 / S3 * U_DC, (300, 2))  # |u_ab| + |u_z| inside each hexagon
    refs = np.concatenate([np.stack([r * np.cos(a), r * np.sin(a)], 1), z], 1)
    d1 = np.asarray(duties_of["decoupled"](jnp.asarray(refs), U_DC))
    d2 = np.asarray(duties_of["double-zs"](jnp.asarray(refs), U_DC))
    np.testing.assert_allclose(d1, d2, atol=1e-12)
    np.testing.assert_allclose(period_average(d1), refs, atol=1e-9)


def test_four_vector_applies_a_z_reference_when_its_dwell_times_allow():
    m = MODULATORS["four-vector"]
    rng = np.random.default_rng(2)
    n_ok = 0
    for _ in range(200):
        u = np.r_[rng.uniform(-100, 100, 2), rng.uniform(-5, 5, 2)]
        _, t = m.dwell_times(jnp.asarray(u), U_DC)
        avg = period_average(m.duties(jnp.asarray(u), U_DC))
        if float(jnp.min(t)) >= 0 and float(jnp.sum(t)) <= 1:
            np.testing.assert_allclose(avg, u, atol=1e-9)
            n_ok += 1
    assert n_ok > 40  # many small z references are reachable; the rest need negative dwell times


def test_switching_bridge_period_average_equals_the_averaged_bridge():
    """Volt-second balance of the segment-exact bridge (13 segments; 25 with dead time off-state)."""
    from pmsmjax.presets.six_phase import six_phase_machine

    machine = six_phase_machine(frame="dq", mechanics="imposed")
    state = machine.initial_state((1.0, 5.0), 100.0, 0.4)
    avg_bridge, sw_bridge = MultiPhaseAveragedBridge(U_DC), MultiPhaseSwitchingBridge(U_DC)
    adv = jax.jit(lambda d: sw_bridge.advance(machine, state, d, 0.0, 1e-4, 1))
    adv_avg = jax.jit(lambda d: avg_bridge.advance(machine, state, d, 0.0, 1e-4, 10))
    rng = np.random.default_rng(3)
    for name in MODULATORS:
        for _ in range(5):
            d = duties_of[name](jnp.asarray(random_references(1, 150.0, rng.integers(1000))), U_DC)[0]
            s_sw, u_sw = adv(d)
            s_avg, u_avg = adv_avg(d)
            np.testing.assert_allclose(u_sw, period_average(d), atol=1e-9)
            np.testing.assert_allclose(u_avg, period_average(d), atol=1e-9)
            # One period of ripple apart, but the same trajectory on average: within the ripple.
            assert float(jnp.max(jnp.abs(s_sw.currents - s_avg.currents))) < 5.0
    times, *_ = sw_bridge.segments(jnp.full(6, 0.5), 1e-4)
    assert times.shape == (14,)
    with pytest.raises(ParameterError, match="shape \\(6,\\)"):
        sw_bridge.advance(machine, state, jnp.zeros(3), 0.0, 1e-4, 1)


def test_dead_time_and_device_drop_of_the_six_leg_bridge():
    """With constant-sign currents each switching leg loses ``sign(i) U_dc t_d / Ts`` of average pole
    voltage (dead time) and ``sign(i) U_f`` (device drop); the ideal fast path equals the general one."""
    from pmsmjax.presets.six_phase import six_phase_machine

    machine = six_phase_machine(frame="natural", mechanics="imposed")
    # 20 A at 15 deg from the phase axes: every phase carries at least 20 sin(15 deg) = 5.2 A, and the
    # duties' few volts cannot change a sign within the period (standstill: no back-EMF).
    i_ab = 20.0 * np.array([np.cos(np.pi / 12), np.sin(np.pi / 12)])
    state = machine.initial_state_vsd([*i_ab, 0.0, 0.0], 0.0, 0.2)
    Ts, t_d, drop = 1e-4, 2e-6, 1.5
    d = jnp.asarray([0.49, 0.51, 0.5, 0.52, 0.48, 0.505])
    ideal = MultiPhaseSwitchingBridge(U_DC).advance(machine, state, d, 0.0, Ts, 1)
    general = MultiPhaseSwitchingBridge(U_DC, device_drop=0.0).advance(machine, state, d, 0.0, Ts, 1)
    np.testing.assert_allclose(general[1], ideal[1], atol=1e-10)
    np.testing.assert_allclose(general[0].currents, ideal[0].currents, atol=1e-12)
    sign = np.sign(np.asarray(machine.phase_currents(state)))
    _, u_dead = MultiPhaseSwitchingBridge(U_DC, dead_time=t_d).advance(machine, state, d, 0.0, Ts, 1)
    lost = -sign * U_DC * t_d / Ts  # per leg, average pole voltage
    np.testing.assert_allclose(u_dead, period_average(np.asarray(d) + lost / U_DC), atol=1e-9)
    _, u_drop = MultiPhaseSwitchingBridge(U_DC, device_drop=drop).advance(machine, state, d, 0.0, Ts, 1)
    np.testing.assert_allclose(u_drop, period_average(np.asarray(d) - sign * drop / U_DC), atol=1e-9)


def test_modulator_gradients_match_finite_differences():
    u0 = jnp.asarray([80.0, -40.0, 3.0, -2.0])
    w = jnp.asarray([0.3, -0.2, 0.5, 0.1, -0.4, 0.7])
    for name in ("four-vector", "two-vector", "decoupled", "double-zs"):
        f = lambda u, name=name: jnp.dot(w, MODULATORS[name].duties(u, U_DC))
        g = np.asarray(jax.grad(f)(u0))
        h = 1e-4
        fd = np.array([(f(u0.at[k].add(h)) - f(u0.at[k].add(-h))) / (2 * h) for k in range(4)])
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-10)
        assert np.all(np.isfinite(jax.grad(f)(jnp.zeros(4))))


def test_two_vector_five_and_seven_harmonics_appear_switching_resolved_and_four_vector_suppresses_them():
    settings = SixPhaseCompareSettings(
        modulators=("four-vector", "two-vector"),
        bridges=("switching",),
        settle_cycles=1,
        window_cycles=1,
        samples_per_period=16,
        thd_max_carriers=2.0,
    )
    result = compare_six_phase(settings)
    fv, tv = result["entries"]["four-vector_switching"], result["entries"]["two-vector_switching"]
    assert fv["linear_limit_v"] == pytest.approx(U_DC / S3) and tv["linear_limit_v"] > fv["linear_limit_v"]
    assert abs(fv["fundamental_phase_voltage_v"] - tv["fundamental_phase_voltage_v"]) < 0.5
    assert fv["z_average_voltage_rms_v"] < 1e-9 and tv["z_average_voltage_rms_v"] > 1.0
    for k in (5, 7):
        assert tv[f"harmonic_{k}_current_a"] > 1.0
        assert tv[f"harmonic_{k}_current_a"] > 100 * fv[f"harmonic_{k}_current_a"]
        # The 5th and 7th live in z1-z2: the phase harmonic equals the z1-z2 current's.
        assert tv[f"harmonic_{k}_current_a"] == pytest.approx(tv[f"harmonic_{k}_z_current_a"], rel=0.02)
    assert tv["current_thd_pct"] > 10 * fv["current_thd_pct"]
