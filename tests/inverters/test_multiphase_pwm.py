"""Multi-phase PWM (the book, ch. 8: six phases; chapter 10: five): the switching states, volt-second
balance on both VSD planes, the linear ranges, the n-leg bridges; each check runs on both windings.

Independent references: the states' voltages and every period average are recomputed here from the leg
duties with the VSD table written out per winding (pole voltages less each star's mean). Two different
constructions must give the same duties inside the linear range: on five phases (one star)
near-four-vector SVPWM (dwell times of four states) and min-max carrier PWM (phase references plus a zero
sequence); on six phases min-max carrier PWM (one zero sequence per set) and decoupled SVPWM (the book's
three-phase SVPWM per set). The linear limits are the
geometric values (six phases: each set's hexagon, ``U_dc/sqrt(3)``, and the L 12-gon's inscribed circle
``(2/3) cos^2 15 deg``; five phases: ``U_dc / (2 cos 18 deg)``, a balanced five-phase set's largest spread,
the L decagon's inscribed circle, ``U_dc/2`` for sinusoidal PWM), found by bisection on the modulators.
The modulators are built by the presets' tables (the names users pick).

Modules: pmsmjax/inverters/multiphase_vectors.py, multiphase_svpwm.py, multiphase_carrier.py,
decoupled_svpwm.py, multiphase_bridges.py; pmsmjax/presets/six_phase.py, five_phase.py (SIX_PHASE_PWMS,
FIVE_PHASE_PWMS).
"""

import dataclasses
import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import ParameterError
from pmsmjax.frames.multiphase import FIVE_PHASE, SIX_PHASE, PhaseLayout
from pmsmjax.inverters import (
    SVPWM,
    DecoupledSVPWM,
    LargeVectorSVPWM,
    MultiPhaseAveragedBridge,
    MultiPhaseSwitchingBridge,
    NearFourVectorSVPWM,
    ZeroSequencePWM,
)
from pmsmjax.inverters.multiphase_vectors import space_vectors
from pmsmjax.jobs.pwm_comparison import CompareSettings, compare
from pmsmjax.presets.five_phase import FIVE_PHASE_PWMS, five_phase_machine
from pmsmjax.presets.six_phase import SIX_PHASE_PWMS, six_phase_machine

U_DC = 311.0
S3 = math.sqrt(3.0)
C15 = math.cos(math.pi / 12)
C18 = math.cos(math.pi / 10)
G5 = 2 * np.pi * np.arange(5) / 5


@dataclasses.dataclass(frozen=True)
class Winding:
    """One winding's modulators and the values the tests check them against (written out here).

    `table`: the VSD rows ``(4, n)`` [alpha, beta, second plane] of phase voltages, amplitude-invariant;
    `stars`: the phases of each isolated star point; `limits`: linear limits per unit of U_dc; `roles`:
    which modulator nulls the second plane by dwell times, which leaves it uncontrolled, which is min-max
    carrier PWM; `uncontrolled_share`: a floor of the uncontrolled method's second-plane average per volt
    of reference; `on_circle`: references put on the limit circle; `angles`: bisection angles.
    """

    layout: PhaseLayout
    pwms: dict
    table: np.ndarray
    stars: tuple
    limits: dict
    roles: dict
    uncontrolled_share: float
    on_circle: int
    angles: int

    @property
    def n(self) -> int:
        return self.layout.n

    def period_average(self, duties):
        """``(..., 4)`` period-average VSD voltages, V, of leg duties ``(..., n)`` (written out)."""
        v = U_DC * np.asarray(duties, float)
        for star in self.stars:
            v[..., star] -= v[..., star].mean(-1, keepdims=True)
        return v @ self.table.T


