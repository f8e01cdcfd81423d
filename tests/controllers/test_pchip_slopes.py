"""PCHIP node slopes of the flux-map reference tables against SciPy's ``PchipInterpolator`` (an independent
implementation): the same slopes on random, monotone, flat-segment and two-point data."""

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from pmsmjax.controllers.flux_map_references import pchip_slopes


def _cases():
    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(3, 25))
        x = np.cumsum(rng.uniform(0.01, 2.0, n))
        if trial % 3 == 0:
            y = np.cumsum(rng.uniform(-0.2, 1.0, n))  # mostly monotone, with turns
        else:
            y = rng.normal(size=n)
        if trial % 5 == 0:
            k = int(rng.integers(1, n))
            y[k] = y[k - 1]  # a flat segment: zero slope at both its ends
        yield x, y


def test_slopes_match_scipy_pchip():
    for x, y in _cases():
        expected = PchipInterpolator(x, y).derivative()(x)
        # SciPy evaluates the last node on the last cubic, one rounding away from the formula.
        np.testing.assert_allclose(
            pchip_slopes(x, y), expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max()
        )


def test_interior_slopes_are_scipys_to_the_bit():
    for x, y in _cases():
        expected = PchipInterpolator(x, y).derivative()(x)
        assert np.array_equal(pchip_slopes(x, y)[:-1], expected[:-1])


def test_two_points_give_the_secant_and_extrema_give_zero():
    np.testing.assert_array_equal(pchip_slopes([0.0, 2.0], [1.0, 5.0]), [2.0, 2.0])
    d = pchip_slopes([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 0.0, 1.0])
    assert d[1] == 0.0 and d[2] == 0.0


@pytest.mark.parametrize("y", [[0.0, 1.0, 4.0, 9.0, 16.0], [3.0, 2.0, 2.0, 1.0, -5.0]])
def test_monotone_data_keep_monotone_slopes(y):
    d = pchip_slopes(np.arange(5.0), y)
    sign = np.sign(np.diff(y)).max() if np.diff(y).max() > 0 else -1.0
    assert np.all(sign * d >= 0.0)
