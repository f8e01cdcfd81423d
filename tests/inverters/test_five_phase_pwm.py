"""Five-phase PWM (BOOK.md chapter 10): the 32 states, volt-second balance on alpha-beta and x-y, the linear
ranges, the five-leg bridges.

Independent references: the states' voltages and every period average are recomputed here from the leg
duties with the 5x5 Clarke written out (pole voltages less their mean, the isolated star); near-four-vector
SVPWM (dwell times of four states) and min-max carrier PWM (phase references plus a zero sequence) are two
different constructions that must give the same duties inside the linear range; the linear limits are the
geometric values (``U_dc / (2 cos 18 deg)``: a balanced five-phase set's largest spread; the L decagon's
inscribed circle for the large-vector method; ``U_dc/2`` for sinusoidal PWM), found by bisection on the
modulators. The generic space-vector tables reproduce the six-phase ones.

Modules: pmsmjax/inverters/multiphase_vectors.py, multiphase_svpwm.py, multiphase_carrier.py,
multiphase_bridges.py.
"""

import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import ParameterError
from pmsmjax.frames.multiphase import FIVE_PHASE, SIX_PHASE
from pmsmjax.inverters import (
    LargeVectorSVPWM,
    MultiPhaseAveragedBridge,
    MultiPhaseSwitchingBridge,
    NearFourVectorSVPWM,
    ZeroSequencePWM,
)
from pmsmjax.inverters import six_phase_vectors as six
from pmsmjax.inverters.multiphase_vectors import space_vectors

U_DC = 311.0
G = 2 * np.pi * np.arange(5) / 5
T_TABLE = np.stack([0.4 * np.cos(G), 0.4 * np.sin(G), 0.4 * np.cos(3 * G), 0.4 * np.sin(3 * G)])
C18 = math.cos(math.pi / 10)
MODULATORS = {
    "near-four-vector": NearFourVectorSVPWM(),
    "carrier": ZeroSequencePWM(),
    "sinusoidal": ZeroSequencePWM(injection="none"),
    "large-vector": LargeVectorSVPWM(),
}
#: Geometric linear limits per unit of U_dc (alpha-beta peak, x-y reference 0).
LIMITS = {
    "near-four-vector": 1 / (2 * C18),
    "carrier": 1 / (2 * C18),
    "sinusoidal": 0.5,
    "large-vector": 0.8 * math.cos(math.pi / 5) * C18,
}


def period_average(duties):
    """``(..., 4)`` period-average [alpha, beta, x, y] V of leg duties ``(..., 5)`` (written out)."""
    v = U_DC * np.asarray(duties, float)
    v = v - v.mean(-1, keepdims=True)
    return v @ T_TABLE.T


duties_of = {name: jax.jit(jax.vmap(m.duties, in_axes=(0, None))) for name, m in MODULATORS.items()}


def test_the_32_states_on_alpha_beta_and_xy():
    sv = space_vectors(FIVE_PHASE)
    expect = [
        period_average(np.asarray(bits[::-1], float)) / U_DC for bits in itertools.product((0, 1), repeat=5)
    ]
    np.testing.assert_allclose(sv.vectors, np.asarray(expect), atol=1e-12)
    ab = np.round(np.hypot(sv.vectors[:, 0], sv.vectors[:, 1]), 6)
    xy = np.round(np.hypot(sv.vectors[:, 2], sv.vectors[:, 3]), 6)
    groups = {}
    for a, b in zip(ab, xy, strict=True):
        groups[(a, b)] = groups.get((a, b), 0) + 1
    big, mid, small = 0.8 * math.cos(math.pi / 5), 0.4, 0.8 * math.cos(2 * math.pi / 5)
    r = lambda x: round(x, 6)
    assert groups == {(0.0, 0.0): 2, (r(small), r(big)): 10, (r(mid), r(mid)): 10, (r(big), r(small)): 10}
    angles = np.degrees(np.arctan2(sv.vectors[sv.large, 1], sv.vectors[sv.large, 0])) % 360
    np.testing.assert_allclose(np.sort(np.round(angles, 9) % 360), 36 * np.arange(10), atol=1e-9)
    # The medium vector at an L direction has its x-y component opposite to the L vector's.
    for i, j in zip(sv.large, sv.second, strict=True):
        np.testing.assert_allclose(sv.vectors[j, :2] / mid, sv.vectors[i, :2] / big, atol=1e-12)
        np.testing.assert_allclose(sv.vectors[j, 2:] / mid, -sv.vectors[i, 2:] / small, atol=1e-12)