SIX = Winding(
    layout=SIX_PHASE,
    pwms=SIX_PHASE_PWMS,
    table=(1.0 / 3.0)
    * np.array(
        [
            [1, -0.5, -0.5, S3 / 2, -S3 / 2, 0],
            [0, S3 / 2, -S3 / 2, 0.5, 0.5, -1],
            [1, -0.5, -0.5, -S3 / 2, S3 / 2, 0],
            [0, -S3 / 2, S3 / 2, 0.5, 0.5, -1],
        ]
    ),
    stars=([0, 1, 2], [3, 4, 5]),
    limits={"four-vector": 1 / S3, "two-vector": (2 / 3) * C15**2, "decoupled": 1 / S3, "double-zs": 1 / S3},
    roles={"nulling": "four-vector", "uncontrolled": "two-vector", "carrier": "double-zs"},
    # z1-z2 left uncontrolled: the L vectors' z components, 0.1725 U_dc per unit of dwell time, add up.
    uncontrolled_share=0.01,
    on_circle=24,
    angles=241,
)
FIVE = Winding(
    layout=FIVE_PHASE,
    pwms=FIVE_PHASE_PWMS,
    table=np.stack([0.4 * np.cos(G5), 0.4 * np.sin(G5), 0.4 * np.cos(3 * G5), 0.4 * np.sin(3 * G5)]),
    stars=([0, 1, 2, 3, 4],),
    limits={
        "near-four-vector": 1 / (2 * C18),
        "carrier": 1 / (2 * C18),
        "sinusoidal": 0.5,
        "large-vector": 0.8 * math.cos(math.pi / 5) * C18,
    },
    roles={"nulling": "near-four-vector", "uncontrolled": "large-vector", "carrier": "carrier"},
    # x-y left uncontrolled: the L vectors' x-y components (0.2472 U_dc per unit of dwell) add up.
    uncontrolled_share=0.05,
    on_circle=40,
    angles=201,
)
WINDINGS = {"six": SIX, "five": FIVE}
MODULATORS = {(w, name): make() for w, winding in WINDINGS.items() for name, make in winding.pwms.items()}
duties_of = {key: jax.jit(jax.vmap(m.duties, in_axes=(0, None))) for key, m in MODULATORS.items()}
EVERY_MODULATOR = pytest.mark.parametrize("key", list(MODULATORS), ids=lambda k: "-".join(k))
EVERY_WINDING = pytest.mark.parametrize("w", list(WINDINGS))


def random_references(n, limit, seed, on_circle):
    rng = np.random.default_rng(seed)
    r = limit * np.sqrt(rng.uniform(0, 1, n)) * 0.999999
    a = rng.uniform(-np.pi, np.pi, n)
    r[:on_circle] = limit * 0.999999  # on the limit circle, at all angles
    return np.stack([r * np.cos(a), r * np.sin(a)], 1)


@EVERY_WINDING
def test_every_state_is_its_written_out_vsd_vector(w):
    winding = WINDINGS[w]
    sv = space_vectors(winding.layout)
    expect = [
        winding.period_average(np.asarray(bits[::-1], float)) / U_DC  # state index: leg 0 = bit 0
        for bits in itertools.product((0, 1), repeat=winding.n)
    ]
    np.testing.assert_allclose(sv.vectors, np.asarray(expect), atol=1e-12)
    np.testing.assert_allclose(winding.period_average(sv.states) / U_DC, sv.vectors, atol=1e-12)


def _groups(sv):
    ab = np.round(np.hypot(sv.vectors[:, 0], sv.vectors[:, 1]), 6)
    second = np.round(np.hypot(sv.vectors[:, 2], sv.vectors[:, 3]), 6)
    groups = {}
    for a, b in zip(ab, second, strict=True):
        groups[(a, b)] = groups.get((a, b), 0) + 1
    return groups


def _check_large_and_second(sv, large, second, first_angle_deg):
    """The L states at ``first_angle + k 360/K`` deg, sorted; the second group collinear with them and
    opposite to them in the second plane; the bisectors halfway between neighbouring L states."""
    K = len(sv.large)
    angles = np.degrees(np.arctan2(sv.vectors[sv.large, 1], sv.vectors[sv.large, 0])) % 360
    expected = first_angle_deg + (360 / K) * np.arange(K)
    np.testing.assert_allclose(np.round(angles, 9) % 360, expected, atol=1e-9)
    small = np.hypot(*sv.vectors[sv.large[0], 2:])
    for i, j in zip(sv.large, sv.second, strict=True):
        np.testing.assert_allclose(sv.vectors[j, :2] / second, sv.vectors[i, :2] / large, atol=1e-12)
        np.testing.assert_allclose(sv.vectors[j, 2:] / second, -sv.vectors[i, 2:] / small, atol=1e-12)
    mid = np.radians(expected + 180 / K)
    np.testing.assert_allclose(sv.bisectors, np.stack([np.cos(mid), np.sin(mid)], 1), atol=1e-15)


