"""Current ripple (pmsmjax/analysis/current_ripple.py) against the analytic ripple of a sampled sine on an
offset: a moving mean over whole periods removes the offset exactly and leaves the sine, whose RMS over
whole periods is its amplitude over sqrt 2; pmsmjax.metrics serves the same functions."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import metrics
from pmsmjax.analysis import current_ripple

PERIOD = 51  # samples; the window spans three whole periods and is odd (exact centring)
WINDOW = 3 * PERIOD


@pytest.mark.parametrize("as_array", [np.asarray, jnp.asarray], ids=["numpy", "jax"])
def test_rms_of_a_sine_about_its_moving_mean(as_array):
    n = np.arange(20 * PERIOD)
    i = as_array(2.0 + 3.0 * np.sin(2 * np.pi * n / PERIOD))
    rms = float(current_ripple.current_ripple_rms_a(i, WINDOW))
    # the deviations cover the samples a centred window reaches: N - W + 1 of them, 17 periods and one
    kept = n[(WINDOW - 1) // 2 : (WINDOW - 1) // 2 + n.size - WINDOW + 1]
    assert rms == pytest.approx(math.sqrt(np.mean((3.0 * np.sin(2 * np.pi * kept / PERIOD)) ** 2)), rel=1e-9)
    assert rms == pytest.approx(3.0 / math.sqrt(2.0), rel=2e-3)  # whole periods but one sample
    peak_to_peak = float(current_ripple.current_ripple_peak_to_peak_a(i, WINDOW))
    samples = 3.0 * np.sin(2 * np.pi * np.arange(PERIOD) / PERIOD)
    assert peak_to_peak == pytest.approx(samples.max() - samples.min(), rel=1e-9)


def test_metrics_serves_the_same_functions():
    for name in ("current_ripple_rms_a", "current_error_rms_a", "reference_phase_currents"):
        assert getattr(metrics, name) is getattr(current_ripple, name)


def test_the_figures_follow_their_inputs_array_library():
    """[`pmsmjax.analysis.array_namespace.namespace`]: NumPy in, NumPy out (no program compiled); JAX in,
    or traced, JAX out."""
    import jax

    from pmsmjax.analysis.array_namespace import namespace

    assert namespace(np.ones(3), 2) is np
    assert namespace(np.ones(3), jnp.ones(3)) is jnp
    assert jax.jit(lambda x: jnp.asarray(namespace(x) is jnp))(jnp.ones(3))
    assert isinstance(current_ripple.current_ripple_rms_a(np.sin(np.arange(300.0)), 101), np.floating)
