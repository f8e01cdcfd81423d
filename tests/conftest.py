"""Test configuration: float64 everywhere (accuracy is compared against scipy references)."""

import jax
import pytest

jax.config.update("jax_enable_x64", True)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test module.

    The suite compiles several hundred closed-loop programs; kept for the whole session they only grow
    the process (modules share fixtures within a file, not across files), and one full run on a loaded
    2-core machine ended in a segmentation fault inside XLA's compiler late in the session.
    """
    yield
    jax.clear_caches()
