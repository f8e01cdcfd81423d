"""Trace.to_numpy: the same record with NumPy leaves, for post-processing that compiles nothing."""

import jax
import numpy as np

from pmsmjax import presets, simulate


def test_to_numpy_holds_the_same_values_as_numpy_arrays():
    trace = simulate(presets.book_drive(), presets.book_scenario(duration_s=0.01, load_time_s=0.005))
    host = trace.to_numpy()
    leaves, host_leaves = jax.tree.leaves(trace), jax.tree.leaves(host)
    assert len(leaves) == len(host_leaves) > 10
    for a, b in zip(leaves, host_leaves, strict=True):
        assert isinstance(a, jax.Array) and type(b) is np.ndarray
        np.testing.assert_array_equal(np.asarray(a), b)
    assert host.columns().keys() == trace.columns().keys()