def test_the_64_six_phase_states_four_lengths_and_twelve_sectors():
    sv = space_vectors(SIX_PHASE)
    r = lambda x: round(x, 6)
    s15 = math.sin(math.pi / 12)
    # (alpha-beta length, z1-z2 length) per unit of U_dc -> count: zero, small, medium, ML, L.
    assert _groups(sv) == {
        (0.0, 0.0): 4,
        (r((2 / 3) * s15), r((2 / 3) * C15)): 12,
        (r(1 / 3), r(1 / 3)): 24,
        (r(math.sqrt(2) / 3), r(math.sqrt(2) / 3)): 12,
        (r((2 / 3) * C15), r((2 / 3) * s15)): 12,
    }
    _check_large_and_second(sv, (2 / 3) * C15, math.sqrt(2) / 3, 15.0)  # 12 sectors of 30 deg
    # |L| in closed form: (2/3) cos 15 deg, which the states' magnitudes give to rounding.
    assert sv.large_magnitude == (2.0 / 3.0) * np.cos(np.pi / 12)
    np.testing.assert_allclose(np.hypot(*sv.vectors[sv.large, :2].T), sv.large_magnitude, rtol=1e-15)


def test_the_32_five_phase_states_three_lengths_and_ten_sectors():
    sv = space_vectors(FIVE_PHASE)
    big, mid, small = 0.8 * math.cos(math.pi / 5), 0.4, 0.8 * math.cos(2 * math.pi / 5)
    r = lambda x: round(x, 6)
    assert _groups(sv) == {
        (0.0, 0.0): 2,
        (r(small), r(big)): 10,
        (r(mid), r(mid)): 10,
        (r(big), r(small)): 10,
    }
    _check_large_and_second(sv, big, mid, 0.0)  # 10 sectors of 36 deg
    assert sv.large_magnitude == pytest.approx(big, rel=1e-15)


@EVERY_MODULATOR
def test_volt_second_balance_inside_the_linear_range(key):
    winding, name = WINDINGS[key[0]], key[1]
    limit = float(MODULATORS[key].linear_limit(U_DC))
    assert abs(limit - winding.limits[name] * U_DC) < 1e-9
    refs = random_references(500, limit, len(name), winding.on_circle)
    d = np.asarray(duties_of[key](jnp.asarray(refs), U_DC))
    assert d.min() >= -1e-12 and d.max() <= 1 + 1e-12
    avg = winding.period_average(d)
    np.testing.assert_allclose(avg[:, :2], refs, atol=1e-9)
    second = np.hypot(avg[:, 2], avg[:, 3])
    if name == winding.roles["uncontrolled"]:
        big = np.hypot(refs[:, 0], refs[:, 1]) > 10.0
        assert np.all(second[big] > winding.uncontrolled_share * np.hypot(refs[big, 0], refs[big, 1]))
    else:
        assert np.max(second) < 1e-9


