"""Six-phase frames (the book, ch. 7): VSD and its inverse, double dq, and the linear relation between them.

Independent references: the VSD rows written out here from Zhao & Lipo's table (not from the library's
harmonic-order construction), the three-phase Clarke of pmsmjax.frames for a three-phase layout,
harmonic sums evaluated directly, and each set's Clarke/Park written in NumPy.
"""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import ParameterError
from pmsmjax.frames.multiphase import (
    DOUBLE_DQ_TO_VSD,
    SIX_PHASE,
    VSD_TO_DOUBLE_DQ,
    PhaseLayout,
    double_dq,
    double_dq_to_vsd,
    inverse_double_dq,
    inverse_vsd,
    inverse_vsd_matrix,
    vsd,
    vsd_matrix,
    vsd_to_double_dq,
    z_to_counter_rotating,
)
from pmsmjax.frames.three_phase import abc_to_alpha_beta_zero

RNG = np.random.default_rng(7)
S3 = math.sqrt(3.0)


def zhao_lipo_table():
    """The amplitude-invariant VSD of the dual three-phase winding as tabulated (A, B, C, U, V, W)."""
    return (1.0 / 3.0) * np.array(
        [
            [1, -0.5, -0.5, S3 / 2, -S3 / 2, 0],
            [0, S3 / 2, -S3 / 2, 0.5, 0.5, -1],
            [1, -0.5, -0.5, -S3 / 2, S3 / 2, 0],
            [0, -S3 / 2, S3 / 2, 0.5, 0.5, -1],
            [1, 1, 1, 0, 0, 0],
            [0, 0, 0, 1, 1, 1],
        ]
    )


def balanced_sets(x):
    """Remove each star's zero sequence (what isolated neutrals enforce)."""
    x = np.array(x, dtype=float)
    x[..., :3] -= x[..., :3].mean(-1, keepdims=True)
    x[..., 3:] -= x[..., 3:].mean(-1, keepdims=True)
    return x


def test_vsd_matrix_is_the_tabulated_one_and_the_inverse_is_exact():
    np.testing.assert_allclose(vsd_matrix(SIX_PHASE), zhao_lipo_table(), atol=1e-15)
    x = RNG.normal(size=(50, 6))
    np.testing.assert_allclose(inverse_vsd(vsd(x)), x, atol=1e-14)
    np.testing.assert_allclose(vsd(inverse_vsd(x)), x, atol=1e-14)
    np.testing.assert_allclose(inverse_vsd_matrix(SIX_PHASE) @ vsd_matrix(SIX_PHASE), np.eye(6), atol=4e-15)
    # Without zero sequences (isolated stars): four components in, phases with zero star sums out.
    y = inverse_vsd(x[:, :4])
    np.testing.assert_allclose(y[:, :3].sum(1), 0.0, atol=1e-14)
    np.testing.assert_allclose(y[:, 3:].sum(1), 0.0, atol=1e-14)
    np.testing.assert_allclose(vsd(y)[:, :4], x[:, :4], atol=1e-14)


def test_power_invariant_vsd_is_orthogonal_and_three_phase_layout_is_clarke():
    T = vsd_matrix(SIX_PHASE, power_invariant=True)
    np.testing.assert_allclose(T @ T.T, np.eye(6), atol=4e-15)
    three = PhaseLayout((0.0, 2 * math.pi / 3, 4 * math.pi / 3), ((0, 1, 2),), (1,), "three-phase")
    x = RNG.normal(size=(20, 3))
    np.testing.assert_allclose(vsd(x, three), abc_to_alpha_beta_zero(x), atol=1e-14)
    np.testing.assert_allclose(vsd(x, three, True), abc_to_alpha_beta_zero(x, True), atol=1e-14)


def test_amplitude_invariance_and_where_the_harmonics_go():
    g = np.asarray(SIX_PHASE.angles)
    for th in RNG.uniform(-np.pi, np.pi, 5):
        X = RNG.uniform(0.5, 3.0)
        for h, plane in ((1, 0), (5, 2), (7, 2), (11, 0), (13, 0)):
            x = X * np.cos(h * (th - g))  # a balanced h-th harmonic in every phase
            v = np.asarray(vsd(x))
            other = 2 - plane
            assert abs(math.hypot(v[plane], v[plane + 1]) - X) < 1e-12, h
            assert abs(v[other]) + abs(v[other + 1]) < 1e-12, h
            assert abs(v[4]) + abs(v[5]) < 1e-12
    # Triplen harmonics are zero sequences of each star.
    v = np.asarray(vsd(np.cos(3 * (0.4 - g))))
    assert np.allclose(v[:4], 0.0, atol=1e-14) and not np.allclose(v[4:], 0.0)


