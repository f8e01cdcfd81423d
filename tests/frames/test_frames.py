"""Clarke/Park transforms (pmsmjax.frames) against hand-written matrices and physical invariants.

References are NumPy matrices written from docs/book_reference.md's conventions, not the library's formulas:
amplitude-invariant Clarke ``2/3 [[1, -1/2, -1/2], [0, sqrt3/2, -sqrt3/2], [1/2, 1/2, 1/2]]``, its
power-invariant (orthogonal) counterpart, and Park ``d = a cos th + b sin th``, ``q = -a sin th + b cos th``.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import frames

S3 = np.sqrt(3.0)
# Amplitude-invariant Clarke with zero sequence (a+b+c)/3.
C_AMP = (2.0 / 3.0) * np.array([[1.0, -0.5, -0.5], [0.0, S3 / 2, -S3 / 2], [0.5, 0.5, 0.5]])
# Power-invariant Clarke: orthonormal rows.
C_POW = np.sqrt(2.0 / 3.0) * np.array(
    [[1.0, -0.5, -0.5], [0.0, S3 / 2, -S3 / 2], [1 / np.sqrt(2), 1 / np.sqrt(2), 1 / np.sqrt(2)]]
)
PHASES = np.array([0.0, -2 * np.pi / 3, 2 * np.pi / 3])  # a, b, c lag by 0, 120, 240 deg


def np_park(x_ab, th):
    c, s = np.cos(th), np.sin(th)
    return np.stack([x_ab[..., 0] * c + x_ab[..., 1] * s, -x_ab[..., 0] * s + x_ab[..., 1] * c], -1)


@pytest.fixture(scope="module")
def rng():
    return np.random.default_rng(20240611)


def test_power_invariant_matrix_is_orthogonal():
    # Sanity of the reference itself: rows orthonormal, and C_POW = diag(sqrt(3/2), sqrt(3/2), sqrt3) C_AMP.
    np.testing.assert_allclose(C_POW @ C_POW.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(np.diag([np.sqrt(1.5), np.sqrt(1.5), S3]) @ C_AMP, C_POW, atol=1e-15)


@pytest.mark.parametrize("power_invariant", [False, True])
def test_clarke_matches_reference_matrix(rng, power_invariant):
    x = rng.normal(scale=100.0, size=(500, 3))  # generic: nonzero zero sequence
    ref = x @ (C_POW if power_invariant else C_AMP).T
    got = np.asarray(frames.abc_to_alpha_beta_zero(x, power_invariant))
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * 100)
    np.testing.assert_allclose(
        np.asarray(frames.abc_to_alpha_beta(x, power_invariant)), ref[:, :2], rtol=0, atol=1e-12 * 100
    )
    # Inverse Clarke against the inverse matrix, with and without the zero sequence.
    inv = np.linalg.inv(C_POW if power_invariant else C_AMP)
    y = rng.normal(scale=100.0, size=(500, 3))
    np.testing.assert_allclose(
        np.asarray(frames.alpha_beta_to_abc(y, power_invariant)), y @ inv.T, rtol=0, atol=1e-12 * 100
    )
    y0 = y.copy()
    y0[:, 2] = 0.0
    np.testing.assert_allclose(
        np.asarray(frames.alpha_beta_to_abc(y[:, :2], power_invariant)), y0 @ inv.T, rtol=0, atol=1e-12 * 100
    )


@pytest.mark.parametrize("power_invariant", [False, True])
def test_clarke_round_trip_exact(rng, power_invariant):
    x = rng.normal(scale=50.0, size=(2000, 3)) + rng.normal(scale=50.0, size=(2000, 1))  # big zero seq
    back = frames.alpha_beta_to_abc(frames.abc_to_alpha_beta_zero(x, power_invariant), power_invariant)
    err = np.max(np.abs(np.asarray(back) - x))
    assert err < 1e-12 * np.max(np.abs(x)), err
    y = rng.normal(scale=50.0, size=(2000, 3))
    fwd = frames.abc_to_alpha_beta_zero(frames.alpha_beta_to_abc(y, power_invariant), power_invariant)
    assert np.max(np.abs(np.asarray(fwd) - y)) < 1e-12 * np.max(np.abs(y))


def test_amplitude_invariance_of_balanced_set(rng):
    # a balanced set of amplitude A: x_k = A cos(wt + phi - 2 pi k/3), zero-sequence free.
    A = rng.uniform(0.1, 400.0, size=300)
    ang = rng.uniform(-10.0, 10.0, size=300)
    x = A[:, None] * np.cos(ang[:, None] + PHASES[None, :])
    ab = np.asarray(frames.abc_to_alpha_beta(x))
    np.testing.assert_allclose(np.hypot(ab[:, 0], ab[:, 1]), A, rtol=1e-13)
    # and the vector points at the phase angle (alpha along phase A)
    np.testing.assert_allclose(ab[:, 0], A * np.cos(ang), rtol=0, atol=1e-12 * 400)
    np.testing.assert_allclose(ab[:, 1], A * np.sin(ang), rtol=0, atol=1e-12 * 400)
    # power-invariant: magnitude sqrt(3/2) A
    abp = np.asarray(frames.abc_to_alpha_beta(x, power_invariant=True))
    np.testing.assert_allclose(np.hypot(abp[:, 0], abp[:, 1]), np.sqrt(1.5) * A, rtol=1e-13)


def test_instantaneous_power(rng):
    u = rng.normal(scale=100.0, size=(1000, 3))
    i = rng.normal(scale=10.0, size=(1000, 3))
    p_abc = np.sum(u * i, axis=1)
    scale = 1e-12 * np.max(np.abs(p_abc))
    # amplitude-invariant: p = 1.5 (u_a i_a + u_b i_b) + 3 u_0 i_0
    ua, ia = np.asarray(frames.abc_to_alpha_beta_zero(u)), np.asarray(frames.abc_to_alpha_beta_zero(i))
    p_amp = 1.5 * np.sum(ua[:, :2] * ia[:, :2], axis=1) + 3.0 * ua[:, 2] * ia[:, 2]
    np.testing.assert_allclose(p_amp, p_abc, rtol=0, atol=scale)
    # power-invariant: p = u_a i_a + u_b i_b + u_0 i_0
    up = np.asarray(frames.abc_to_alpha_beta_zero(u, power_invariant=True))
    ip = np.asarray(frames.abc_to_alpha_beta_zero(i, power_invariant=True))
    np.testing.assert_allclose(np.sum(up * ip, axis=1), p_abc, rtol=0, atol=scale)
    # balanced (zero-sequence free) sets: the alpha-beta part carries all the power
    ub, ib = u - u.mean(1, keepdims=True), i - i.mean(1, keepdims=True)
    pb = np.sum(ub * ib, axis=1)
    p_ab = 1.5 * np.sum(
        np.asarray(frames.abc_to_alpha_beta(ub)) * np.asarray(frames.abc_to_alpha_beta(ib)), 1
    )
    np.testing.assert_allclose(p_ab, pb, rtol=0, atol=scale)
    p_ab_pow = np.sum(
        np.asarray(frames.abc_to_alpha_beta(ub, True)) * np.asarray(frames.abc_to_alpha_beta(ib, True)), 1
    )
    np.testing.assert_allclose(p_ab_pow, pb, rtol=0, atol=scale)


def test_park_matches_reference_and_inverts(rng):
    x = rng.normal(scale=30.0, size=(1000, 2))
    th = rng.uniform(-50.0, 50.0, size=1000)  # unwrapped angles too
    dq = np.asarray(frames.park(x, th))
    np.testing.assert_allclose(dq, np_park(x, th), rtol=0, atol=1e-12 * 30)
    np.testing.assert_allclose(np.linalg.norm(dq, axis=1), np.linalg.norm(x, axis=1), rtol=1e-13)
    np.testing.assert_allclose(np.asarray(frames.inverse_park(dq, th)), x, rtol=0, atol=1e-12 * 30)
    np.testing.assert_allclose(
        np.asarray(frames.park(frames.inverse_park(x, th), th)), x, rtol=0, atol=1e-12 * 30
    )
    # rotation(theta) rotates by +theta, so inverse Park is rotation(theta) @ dq
    R = np.asarray(frames.rotation(th))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, dq), x, rtol=0, atol=1e-12 * 30)


def test_park_of_rotating_vector_is_constant():
    # x_ab = A [cos(w t + g), sin(w t + g)] seen at its own angle w t gives constant [A cos g, A sin g].
    A, g, w = 7.3, 0.4, 418.9
    t = np.linspace(0.0, 0.1, 2001)
    x = A * np.stack([np.cos(w * t + g), np.sin(w * t + g)], -1)
    dq = np.asarray(frames.park(x, w * t))
    np.testing.assert_allclose(dq, np.broadcast_to([A * np.cos(g), A * np.sin(g)], dq.shape), atol=1e-12 * A)
    # a rotating abc set through abc_to_dq: the magnet flux psi_f cos(th - phi_x) lands on +d
    psi_abc = 0.1827 * np.cos(w * t[:, None] + PHASES[None, :])
    np.testing.assert_allclose(
        np.asarray(frames.abc_to_dq(psi_abc, w * t)),
        np.broadcast_to([0.1827, 0.0], (t.size, 2)),
        atol=1e-14,
    )
    # sanity: the same vector at a different angle is not constant (the check can fail)
    wrong = np.asarray(frames.park(x, 0.5 * w * t))
    assert np.ptp(wrong[:, 0]) > A


@pytest.mark.parametrize("power_invariant", [False, True])
def test_dq_abc_round_trip(rng, power_invariant):
    i_dq = rng.normal(scale=10.0, size=(1000, 2))
    th = rng.uniform(-20.0, 20.0, size=1000)
    abc = np.asarray(frames.dq_to_abc(i_dq, th, power_invariant))
    np.testing.assert_allclose(abc.sum(1), 0.0, atol=1e-12 * 10)  # no zero sequence
    np.testing.assert_allclose(np.asarray(frames.abc_to_dq(abc, th, power_invariant)), i_dq, atol=1e-12 * 10)
    # against the reference: abc = C^-1 [R(th) dq, 0]
    C = C_POW if power_invariant else C_AMP
    ab = np.stack(
        [
            i_dq[:, 0] * np.cos(th) - i_dq[:, 1] * np.sin(th),
            i_dq[:, 0] * np.sin(th) + i_dq[:, 1] * np.cos(th),
        ],
        1,
    )
    ref = np.concatenate([ab, np.zeros((1000, 1))], 1) @ np.linalg.inv(C).T
    np.testing.assert_allclose(abc, ref, atol=1e-12 * 10)
    # amplitude-invariant: phase peak equals |i_dq|
    if not power_invariant:
        amp = np.linalg.norm(i_dq, axis=1)
        phase_a = np.asarray(frames.dq_to_abc(i_dq, -np.arctan2(i_dq[:, 1], i_dq[:, 0])))[:, 0]
        np.testing.assert_allclose(phase_a, amp, rtol=1e-12)
    # abc_to_dq ignores a zero-sequence component
    abc0 = abc + rng.normal(size=(1000, 1))
    np.testing.assert_allclose(np.asarray(frames.abc_to_dq(abc0, th, power_invariant)), i_dq, atol=1e-12 * 10)


def test_wrap_angle(rng):
    th = np.concatenate(
        [rng.uniform(-1e3, 1e3, 5000), np.arange(-20, 21) * np.pi, [0.0, np.pi, -np.pi, 3 * np.pi - 1e-9]]
    )
    w = np.asarray(frames.wrap_angle(th))
    assert np.all(w >= -np.pi) and np.all(w < np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(th), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(th), atol=1e-12)
    # the difference is a whole number of turns
    turns = (th - w) / (2 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-12 * 1e3)
    # angles already inside [-pi, pi) are returned unchanged
    inside = rng.uniform(-np.pi, np.pi, 1000)
    np.testing.assert_allclose(np.asarray(frames.wrap_angle(inside)), inside, rtol=0, atol=1e-15)
    # derivative 1 (the jump is a constant)
    g = jax.vmap(jax.grad(frames.wrap_angle))(jnp.asarray(th))
    np.testing.assert_array_equal(np.asarray(g), 1.0)