@EVERY_MODULATOR
def test_linear_limit_is_the_largest_reproducible_circle(key):
    """Bisect the largest radius reproduced to 1e-9 V (second plane nulled too, where the method nulls
    it) at each angle: its minimum is the limit."""
    winding, name = WINDINGS[key[0]], key[1]
    angles = np.linspace(0, 2 * np.pi, winding.angles)
    lo, hi = np.full(angles.shape, 0.3 * U_DC), np.full(angles.shape, 0.8 * U_DC)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        refs = np.stack([mid * np.cos(angles), mid * np.sin(angles)], 1)
        avg = winding.period_average(duties_of[key](jnp.asarray(refs), U_DC))
        ok = np.max(np.abs(avg[:, :2] - refs), 1) < 1e-9
        if name != winding.roles["uncontrolled"]:
            ok &= np.max(np.abs(avg[:, 2:]), 1) < 1e-9
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    assert abs(lo.min() - winding.limits[name] * U_DC) < 1e-6 * U_DC
    # 2 % beyond it the average falls short of the reference at the worst angles (over-modulation).
    radius = 1.02 * winding.limits[name] * U_DC
    refs = radius * np.stack([np.cos(angles), np.sin(angles)], 1)
    reached = np.hypot(*winding.period_average(duties_of[key](jnp.asarray(refs), U_DC))[:, :2].T)
    assert np.min(reached) < radius - 1.0


def test_linear_limits_in_closed_form_to_the_last_bit():
    """Where a limit is the three-phase hexagon's, every method gives the number three-phase SVPWM gives;
    the five-phase near-four-vector limit from the dwell-time tables is the closed form to rounding."""
    hexagon = float(SVPWM().linear_limit(U_DC))
    assert hexagon == U_DC / math.sqrt(3.0)
    for name in ("four-vector", "decoupled", "double-zs"):
        assert float(MODULATORS["six", name].linear_limit(U_DC)) == hexagon, name
    c15 = np.cos(np.pi / 12)  # the 12-gon's inscribed circle (2/3) cos^2 15 deg, as NumPy rounds it
    assert float(MODULATORS["six", "two-vector"].linear_limit(U_DC)) == (2 / 3) * c15 * c15 * U_DC
    nfv, carrier = (float(MODULATORS["five", m].linear_limit(U_DC)) for m in ("near-four-vector", "carrier"))
    assert nfv == pytest.approx(carrier, rel=1e-15) and carrier == U_DC / (2 * C18)


def test_near_four_vector_equals_min_max_carrier_on_one_star():
    """Five phases, one star: the zero states shared equally are the min-max zero sequence. (Six phases'
    two stars get one zero sequence each from the carrier, one common one from the dwell times: the same
    period average, other duties.)"""
    rng = np.random.default_rng(5)
    r = rng.uniform(0, 0.8 * FIVE.limits["carrier"] * U_DC, 300)
    a = rng.uniform(-np.pi, np.pi, 300)
    refs = jnp.asarray(np.stack([r * np.cos(a), r * np.sin(a)], 1))
    d1 = np.asarray(duties_of["five", "near-four-vector"](refs, U_DC))
    d2 = np.asarray(duties_of["five", "carrier"](refs, U_DC))
    np.testing.assert_allclose(d1, d2, atol=1e-12)


@EVERY_WINDING
def test_the_carrier_applies_a_second_plane_reference_inside_the_link(w):
    winding = WINDINGS[w]
    carrier = winding.roles["carrier"]
    rng = np.random.default_rng(5)
    r = rng.uniform(0, 0.8 * winding.limits[carrier] * U_DC, 300)
    a = rng.uniform(-np.pi, np.pi, 300)
    second = rng.uniform(-10, 10, (300, 2))
    refs = np.concatenate([np.stack([r * np.cos(a), r * np.sin(a)], 1), second], 1)
    d = np.asarray(duties_of[w, carrier](jnp.asarray(refs), U_DC))
    inside = (d.min(1) > 1e-9) & (d.max(1) < 1 - 1e-9)
    assert inside.sum() > 250
    np.testing.assert_allclose(winding.period_average(d[inside]), refs[inside], atol=1e-9)


@EVERY_WINDING
def test_near_four_vector_applies_a_second_plane_reference_when_its_dwell_times_allow(w):
    winding = WINDINGS[w]
    m = MODULATORS[w, winding.roles["nulling"]]
    rng = np.random.default_rng(2)
    n_ok = 0
    for _ in range(200):
        u = np.r_[rng.uniform(-100, 100, 2), rng.uniform(-5, 5, 2)]
        _, t = m.dwell_times(jnp.asarray(u), U_DC)
        if float(jnp.min(t)) >= 0 and float(jnp.sum(t)) <= 1:
            np.testing.assert_allclose(winding.period_average(m.duties(jnp.asarray(u), U_DC)), u, atol=1e-9)
            n_ok += 1
    assert n_ok > 100  # most small second-plane references are reachable (127 of 200 six, 171 five)