def test_generic_tables_reproduce_the_six_phase_ones():
    sv = space_vectors(SIX_PHASE)
    np.testing.assert_array_equal(sv.large, six.LARGE)
    np.testing.assert_array_equal(sv.second, six.MEDIUM_LARGE)
    np.testing.assert_allclose(sv.bisectors, six.BISECTORS, atol=1e-15)
    assert NearFourVectorSVPWM(SIX_PHASE).linear_limit(1.0) == pytest.approx(1 / math.sqrt(3), rel=1e-12)


def random_references(n, limit, seed):
    rng = np.random.default_rng(seed)
    r = limit * np.sqrt(rng.uniform(0, 1, n)) * 0.999999
    a = rng.uniform(-np.pi, np.pi, n)
    r[:40] = limit * 0.999999  # on the limit circle, at all angles
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
    xy = np.hypot(avg[:, 2], avg[:, 3])
    if name == "large-vector":
        # x-y left uncontrolled: the L vectors' x-y components (0.2472 U_dc per unit of dwell) add up.
        big = np.hypot(refs[:, 0], refs[:, 1]) > 10.0
        assert np.all(xy[big] > 0.05 * np.hypot(refs[big, 0], refs[big, 1]))
    else:
        assert np.max(xy) < 1e-9


@pytest.mark.parametrize("name", list(MODULATORS))
def test_linear_limit_is_the_largest_reproducible_circle(name):
    """Bisect the largest radius reproduced to 1e-9 V at each of 201 angles: its minimum is the limit."""
    angles = np.linspace(0, 2 * np.pi, 201)
    lo, hi = np.full(angles.shape, 0.3 * U_DC), np.full(angles.shape, 0.8 * U_DC)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        refs = np.stack([mid * np.cos(angles), mid * np.sin(angles)], 1)
        avg = period_average(duties_of[name](jnp.asarray(refs), U_DC))
        ok = np.max(np.abs(avg[:, :2] - refs), 1) < 1e-9
        if name != "large-vector":
            ok &= np.max(np.abs(avg[:, 2:]), 1) < 1e-9
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    assert abs(lo.min() - LIMITS[name] * U_DC) < 1e-6 * U_DC
    # 2 % beyond it the average falls short of the reference at the worst angles (over-modulation).
    radius = 1.02 * LIMITS[name] * U_DC
    refs = radius * np.stack([np.cos(angles), np.sin(angles)], 1)
    reached = np.hypot(*period_average(duties_of[name](jnp.asarray(refs), U_DC))[:, :2].T)
    assert np.min(reached) < radius - 1.0


def test_near_four_vector_equals_min_max_carrier_and_both_apply_xy():
    rng = np.random.default_rng(5)
    r = rng.uniform(0, 0.8 * LIMITS["carrier"] * U_DC, 300)
    a = rng.uniform(-np.pi, np.pi, 300)
    refs2 = np.stack([r * np.cos(a), r * np.sin(a)], 1)
    d1 = np.asarray(duties_of["near-four-vector"](jnp.asarray(refs2), U_DC))
    d2 = np.asarray(duties_of["carrier"](jnp.asarray(refs2), U_DC))
    np.testing.assert_allclose(d1, d2, atol=1e-12)
    # With an x-y command: the carrier applies it exactly while the references stay inside the link.
    xy = rng.uniform(-10, 10, (300, 2))
    refs = np.concatenate([refs2, xy], 1)
    d = np.asarray(duties_of["carrier"](jnp.asarray(refs), U_DC))
    inside = (d.min(1) > 1e-9) & (d.max(1) < 1 - 1e-9)
    assert inside.sum() > 250
    np.testing.assert_allclose(period_average(d[inside]), refs[inside], atol=1e-9)
    nfv = MODULATORS["near-four-vector"]
    n_ok = 0
    for u in refs[:100]:
        _, t = nfv.dwell_times(jnp.asarray(u), U_DC)
        if float(jnp.min(t)) >= 0 and float(jnp.sum(t)) <= 1:
            np.testing.assert_allclose(period_average(nfv.duties(jnp.asarray(u), U_DC)), u, atol=1e-9)
            n_ok += 1
    assert n_ok > 30


