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


# --- Scheduling on pytest-xdist workers (``--dist loadgroup``, pyproject.toml) -------------------------
#: Work units that take much longer than the rest (seconds on 2 quiet cores, cold compilation cache,
#: roughly): scheduled first, heaviest first, so that the last units handed out are the short ones and
#: the workers finish together. A prefix of a node id; anything not listed keeps its collection order.
HEAVY_FIRST = {
    "tests/notebooks/test_notebooks.py::test_notebook_runs[12_commissioning.ipynb]": 70,
    "tests/cli/test_bench_smoke.py": 50,
    "tests/tuning/test_observer_tuning.py::test_gradient_matches_central_differences_and_is_finite": 45,
    "tests/machines/test_flux_map.py": 55,
    "tests/notebooks/test_notebooks.py::test_notebook_runs[08_six_phase.ipynb]": 40,
    "tests/tuning/test_observer_tuning.py": 40,
    "tests/cli/test_drive_file_commands.py": 40,
    "tests/cli/test_multiphase_commands.py": 40,
    "tests/tuning/test_scale.py": 40,
    "tests/inverters/test_switching.py": 35,
    "tests/notebooks/test_notebooks.py": 25,
    "tests/tuning/test_baselines.py": 25,
    "tests/tuning/test_identify.py": 25,
    "tests/tuning/test_hfi_tuning.py": 25,
    "tests/jobs/test_controls.py": 20,
    "tests/controllers/test_dtc.py": 20,
    "tests/cli/test_flux_map_commands.py": 20,
    "tests/tuning/test_identify_starved.py": 20,
}
#: Node-id prefixes whose tests are each a work unit of their own (no module fixtures worth sharing):
#: the notebooks (each runs in its own kernel) and the per-observer gradient checks (each compiles its own
#: program).
ONE_UNIT_EACH = (
    "tests/notebooks/test_notebooks.py::test_notebook_runs[",
    "tests/tuning/test_observer_tuning.py::test_gradient_matches_central_differences_and_is_finite",
)


def _weight(nodeid):
    return max((w for prefix, w in HEAVY_FIRST.items() if nodeid.startswith(prefix)), default=0)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Under ``--dist loadgroup``: a test file is one work unit (its module fixtures are built once, on one
    worker), except the tests of ``ONE_UNIT_EACH``, which are spread over the workers one by one; heavy
    units first (``HEAVY_FIRST``). Runs before xdist's own hook, which reads the ``xdist_group`` marks."""
    if config.getoption("dist", "no") != "loadgroup":
        return
    for item in items:
        if any(item.iter_markers("xdist_group")):
            continue
        nodeid = item.nodeid
        one = any(nodeid.startswith(prefix) for prefix in ONE_UNIT_EACH)
        item.add_marker(pytest.mark.xdist_group(nodeid if one else nodeid.split("::")[0]))
    items.sort(key=lambda item: -_weight(item.nodeid))  # stable: the rest keep their order