def test_decoupled_svpwm_equals_double_zero_sequence_and_both_apply_z():
    rng = np.random.default_rng(5)
    r = rng.uniform(0, 0.75 / S3 * U_DC, 300)
    a = rng.uniform(-np.pi, np.pi, 300)
    z = rng.uniform(-0.2 / S3 * U_DC, 0.2 / S3 * U_DC, (300, 2))  # |u_ab| + |u_z| inside each hexagon
    refs = np.concatenate([np.stack([r * np.cos(a), r * np.sin(a)], 1), z], 1)
    d1 = np.asarray(duties_of["six", "decoupled"](jnp.asarray(refs), U_DC))
    d2 = np.asarray(duties_of["six", "double-zs"](jnp.asarray(refs), U_DC))
    np.testing.assert_allclose(d1, d2, atol=1e-12)
    np.testing.assert_allclose(SIX.period_average(d1), refs, atol=1e-9)


MACHINES = {"six": six_phase_machine, "five": five_phase_machine}
#: The machine frame each winding's bridges are checked on (both are tested against the others in
#: tests/machines), and its state: 1 A and 5 A on the first two axes, 100 rad/s, 0.4 rad.
BRIDGE_POINT = {
    "six": ("dq", lambda m: m.initial_state((1.0, 5.0), 100.0, 0.4)),
    "five": ("natural", lambda m: m.initial_state_vsd([1.0, 5.0, 0.0, 0.0], 100.0, 0.4)),
}


@EVERY_WINDING
def test_switching_bridge_period_average_equals_the_averaged_bridge(w):
    """Volt-second balance of the segment-exact bridge (2n + 1 segments; more with dead time)."""
    winding = WINDINGS[w]
    frame, initial = BRIDGE_POINT[w]
    machine = MACHINES[w](frame=frame, mechanics="imposed")
    state = initial(machine)
    avg_bridge = MultiPhaseAveragedBridge(U_DC, winding.layout)
    sw_bridge = MultiPhaseSwitchingBridge(U_DC, layout=winding.layout)
    adv = jax.jit(lambda d: sw_bridge.advance(machine, state, d, 0.0, 1e-4, 1))
    adv_avg = jax.jit(lambda d: avg_bridge.advance(machine, state, d, 0.0, 1e-4, 10))
    rng = np.random.default_rng(3)
    for name in winding.pwms:
        for _ in range(4):
            refs = random_references(1, 140.0, rng.integers(1000), 1)  # on a 140 V circle
            d = duties_of[w, name](jnp.asarray(refs), U_DC)[0]
            s_sw, u_sw = adv(d)
            s_avg, u_avg = adv_avg(d)
            np.testing.assert_allclose(u_sw, winding.period_average(d), atol=1e-9)
            np.testing.assert_allclose(u_avg, winding.period_average(d), atol=1e-9)
            # One period of ripple apart, but the same trajectory on average: within the ripple.
            assert float(jnp.max(jnp.abs(s_sw.currents - s_avg.currents))) < 5.0
    times, *_ = sw_bridge.segments(jnp.full(winding.n, 0.5), 1e-4)
    assert times.shape == (2 * winding.n + 2,)  # 2 n edges, 2 n + 1 segments
    with pytest.raises(ParameterError, match=f"shape \\({winding.n},\\)"):
        sw_bridge.advance(machine, state, jnp.zeros(winding.n + 1), 0.0, 1e-4, 1)


#: 20 A in alpha-beta at an angle where every phase carries at least 5 A (six phases: 20 sin 15 deg = 5.2
#: A; five phases: 20 cos 72 deg = 6.2 A), and duties whose few volts cannot change a sign within the
#: period (standstill: no back-EMF).
DEAD_TIME_POINT = {
    "six": (20.0 * np.array([C15, math.sin(math.pi / 12)]), [0.49, 0.51, 0.5, 0.52, 0.48, 0.505]),
    "five": (np.array([20.0, 0.0]), [0.49, 0.51, 0.5, 0.52, 0.48]),
}


