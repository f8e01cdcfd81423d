"""Smoke test of the core benchmark (benchmarks/bench_core.py) at its quick sizes.

It checks that every figure is present, positive and finite, that the library and the hand-written
minimal loop it is timed against simulate the same trajectory, and that the report is written
atomically. Timings are never asserted (timed tests are forbidden; quick-size timings mean nothing).
"""

import json
import math

import pytest

from benchmarks import bench_core
from benchmarks.bench_core import REQUIRED_KEYS, mode_crossover, run

# Largest speed difference (r/min) allowed between the library and the minimal loop: both run the same
# float32 arithmetic in a different order, so they agree to rounding (about 1e-4 r/min is observed).
SPEED_AGREEMENT_RPM = 1e-2


@pytest.fixture(scope="module")
def results() -> dict:
    return run(quick=True)


def _is_positive_finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def test_every_required_key_is_reported(results):
    missing = [key for key in REQUIRED_KEYS if key not in results]
    assert not missing


def test_figures_are_positive_and_finite(results):
    scalars = [
        k for k in REQUIRED_KEYS if k not in ("forward_vs_reverse", "machine", "mode_crossover_n_params")
    ]
    bad = {k: results[k] for k in scalars if not _is_positive_finite(results[k])}
    assert not bad
    crossover = results["mode_crossover_n_params"]
    assert isinstance(crossover, int) and crossover >= 0


def test_mode_comparison_rows_are_complete(results):
    rows = results["forward_vs_reverse"]
    assert rows
    for row in rows:
        assert isinstance(row["n_params"], int) and row["n_params"] >= 1
        for key in ("forward_s", "reverse_s", "forward_compile_s", "reverse_compile_s"):
            assert math.isfinite(row[key]) and row[key] >= 0, (key, row)
        assert row["forward_s"] > 0 and row["reverse_s"] > 0


def test_rates_match_times(results):
    n = results["n_periods"]
    assert results["periods_per_s_single"] == pytest.approx(n / (1e-3 * results["library_ms"]))
    assert results["ratio_vs_minimal_literal"] == pytest.approx(
        results["library_ms"] / results["minimal_loop_literal_ms"]
    )
    assert results["grad_over_forward_ratio"] == pytest.approx(
        results["grad_batch64_s"] / results["forward_batch64_s"]
    )


def test_library_and_minimal_loop_simulate_the_same_trajectory(results):
    # The scenario must actually move the motor, or agreement would be trivial.
    assert results["peak_speed_rpm"] > 500.0
    assert results["max_speed_diff_rpm_literal"] < SPEED_AGREEMENT_RPM
    assert results["max_speed_diff_rpm_runtime_params"] < SPEED_AGREEMENT_RPM


def test_forward_and_reverse_mode_gradients_agree(results):
    assert results["grad_all_finite"]
    for row in results["forward_vs_reverse"]:
        assert row["grad_rel_diff"] < 1e-3, row


def test_machine_is_described(results):
    machine = results["machine"]
    assert machine["cpu_count"] >= 1
    for key in ("cpu", "jax", "backend", "device"):
        assert isinstance(machine[key], str) and machine[key], key
    # The suite runs in float64 (conftest); the benchmark reports the precision it ran in.
    assert results["dtype"] == "float64"


def test_mode_crossover_is_last_count_where_forward_mode_wins():
    row = lambda n, fwd, rev: {"n_params": n, "forward_s": fwd, "reverse_s": rev}
    assert mode_crossover([row(1, 1.0, 3.0), row(4, 2.0, 3.0), row(8, 4.0, 3.0)]) == 4
    assert mode_crossover([row(8, 4.0, 3.0), row(1, 1.0, 3.0)]) == 1  # order of rows does not matter
    assert mode_crossover([row(1, 4.0, 3.0), row(2, 1.0, 3.0)]) == 0  # reverse already wins at n = 1
    assert mode_crossover([row(1, 1.0, 3.0), row(13, 2.0, 3.0)]) == 13  # not bracketed


def test_main_writes_the_results_as_json(results, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(bench_core, "run", lambda quick=False: results)
    path = tmp_path / "bench.json"
    bench_core.main(str(path), quick=True)
    assert json.loads(path.read_text()) == results
    assert "library / minimal" in capsys.readouterr().out
    assert [p.name for p in tmp_path.iterdir()] == ["bench.json"]


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "bench.json"
    path.write_text('{"old": 1}')
    with pytest.raises(TypeError):
        bench_core.write_json_atomic(str(path), {"not serialisable": object()})
    assert path.read_text() == '{"old": 1}'
    assert [p.name for p in tmp_path.iterdir()] == ["bench.json"]