def test_five_leg_bridges_period_average_and_dead_time():
    from pmsmjax.presets.five_phase import five_phase_machine

    machine = five_phase_machine(frame="natural", mechanics="imposed")
    state = machine.initial_state_vsd([1.0, 5.0, 0.0, 0.0], 100.0, 0.4)
    avg_bridge = MultiPhaseAveragedBridge(U_DC, FIVE_PHASE)
    sw_bridge = MultiPhaseSwitchingBridge(U_DC, layout=FIVE_PHASE)
    adv = jax.jit(lambda d: sw_bridge.advance(machine, state, d, 0.0, 1e-4, 1))
    adv_avg = jax.jit(lambda d: avg_bridge.advance(machine, state, d, 0.0, 1e-4, 10))
    rng = np.random.default_rng(3)
    for name in MODULATORS:
        for _ in range(3):
            d = duties_of[name](jnp.asarray(random_references(1, 140.0, rng.integers(1000))), U_DC)[0]
            s_sw, u_sw = adv(d)
            s_avg, u_avg = adv_avg(d)
            np.testing.assert_allclose(u_sw, period_average(d), atol=1e-9)
            np.testing.assert_allclose(u_avg, period_average(d), atol=1e-9)
            assert float(jnp.max(jnp.abs(s_sw.currents - s_avg.currents))) < 5.0
    times, *_ = sw_bridge.segments(jnp.full(5, 0.5), 1e-4)
    assert times.shape == (12,)  # 2 x 5 edges, 11 segments
    with pytest.raises(ParameterError, match="shape \\(5,\\)"):
        sw_bridge.advance(machine, state, jnp.zeros(6), 0.0, 1e-4, 1)
    # Dead time: each leg loses sign(i) U_dc t_d / Ts of average pole voltage (constant-sign currents at
    # standstill; 20 A along the A axis: every phase carries at least 20 cos 72 deg = 6.2 A).
    state = machine.initial_state_vsd([20.0, 0.0, 0.0, 0.0])
    d = jnp.asarray([0.49, 0.51, 0.5, 0.52, 0.48])
    sign = np.sign(np.asarray(machine.phase_currents(state)))
    assert np.all(np.abs(np.asarray(machine.phase_currents(state))) > 6.0)
    Ts, t_d = 1e-4, 2e-6
    machine0 = five_phase_machine(frame="natural", mechanics="imposed")
    _, u_dead = MultiPhaseSwitchingBridge(U_DC, dead_time=t_d, layout=FIVE_PHASE).advance(
        machine0, state, d, 0.0, Ts, 1
    )
    np.testing.assert_allclose(u_dead, period_average(np.asarray(d) - sign * t_d / Ts), atol=1e-9)


def test_modulator_gradients_match_finite_differences():
    u0 = jnp.asarray([80.0, -40.0, 3.0, -2.0])
    w = jnp.asarray([0.3, -0.2, 0.5, 0.1, -0.4])
    for name, m in MODULATORS.items():
        f = lambda u, m=m: jnp.dot(w, m.duties(u, U_DC))
        g = np.asarray(jax.grad(f)(u0))
        h = 1e-4
        fd = np.array([(f(u0.at[k].add(h)) - f(u0.at[k].add(-h))) / (2 * h) for k in range(4)])
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-10, err_msg=name)
        assert np.all(np.isfinite(jax.grad(f)(jnp.zeros(4))))


def test_modulator_checks():
    with pytest.raises(ParameterError, match="injection"):
        ZeroSequencePWM(injection="third")
    with pytest.raises(ParameterError, match="reference"):
        MODULATORS["near-four-vector"].duties(jnp.zeros(3), U_DC)
    assert all(m.n_phases == 5 for m in MODULATORS.values())