@EVERY_WINDING
def test_dead_time_and_device_drop_of_the_n_leg_bridge(w):
    """With constant-sign currents each switching leg loses ``sign(i) U_dc t_d / Ts`` of average pole
    voltage (dead time) and ``sign(i) U_f`` (device drop); the ideal fast path equals the general one."""
    winding = WINDINGS[w]
    machine = MACHINES[w](frame="natural", mechanics="imposed")
    i_ab, duties = DEAD_TIME_POINT[w]
    state = machine.initial_state_vsd([*i_ab, 0.0, 0.0], 0.0, 0.2)
    assert np.all(np.abs(np.asarray(machine.phase_currents(state))) > 5.0)
    Ts, t_d, drop = 1e-4, 2e-6, 1.5
    d = jnp.asarray(duties)
    bridge = lambda **kw: MultiPhaseSwitchingBridge(U_DC, layout=winding.layout, **kw)
    ideal = bridge().advance(machine, state, d, 0.0, Ts, 1)
    general = bridge(device_drop=0.0).advance(machine, state, d, 0.0, Ts, 1)
    np.testing.assert_allclose(general[1], ideal[1], atol=1e-10)
    np.testing.assert_allclose(general[0].currents, ideal[0].currents, atol=1e-12)
    sign = np.sign(np.asarray(machine.phase_currents(state)))
    _, u_dead = bridge(dead_time=t_d).advance(machine, state, d, 0.0, Ts, 1)
    lost = -sign * U_DC * t_d / Ts  # per leg, average pole voltage
    np.testing.assert_allclose(u_dead, winding.period_average(np.asarray(d) + lost / U_DC), atol=1e-9)
    _, u_drop = bridge(device_drop=drop).advance(machine, state, d, 0.0, Ts, 1)
    np.testing.assert_allclose(u_drop, winding.period_average(np.asarray(d) - sign * drop / U_DC), atol=1e-9)


@EVERY_MODULATOR
def test_modulator_gradients_match_finite_differences(key):
    u0 = jnp.asarray([80.0, -40.0, 3.0, -2.0])
    w = jnp.asarray([0.3, -0.2, 0.5, 0.1, -0.4, 0.7][: WINDINGS[key[0]].n])
    f = lambda u: jnp.dot(w, MODULATORS[key].duties(u, U_DC))
    g = np.asarray(jax.grad(f)(u0))
    h = 1e-4
    fd = np.array([(f(u0.at[k].add(h)) - f(u0.at[k].add(-h))) / (2 * h) for k in range(4)])
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-10)
    assert np.all(np.isfinite(jax.grad(f)(jnp.zeros(4))))


def test_modulator_checks():
    with pytest.raises(ParameterError, match="injection"):
        ZeroSequencePWM(injection="third")
    for w, winding in WINDINGS.items():
        with pytest.raises(ParameterError, match="reference"):
            MODULATORS[w, winding.roles["nulling"]].duties(jnp.zeros(3), U_DC)
        assert all(MODULATORS[w, name].n_phases == winding.n for name in winding.pwms), w
    # The classes' default winding is the five-phase one; decoupled SVPWM is six-phase only.
    for cls in (NearFourVectorSVPWM, LargeVectorSVPWM, ZeroSequencePWM):
        assert cls().layout == FIVE_PHASE
    assert DecoupledSVPWM().n_phases == 6


@pytest.mark.slow
def test_two_vector_five_and_seven_harmonics_appear_switching_resolved_and_four_vector_suppresses_them():
    settings = CompareSettings(
        phases=6,
        modulators=("four-vector", "two-vector"),
        bridges=("switching",),
        settle_cycles=1,
        window_cycles=1,
        samples_per_period=16,
        thd_max_carriers=2.0,
    )
    result = compare(settings)
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
