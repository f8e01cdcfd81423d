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


# --- Scheduling on pytest-xdist workers (``--dist loadfile --no-loadscope-reorder``, pyproject.toml) ----
#: Test files that take much longer than the rest (seconds on 2 quiet cores, cold compilation cache,
#: roughly): handed out first, heaviest first, so that the last files handed out are short ones and the
#: workers finish together. Any other file keeps its collection order. (xdist's own reorder sorts files
#: by their number of tests, which put the long files of a few tests last.)
HEAVY_FIRST = {
    "tests/notebooks/test_notebooks_commissioning.py": 60,
    "tests/notebooks/test_notebooks_multiphase.py": 70,
    "tests/notebooks/test_notebooks_controls.py": 75,
    "tests/notebooks/test_notebooks.py": 65,
    "tests/tuning/test_observer_tuning.py": 150,
    "tests/cli/test_bench_smoke.py": 50,
    "tests/cli/test_multiphase_commands.py": 50,
    "tests/tuning/test_scale.py": 45,
    "tests/cli/test_drive_file_commands.py": 40,
    "tests/inverters/test_switching.py": 35,
    "tests/machines/test_flux_map.py": 30,
    "tests/tuning/test_baselines.py": 30,
    "tests/tuning/test_identify.py": 25,
    "tests/tuning/test_hfi_tuning.py": 25,
    "tests/jobs/test_controls.py": 20,
    "tests/controllers/test_dtc.py": 20,
    "tests/cli/test_flux_map_commands.py": 20,
    "tests/tuning/test_identify_starved.py": 20,
}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """On an xdist worker (the order it collects in is the order the files are handed out): the files of
    ``HEAVY_FIRST`` first, heaviest first; a file's tests stay together and in their order."""
    if not hasattr(config, "workerinput"):
        return
    items.sort(key=lambda item: -HEAVY_FIRST.get(item.nodeid.split("::")[0], 0))  # stable
