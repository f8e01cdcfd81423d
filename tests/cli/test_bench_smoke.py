"""Smoke test of the core benchmark, run as the script it is (``python -m benchmarks.bench_core --quick
--json FILE`` from the repository root), and of the library timing behind it and ``pmsmjax bench``
(pmsmjax/jobs/bench.py).

It checks that every figure is present, positive and finite, that the library and the hand-written
minimal loop it is timed against simulate the same trajectory, that forward- and reverse-mode gradients
agree, and that the report is written whole. Timings are never asserted (timed tests are forbidden;
quick-size timings mean nothing).
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from pmsmjax.jobs.bench import REQUIRED_KEYS, mode_crossover

ROOT = Path(__file__).resolve().parents[2]
#: The comparison with the minimal loop that the benchmark adds to the library's figures.
MINIMAL_KEYS = (
    "minimal_loop_literal_ms",
    "minimal_loop_runtime_params_ms",
    "ratio_vs_minimal_literal",
    "ratio_vs_minimal_runtime_params",
    "max_speed_diff_rpm_literal",
    "max_speed_diff_rpm_runtime_params",
)
# Largest speed difference (r/min) allowed between the library and the minimal loop: both run the same
# float32 arithmetic in a different order, so they agree to rounding (about 1e-4 r/min is observed).
SPEED_AGREEMENT_RPM = 1e-2


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """The script's stdout, the folder it wrote into, and the figures it wrote."""
    out = tmp_path_factory.mktemp("bench")
    path = out / "bench.json"
    command = [sys.executable, "-m", "benchmarks.bench_core", "--quick", "--json", str(path)]
    r = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stdout, out, json.loads(path.read_text())


@pytest.fixture(scope="module")
def results(bench) -> dict:
    return bench[2]


def _is_positive_finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


@pytest.mark.slow
def test_every_required_key_is_reported(results):
    missing = [key for key in (*REQUIRED_KEYS, *MINIMAL_KEYS) if key not in results]
    assert not missing


def test_figures_are_positive_and_finite(results):
    scalars = [
        k
        for k in (*REQUIRED_KEYS, *MINIMAL_KEYS)
        if k not in ("forward_vs_reverse", "machine", "mode_crossover_n_params")
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
    # Run as a script the benchmark keeps JAX's default precision, and says so.
    assert results["dtype"] == "float32"


def test_mode_crossover_is_last_count_where_forward_mode_wins():
    row = lambda n, fwd, rev: {"n_params": n, "forward_s": fwd, "reverse_s": rev}
    assert mode_crossover([row(1, 1.0, 3.0), row(4, 2.0, 3.0), row(8, 4.0, 3.0)]) == 4
    assert mode_crossover([row(8, 4.0, 3.0), row(1, 1.0, 3.0)]) == 1  # order of rows does not matter
    assert mode_crossover([row(1, 4.0, 3.0), row(2, 1.0, 3.0)]) == 0  # reverse already wins at n = 1
    assert mode_crossover([row(1, 1.0, 3.0), row(13, 2.0, 3.0)]) == 13  # not bracketed


def test_the_table_is_printed_and_only_the_json_is_written(bench):
    stdout, out, _ = bench
    assert "library / minimal" in stdout and "compile time" in stdout
    assert stdout.rstrip().endswith(f"wrote {out / 'bench.json'}")
    assert [p.name for p in out.iterdir()] == ["bench.json"]  # no temporary left


def test_pmsmjax_bench_prints_and_writes_the_library_figures(results, tmp_path, monkeypatch, capsys):
    """``pmsmjax bench`` reports what :func:`pmsmjax.jobs.bench.run` measures (here the
    script's own figures without the minimal loop, so the command's compiles are not paid twice)."""
    from pmsmjax.cli import main
    from pmsmjax.jobs import bench as engine_timing

    library = {k: v for k, v in results.items() if k not in MINIMAL_KEYS}
    monkeypatch.setattr(engine_timing, "run", lambda quick=False: library)
    path = tmp_path / "bench.json"
    assert main(["bench", "--quick", "--json", str(path)]) == 0
    assert json.loads(path.read_text()) == library
    out = capsys.readouterr().out
    assert "single run (simulate)" in out and "minimal" not in out
    assert [p.name for p in tmp_path.iterdir()] == ["bench.json"]


def test_the_report_lists_every_mode_row_and_its_crossover(results):
    """[`pmsmjax.jobs.bench_report.format_table`]: one line per row of each forward/reverse table, each
    ratio the quotient of its times, and the crossover the mode table's own."""
    from pmsmjax.jobs.bench_report import format_table

    table = format_table(results)
    rows = results["forward_vs_reverse"]
    for r in rows:
        assert f"{r['n_params']:>10}{r['forward_s']:>10.4f}{r['reverse_s']:>10.4f}" in table
        assert f"{r['forward_s'] / r['reverse_s']:>10.2f}" in table
    n = results["mode_crossover_n_params"]
    assert (f"up to n = {n} parameters" in table) or (f"every measured n (<= {n})" in table)
