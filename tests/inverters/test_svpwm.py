"""The book's SVPWM (pmsmjax.inverters.svpwm) against volt-second balance and an independent min-max PWM.

References written here in NumPy: the amplitude-invariant Clarke of the period-average phase voltages,
the 7-segment switching sequence rebuilt from the comparison times, the hexagon boundary
``r(delta) = (U_dc/sqrt3) / cos(delta - 30 deg)``, and the carrier-based zero-sequence (min-max)
injection ``d_x = 1/2 + (u_x + u_0)/U_dc``, ``u_0 = -(max + min)/2``, which is equivalent to SVPWM in the
linear range.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.inverters import SVPWM, phase_voltages, sector_code, switching_times

S3 = np.sqrt(3.0)
TS = 1e-4
SECTOR_CODES = [3, 1, 5, 4, 6, 2]  # book: sectors I..VI, sector I = 0..60 deg

duties_batch = jax.jit(jax.vmap(SVPWM().duties))
times_batch = jax.jit(jax.vmap(switching_times, in_axes=(0, 0, None)))
codes_batch = jax.jit(jax.vmap(sector_code))
phase_voltages_batch = jax.jit(jax.vmap(phase_voltages))


def np_inverse_clarke(u_ab):
    a, b = u_ab[..., 0], u_ab[..., 1]
    return np.stack([a, -0.5 * a + 0.5 * S3 * b, -0.5 * a - 0.5 * S3 * b], axis=-1)


def np_clarke(u_abc):
    a, b, c = u_abc[..., 0], u_abc[..., 1], u_abc[..., 2]
    return np.stack([(2.0 * a - b - c) / 3.0, (b - c) / S3], axis=-1)


def average_voltage(duties, u_dc):
    """Period-average stator-frame voltage of a star machine with isolated neutral, from leg duties."""
    v = u_dc[:, None] * (duties - duties.mean(axis=1, keepdims=True))
    return np_clarke(v)


def min_max_duties(u_ab, u_dc):
    u = np_inverse_clarke(u_ab)
    u0 = -0.5 * (u.max(axis=1) + u.min(axis=1))
    return 0.5 + (u + u0[:, None]) / u_dc[:, None]


def hexagon_radius(angle, u_dc):
    delta = np.mod(angle, np.pi / 3)
    return (u_dc / S3) / np.cos(delta - np.pi / 6)


def random_refs(rng, n, radius_factor):
    """``n`` references with random angle and |u| = radius_factor * U_dc/sqrt3 (array or scalar)."""
    u_dc = rng.uniform(100.0, 700.0, n)
    ang = rng.uniform(-np.pi, np.pi, n)
    mag = radius_factor * u_dc / S3
    return np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1), u_dc, ang


@pytest.fixture(scope="module")
def linear_refs():
    rng = np.random.default_rng(2024)
    n = 5000
    # uniform over the inscribed disc, plus 200 exactly on the circle
    radius = np.sqrt(rng.uniform(0.0, 1.0, n))
    radius[:200] = 1.0
    u_ab, u_dc, ang = random_refs(rng, n, radius)
    # references on sector boundaries (the sector test switches formula there)
    edge = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [0.5, S3 / 2], [-0.5, -S3 / 2]])
    u_ab = np.concatenate([u_ab, 150.0 * edge])
    u_dc = np.concatenate([u_dc, np.full(len(edge), 311.0)])
    return u_ab, u_dc


def test_linear_range_reproduces_reference(linear_refs):
    u_ab, u_dc = linear_refs
    d = np.asarray(duties_batch(jnp.asarray(u_ab), jnp.asarray(u_dc)))
    err = np.linalg.norm(average_voltage(d, u_dc) - u_ab, axis=1) / (u_dc / S3)
    print(f"\nworst relative error of the period average: {err.max():.2e}")
    assert err.max() < 1e-9
    # the library's averaged-bridge formula gives the same phase voltages as the NumPy one
    v_lib = np.asarray(phase_voltages_batch(jnp.asarray(d), jnp.asarray(u_dc)))
    v_np = u_dc[:, None] * (d - d.mean(axis=1, keepdims=True))
    np.testing.assert_allclose(v_lib, v_np, rtol=0, atol=1e-12 * 700)
    assert np.max(np.abs(np_clarke(v_lib) - u_ab) / (u_dc / S3)[:, None]) < 1e-9
    np.testing.assert_allclose(v_lib.sum(axis=1), 0.0, atol=1e-12 * 700)


def test_equals_min_max_zero_sequence_injection(linear_refs):
    u_ab, u_dc = linear_refs
    d = np.asarray(duties_batch(jnp.asarray(u_ab), jnp.asarray(u_dc)))
    ref = min_max_duties(u_ab, u_dc)
    print(f"\nworst duty difference to min-max PWM: {np.abs(d - ref).max():.2e}")
    np.testing.assert_allclose(d, ref, rtol=0, atol=1e-12)


def test_sector_codes_follow_the_book():
    rng = np.random.default_rng(1)
    for k, code in enumerate(SECTOR_CODES):
        ang = np.deg2rad(60.0 * k + rng.uniform(1e-6, 60.0 - 1e-6, 500))
        mag = rng.uniform(1e-3, 500.0, 500)
        u = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
        np.testing.assert_array_equal(np.asarray(codes_batch(jnp.asarray(u))), code)
    assert int(sector_code(jnp.zeros(2))) == 0


def switching_state_vector(s, u_dc):
    """Stator-frame voltage vector ``(2,)`` of a switching state ``s = (s_a, s_b, s_c)`` in {0, 1}."""
    return np_clarke(u_dc * np.asarray(s, float))


def test_seven_segment_sequence_volt_seconds():
    # Rebuild the 0-x-y-7-y-x-0 sequence from the comparison times: leg x is high for t in
    # [T_cm_x, Ts - T_cm_x]. Every segment switches one leg, the active vectors are the two that bound
    # the reference's sector, and their volt-seconds equal Ts * u_ref.
    rng = np.random.default_rng(7)
    u_ab, u_dc, ang = random_refs(rng, 600, np.sqrt(rng.uniform(0.01, 1.0, 600)))
    T_cm, T1, T2 = (np.asarray(x) for x in times_batch(jnp.asarray(u_ab), jnp.asarray(u_dc), TS))
    for j in range(len(u_ab)):
        edges = np.sort(np.concatenate([[0.0, TS], T_cm[j], TS - T_cm[j]]))
        mids = 0.5 * (edges[1:] + edges[:-1])
        states = (T_cm[j][None, :] <= mids[:, None]) & (mids[:, None] < TS - T_cm[j][None, :])
        durations = np.diff(edges)
        np.testing.assert_array_equal(states.sum(axis=1), [0, 1, 2, 3, 2, 1, 0])
        assert np.all(np.abs(np.diff(states.astype(int), axis=0)).sum(axis=1) == 1)  # one leg per edge
        one, two = states[1], states[2]
        np.testing.assert_allclose(durations[1] + durations[5], T1[j], rtol=0, atol=1e-12 * TS)
        np.testing.assert_allclose(durations[2] + durations[4], T2[j], rtol=0, atol=1e-12 * TS)
        v1, v2 = switching_state_vector(one, u_dc[j]), switching_state_vector(two, u_dc[j])
        np.testing.assert_allclose(np.linalg.norm(v1), 2.0 / 3.0 * u_dc[j], rtol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(v2), 2.0 / 3.0 * u_dc[j], rtol=1e-14)
        # the two active vectors bound the sector holding the reference
        k = np.floor(np.mod(ang[j], 2 * np.pi) / (np.pi / 3))
        bounds = {round(np.mod(k, 6)), round(np.mod(k + 1, 6))}
        got = {round(np.mod(np.arctan2(v[1], v[0]), 2 * np.pi) / (np.pi / 3)) % 6 for v in (v1, v2)}
        assert got == bounds
        volt_seconds = T1[j] * v1 + T2[j] * v2
        np.testing.assert_allclose(volt_seconds, TS * u_ab[j], rtol=0, atol=1e-9 * TS * u_dc[j])


def test_overmodulation_keeps_direction_and_clips_to_hexagon():
    rng = np.random.default_rng(3)
    n = 4000
    u_dc = rng.uniform(100.0, 700.0, n)
    ang = rng.uniform(-np.pi, np.pi, n)
    mag = hexagon_radius(ang, u_dc) * rng.uniform(1.0001, 3.0, n)  # beyond the hexagon
    u_ab = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
    d = np.asarray(duties_batch(jnp.asarray(u_ab), jnp.asarray(u_dc)))
    assert np.all(d >= 0.0) and np.all(d <= 1.0)
    avg = average_voltage(d, u_dc)
    ang_err = np.abs(np.angle(np.exp(1j * (np.arctan2(avg[:, 1], avg[:, 0]) - ang))))
    mag_err = np.abs(np.linalg.norm(avg, axis=1) / hexagon_radius(ang, u_dc) - 1.0)
    print(f"\nover-modulation: worst angle error {ang_err.max():.2e} rad, magnitude {mag_err.max():.2e}")
    assert ang_err.max() < 1e-9
    assert mag_err.max() < 1e-9
    _, T1, T2 = (np.asarray(x) for x in times_batch(jnp.asarray(u_ab), jnp.asarray(u_dc), TS))
    np.testing.assert_allclose(T1 + T2, TS, rtol=1e-12)
    # between the inscribed circle and the hexagon nothing is scaled: the reference is reproduced
    lim = u_dc / S3
    mag_in = lim + rng.uniform(0.0, 0.9999, n) * (hexagon_radius(ang, u_dc) - lim)
    u_in = np.stack([mag_in * np.cos(ang), mag_in * np.sin(ang)], axis=1)
    d_in = np.asarray(duties_batch(jnp.asarray(u_in), jnp.asarray(u_dc)))
    assert np.max(np.abs(average_voltage(d_in, u_dc) - u_in) / lim[:, None]) < 1e-9


def test_linear_limit():
    assert SVPWM().linear_limit(311.0) == pytest.approx(311.0 / S3, rel=1e-15)
    ang = np.linspace(-np.pi, np.pi, 3601)
    u_dc = np.full(ang.size, 311.0)
    lim = 311.0 / S3
    inside = 0.999 * lim * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    _, T1, T2 = (np.asarray(x) for x in times_batch(jnp.asarray(inside), jnp.asarray(u_dc), TS))
    assert np.all(T1 + T2 <= TS)
    assert np.all(T1 >= -1e-15 * TS) and np.all(T2 >= -1e-15 * TS)
    d = np.asarray(duties_batch(jnp.asarray(inside), jnp.asarray(u_dc)))
    np.testing.assert_allclose(average_voltage(d, u_dc), inside, rtol=0, atol=1e-9 * lim)
    # just outside the circle, 30 deg into each sector (where the hexagon touches the circle)
    ang30 = np.deg2rad(30.0 + 60.0 * np.arange(6))
    outside = 1.001 * lim * np.stack([np.cos(ang30), np.sin(ang30)], axis=1)
    _, T1, T2 = (np.asarray(x) for x in times_batch(jnp.asarray(outside), jnp.asarray(u_dc[:6]), TS))
    np.testing.assert_allclose(T1 + T2, TS, rtol=1e-12)  # scaled down to the period
    d = np.asarray(duties_batch(jnp.asarray(outside), jnp.asarray(u_dc[:6])))
    np.testing.assert_allclose(np.linalg.norm(average_voltage(d, u_dc[:6]), axis=1), lim, rtol=1e-12)


def test_duties_in_unit_interval_and_zero_reference():
    rng = np.random.default_rng(9)
    u_ab, u_dc, _ = random_refs(rng, 5000, rng.uniform(0.0, 5.0, 5000))
    d = np.asarray(duties_batch(jnp.asarray(u_ab), jnp.asarray(u_dc)))
    assert np.all(d >= 0.0) and np.all(d <= 1.0)
    assert d.min() == pytest.approx(0.0, abs=1e-12) and d.max() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_array_equal(np.asarray(SVPWM().duties(jnp.zeros(2), 311.0)), 0.5)


def test_gradient_finite_at_zero_and_matches_finite_differences():
    duties = SVPWM().duties
    u_dc = 311.0
    for jac in (jax.jacfwd, jax.jacrev):
        g0 = np.asarray(jac(duties)(jnp.zeros(2), u_dc))
        assert np.all(np.isfinite(g0)), g0
    jac = jax.jit(jax.vmap(jax.jacrev(duties), in_axes=(0, None)))
    rng = np.random.default_rng(4)
    n = 300
    ang = rng.uniform(-np.pi, np.pi, n)
    # keep 1 deg away from the sector boundaries, where the duties have kinks
    ang = np.where(np.abs(np.mod(ang, np.pi / 3) - np.pi / 6) > np.pi / 6 - np.deg2rad(1.0), ang + 0.05, ang)
    # linear range (|u| < 179.6 V at 311 V), then over-modulated
    mag = np.concatenate([rng.uniform(20.0, 170.0, n // 2), rng.uniform(200.0, 400.0, n - n // 2)])
    u = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
    g = np.asarray(jac(jnp.asarray(u), u_dc))
    h = 1e-3
    fd = np.empty_like(g)
    for i in range(2):
        e = np.zeros(2)
        e[i] = h
        plus = np.asarray(duties_batch(jnp.asarray(u + e), jnp.full(n, u_dc)))
        minus = np.asarray(duties_batch(jnp.asarray(u - e), jnp.full(n, u_dc)))
        fd[:, :, i] = (plus - minus) / (2 * h)
    print(f"\nworst gradient error: {np.abs(g - fd).max():.2e} (gradient scale {np.abs(g).max():.2e})")
    np.testing.assert_allclose(g, fd, rtol=0, atol=1e-8)
    # in the linear range it is also the gradient of min-max PWM, written out by hand:
    # d d_x/du_ab = (M_x - (M_max + M_min)/2)/U_dc with M the inverse-Clarke rows
    M = np.array([[1.0, 0.0], [-0.5, S3 / 2], [-0.5, -S3 / 2]])
    lin = u[: n // 2]
    u_abc = lin @ M.T
    i_max, i_min = u_abc.argmax(axis=1), u_abc.argmin(axis=1)
    g_mm = (M[None, :, :] - 0.5 * (M[i_max] + M[i_min])[:, None, :]) / u_dc
    np.testing.assert_allclose(g[: n // 2], g_mm, rtol=0, atol=1e-13)
