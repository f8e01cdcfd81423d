"""Test configuration: float64 everywhere (accuracy is compared against scipy references), and JAX's
persistent compilation cache, so that a program compiled by one test module (or one pytest-xdist worker)
is loaded from disk by the next instead of compiled again."""

import os
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)

#: Where compiled programs are kept between test modules, workers and runs (``PMSMJAX_TEST_CACHE`` moves
#: it; an empty value turns the cache off). Inside the checkout, ignored by git.
_CACHE = os.environ.get(
    "PMSMJAX_TEST_CACHE", str(Path(__file__).resolve().parents[1] / ".jax_cache" / "tests")
)
# The commands the tests start as subprocesses use the same folder (or none), never the user's cache.
os.environ["PMSMJAX_CACHE_DIR"] = _CACHE or "off"
if _CACHE:
    jax.config.update("jax_compilation_cache_dir", _CACHE)
    # Cache every program: the suite's are many and small, each costing well under a second to compile.
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's in-memory compiled programs after each test module.

    Kept for the whole test run they only grow the process (modules share fixtures within a file, not across
    files); a program needed again is loaded from the persistent cache above rather than compiled.
    """
    yield
    jax.clear_caches()
