"""Carrier-based modulators (pmsmjax.inverters.spwm) against volt-second balance and written-out references.

References here, in NumPy: the period-average phase voltage of leg duties ``u_x = U_dc (d_x - mean d)``
(isolated neutral) and its amplitude-invariant Clarke; the third harmonic from the angle
(``-(|u|/6) cos(3 atan2(u_b, u_a))``); the min-max zero sequence. The linear range of each is shown from
both sides: the average equals the reference to 1e-9 inside, and misses it by a clear margin just outside.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import ParameterError
from pmsmjax.inverters import SVPWM, MinMaxPWM, SinusoidalPWM, ThirdHarmonicPWM, third_harmonic

S3 = np.sqrt(3.0)
MODULATORS = [SinusoidalPWM(), ThirdHarmonicPWM(), MinMaxPWM(), SVPWM()]
# Linear limit as a fraction of U_dc: the book's figures (U_dc/2 and U_dc/sqrt3).
EXPECTED_LIMIT = {"sinusoidal": 0.5, "third_harmonic": 1 / S3, "min_max": 1 / S3, "svpwm": 1 / S3}


def np_clarke(u):
    return np.stack([(2 * u[:, 0] - u[:, 1] - u[:, 2]) / 3.0, (u[:, 1] - u[:, 2]) / S3], axis=1)


def average_voltage(duties, u_dc):
    return np_clarke(u_dc[:, None] * (duties - duties.mean(axis=1, keepdims=True)))


def refs_on_disc(rng, n, radius_of_dc):
    """``n`` references of random angle, |u| = radius_of_dc * U_dc (array or scalar), random U_dc."""
    u_dc = rng.uniform(100.0, 700.0, n)
    ang = rng.uniform(-np.pi, np.pi, n)
    mag = radius_of_dc * u_dc
    return np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1), u_dc


def duties_of(modulator, u_ab, u_dc):
    return np.asarray(jax.jit(jax.vmap(modulator.duties))(jnp.asarray(u_ab), jnp.asarray(u_dc)))


@pytest.mark.parametrize("modulator", MODULATORS, ids=lambda m: m.name)
def test_linear_limit_is_the_books(modulator):
    assert float(modulator.linear_limit(311.0)) == pytest.approx(311.0 * EXPECTED_LIMIT[modulator.name])


@pytest.mark.parametrize("modulator", MODULATORS, ids=lambda m: m.name)
def test_period_average_equals_reference_inside_linear_range(modulator):
    rng = np.random.default_rng(3)
    n = 4000
    radius = np.sqrt(rng.uniform(0.0, 1.0, n)) * EXPECTED_LIMIT[modulator.name]
    radius[:300] = EXPECTED_LIMIT[modulator.name]  # on the limit itself
    u_ab, u_dc = refs_on_disc(rng, n, radius)
    d = duties_of(modulator, u_ab, u_dc)
    assert np.all((d >= 0.0) & (d <= 1.0))
    err = np.linalg.norm(average_voltage(d, u_dc) - u_ab, axis=1) / np.maximum(
        np.linalg.norm(u_ab, axis=1), 1.0
    )
    print(f"\n{modulator.name}: worst relative error inside the linear range {err.max():.1e}")
    assert err.max() < 1e-9


@pytest.mark.parametrize("modulator", MODULATORS, ids=lambda m: m.name)
def test_not_linear_beyond_its_range(modulator):
    # 3 % beyond the limit, on a ring of angles: the worst angle must miss the reference by far more than
    # rounding (sinusoidal PWM saturates near the phase axes, the others near the hexagon's corners).
    ang = np.linspace(-np.pi, np.pi, 721)
    u_dc = np.full(ang.size, 311.0)
    mag = 1.03 * EXPECTED_LIMIT[modulator.name] * 311.0
    u_ab = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
    d = duties_of(modulator, u_ab, u_dc)
    err = np.linalg.norm(average_voltage(d, u_dc) - u_ab, axis=1) / mag
    assert np.all((d >= 0.0) & (d <= 1.0))
    assert err.max() > 5e-3


def test_sinusoidal_duties_are_the_phase_references():
    rng = np.random.default_rng(5)
    u_ab, u_dc = refs_on_disc(rng, 200, 0.4)
    u_abc = np.stack(
        [u_ab[:, 0], -0.5 * u_ab[:, 0] + 0.5 * S3 * u_ab[:, 1], -0.5 * u_ab[:, 0] - 0.5 * S3 * u_ab[:, 1]], 1
    )
    np.testing.assert_allclose(
        duties_of(SinusoidalPWM(), u_ab, u_dc), 0.5 + u_abc / u_dc[:, None], atol=1e-14
    )


def test_third_harmonic_is_a_sixth_of_the_fundamental_at_three_times_its_angle():
    rng = np.random.default_rng(6)
    u_ab, _ = refs_on_disc(rng, 1000, 0.5)
    ref = -np.linalg.norm(u_ab, axis=1) / 6.0 * np.cos(3.0 * np.arctan2(u_ab[:, 1], u_ab[:, 0]))
    got = np.asarray(jax.vmap(third_harmonic)(jnp.asarray(u_ab)))
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * 350)
    # it lowers the phase peak over a rotation to sqrt3/2 of the fundamental (why the range grows 2/sqrt3)
    ang = np.linspace(0, 2 * np.pi, 3601)
    ring = np.stack([np.cos(ang), np.sin(ang)], 1)
    d = duties_of(ThirdHarmonicPWM(), 100.0 * ring, np.full(ang.size, 1000.0))
    assert np.max(np.abs(d - 0.5)) * 1000.0 == pytest.approx(100.0 * S3 / 2, rel=1e-6)


def test_min_max_equals_svpwm_in_the_linear_range():
    rng = np.random.default_rng(8)
    u_ab, u_dc = refs_on_disc(rng, 2000, np.sqrt(rng.uniform(0, 1, 2000)) / S3)
    np.testing.assert_allclose(duties_of(MinMaxPWM(), u_ab, u_dc), duties_of(SVPWM(), u_ab, u_dc), atol=1e-12)


@pytest.mark.parametrize("modulator", MODULATORS[:3], ids=lambda m: m.name)
def test_gradients_are_finite_at_zero_and_match_differences(modulator):
    u_dc = jnp.asarray(311.0)
    jac = jax.jacobian(modulator.duties)(jnp.zeros(2), u_dc)
    assert np.all(np.isfinite(np.asarray(jac)))
    u0 = jnp.asarray([60.0, -25.0])
    jac = np.asarray(jax.jacobian(modulator.duties)(u0, u_dc))
    h = 1e-5
    fd = np.stack(
        [
            (np.asarray(modulator.duties(u0 + h * e, u_dc)) - np.asarray(modulator.duties(u0 - h * e, u_dc)))
            / (2 * h)
            for e in jnp.eye(2)
        ],
        axis=1,
    )
    np.testing.assert_allclose(jac, fd, rtol=1e-7, atol=1e-10)


@pytest.mark.parametrize("modulator", MODULATORS[:3], ids=lambda m: m.name)
def test_reference_must_be_an_alpha_beta_pair(modulator):
    with pytest.raises(ParameterError, match=r"shape \(2,\)"):
        modulator.duties(jnp.zeros(3), 311.0)