def numpy_set_dq(x3, theta):
    """Clarke (2/3) then Park of one three-phase set (written out)."""
    a, b, c = x3
    alpha, beta = (2 * a - b - c) / 3, (b - c) / S3
    return np.array(
        [alpha * np.cos(theta) + beta * np.sin(theta), -alpha * np.sin(theta) + beta * np.cos(theta)]
    )


def test_double_dq_against_numpy_and_round_trip():
    for _ in range(10):
        x = balanced_sets(RNG.normal(size=6))
        th = RNG.uniform(-np.pi, np.pi)
        expect = np.concatenate([numpy_set_dq(x[:3], th), numpy_set_dq(x[3:], th - np.pi / 6)])
        np.testing.assert_allclose(double_dq(x, th), expect, atol=1e-14)
        np.testing.assert_allclose(inverse_double_dq(double_dq(x, th), th), x, atol=1e-14)
    # A balanced fundamental in both sets, aligned with the rotor: the same (d, q) in each set.
    g = np.asarray(SIX_PHASE.angles)
    th, i_d, i_q = 0.9, -1.5, 4.0
    x = i_d * np.cos(th - g) - i_q * np.sin(th - g)
    np.testing.assert_allclose(double_dq(x, th), [i_d, i_q, i_d, i_q], atol=1e-14)


def test_linear_relation_between_double_dq_and_vsd_both_ways():
    np.testing.assert_allclose(VSD_TO_DOUBLE_DQ @ DOUBLE_DQ_TO_VSD, np.eye(4), atol=1e-15)
    x = balanced_sets(RNG.normal(size=(40, 6)))
    th = RNG.uniform(-np.pi, np.pi, 40)
    v = np.asarray(vsd(x))
    c, s = np.cos(th), np.sin(th)
    dq = np.stack([v[:, 0] * c + v[:, 1] * s, -v[:, 0] * s + v[:, 1] * c], 1)
    # The z1-z2 vector seen from the frame rotating at -theta: e^{j th} (z1 + j z2), written out.
    zc = np.stack([v[:, 2] * c - v[:, 3] * s, v[:, 2] * s + v[:, 3] * c], 1)
    dd = np.asarray(double_dq(x, th))
    # Forward: the constant matrix M maps double dq onto [dq, z'], at every angle.
    np.testing.assert_allclose(dd @ DOUBLE_DQ_TO_VSD.T, np.concatenate([dq, zc], 1), atol=1e-13)
    np.testing.assert_allclose(z_to_counter_rotating(v[:, 2:4], th), zc, atol=1e-14)
    # Backward, and the library's composed functions (z1-z2 stationary).
    np.testing.assert_allclose(np.concatenate([dq, zc], 1) @ VSD_TO_DOUBLE_DQ.T, dd, atol=1e-13)
    np.testing.assert_allclose(double_dq_to_vsd(dd, th), np.concatenate([dq, v[:, 2:4]], 1), atol=1e-13)
    np.testing.assert_allclose(vsd_to_double_dq(np.concatenate([dq, v[:, 2:4]], 1), th), dd, atol=1e-13)
    # The relation is linear and angle-free: least squares over all samples recovers M exactly.
    M, *_ = np.linalg.lstsq(dd, np.concatenate([dq, zc], 1), rcond=None)
    np.testing.assert_allclose(M.T, DOUBLE_DQ_TO_VSD, atol=1e-12)


def test_bad_layouts_and_shapes_are_refused():
    with pytest.raises(ParameterError, match="planes"):
        vsd_matrix(PhaseLayout((0.0, 1.0, 2.0, 3.0), ((0, 1, 2, 3),), (1, 5), "bad"))
    with pytest.raises(ParameterError, match="not orthogonal"):
        vsd_matrix(PhaseLayout(SIX_PHASE.angles, SIX_PHASE.neutrals, (1, 2), "wrong order"))
    with pytest.raises(ParameterError, match="expected 6 phases"):
        vsd(jnp.zeros(5))
    with pytest.raises(ParameterError, match="6 or 4 components"):
        inverse_vsd(jnp.zeros(3))
