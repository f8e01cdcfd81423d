"""The engine's scan in blocks of periods (pmsmjax.simulate.scan_in_blocks) against a plain step loop, the
block lengths it picks against XLA:CPU's 512-byte sequential-execution limit, and a simulation whose
period count has no divisor (one flat scan) against one run in blocks."""

import jax.numpy as jnp
import numpy as np
import pytest

import pmsmjax
from pmsmjax import presets
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import SEQUENTIAL_BUFFER_BYTES, block_length, scan_in_blocks
from pmsmjax.units import rpm_to_rad_s


def counting_filter_step(carry, x):
    """A first-order filter that also counts its steps: pytree carry and outputs; a dropped, repeated or
    reordered step shows in the count and in the filter's output."""
    k, z = carry
    z = 0.95 * z + x
    return (k + 1, z), {"k": k, "pair": jnp.stack([z, x])}


@pytest.mark.parametrize("n", [4000, 97, 12])
def test_blocks_give_the_step_loop_results(n):
    xs = jnp.asarray(np.random.default_rng(0).uniform(size=n))
    (k_end, z_end), ys = scan_in_blocks(counting_filter_step, (0, 0.3), xs, bytes_per_step=16)
    z, zs = 0.3, []
    for x in np.asarray(xs):  # the same filter, one step at a time in NumPy
        z = 0.95 * z + x
        zs.append(z)
    np.testing.assert_array_equal(np.asarray(ys["k"]), np.arange(n))
    np.testing.assert_allclose(np.asarray(ys["pair"][:, 0]), zs, rtol=1e-13)
    np.testing.assert_array_equal(np.asarray(ys["pair"][:, 1]), np.asarray(xs))
    assert int(k_end) == n and float(z_end) == pytest.approx(zs[-1], rel=1e-13)


@pytest.mark.parametrize(
    "n, bytes_per_step, expected",
    [
        (4000, 44, 10),  # the sensored record row, float32: 11 elements
        (4000, 52, 8),  # with the estimate: 13 elements (10 rows would be 520 bytes)
        (4000, 104, 4),  # the same in float64
        (4001, 44, 1),  # a prime period count: one flat scan
        (12, 4, 12),  # the whole scan fits
        (4000, 800, 1),  # a row over the limit
    ],
)
def test_block_length_is_the_largest_divisor_within_the_limit(n, bytes_per_step, expected):
    b = block_length(n, bytes_per_step)
    assert b == expected
    assert n % b == 0 and (b == 1 or b * bytes_per_step <= SEQUENTIAL_BUFFER_BYTES)


def test_flat_and_blocked_simulations_agree():
    drive = presets.book_drive()
    w = rpm_to_rad_s(1000.0)
    # 4001 periods (prime: one flat scan) and the first 4000 of them (blocks of 10 or 4 periods).
    long = Scenario(4001 * drive.Ts, Profile.step(0.0, 0.0, w), Profile.step(0.2, 0.0, 10.0))
    short = Scenario(4000 * drive.Ts, Profile.step(0.0, 0.0, w), Profile.step(0.2, 0.0, 10.0))
    flat, blocked = pmsmjax.simulate(drive, long), pmsmjax.simulate(drive, short)
    for name in ("omega_m", "i_dq", "duties", "u_dq_ref", "theta_e_est"):
        np.testing.assert_array_equal(
            np.asarray(getattr(flat, name))[:4000], np.asarray(getattr(blocked, name))
        )
