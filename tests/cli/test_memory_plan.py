"""The memory plan: its arithmetic written out independently, the budget's sources, and the commands'
one-line refusals (exit 2, nothing written) before anything compiles. No test runs a big job: the
refusals come from the sizes alone."""

import numpy as np
import pytest

from pmsmjax.cli import main, memory
from pmsmjax.io.logs import log_rows
from pmsmjax.spec.validation import ParameterError


def test_demo_estimate_written_out():
    # 1000 s at 10 kHz, 25 columns, every period recorded: base + inputs + trace rows.
    n, cols = 10_000_000, 25
    expected = memory.BASE_BYTES + memory.DEMO_PERIOD_BYTES * n + memory.DEMO_ROW_BYTES * cols * n
    assert memory.demo_bytes(n, 1, cols) == pytest.approx(expected)
    assert memory.demo_bytes(n, 100, cols) == pytest.approx(
        memory.BASE_BYTES + memory.DEMO_PERIOD_BYTES * n + memory.DEMO_ROW_BYTES * cols * n / 100
    )


def test_demo_decimation_to_fit_is_the_smallest_divisor_that_fits():
    n, cols, budget = 10_000_000, 25, 4e9
    d = memory.demo_decimate_to_fit(n, cols, budget)
    assert n % d == 0 and memory.demo_bytes(n, d, cols) <= budget
    smaller = [k for k in range(1, d) if n % k == 0]
    assert all(memory.demo_bytes(n, k, cols) > budget for k in smaller)
    assert memory.demo_decimate_to_fit(n, cols, memory.BASE_BYTES) is None  # the inputs alone do not fit


def test_montecarlo_estimate_written_out():
    n, p, m, rec, chunk = 1000, 6, 9, 200, 64
    per_run = (
        8 * memory.MC_SAMPLE_COPIES * p + 8 * memory.MC_METRIC_COPIES * m + memory.MC_RECORD_COPIES * 4 * rec
    )
    per_chunk = 2 * (memory.MC_RUN_DEVICE_BYTES + 4 * (rec + m))
    assert memory.montecarlo_bytes(n, p, m, rec, chunk) == pytest.approx(
        memory.BASE_BYTES + n * per_run + chunk * per_chunk
    )
    fit = memory.montecarlo_runs_to_fit(p, m, rec, chunk, 4e9)
    assert (
        memory.montecarlo_bytes(fit, p, m, rec, chunk)
        <= 4e9
        < memory.montecarlo_bytes(fit + 1, p, m, rec, chunk)
    )


def test_log_estimate_and_rows_to_fit():
    for command in ("identify", "replay", "observe"):
        rows = memory.log_rows_to_fit(command, 4e9)
        assert memory.log_fit_bytes(command, rows) <= 4e9 < memory.log_fit_bytes(command, rows + 1)
        assert memory.log_fit_bytes(command, 0) == memory.LOG_BASE_BYTES[command]


def test_budget_sources(monkeypatch):
    monkeypatch.delenv(memory.ENV_VAR, raising=False)
    monkeypatch.setattr(memory, "available_bytes", lambda: 6e9)
    assert memory.budget_bytes() == (3e9, "default")  # half of 6 GB available, under the 4 GB cap
    monkeypatch.setattr(memory, "available_bytes", lambda: 64e9)
    assert memory.budget_bytes() == (4e9, "default")
    monkeypatch.setenv(memory.ENV_VAR, "12")
    assert memory.budget_bytes() == (12e9, memory.ENV_VAR)
    assert memory.budget_bytes(2.5) == (2.5e9, "--max-memory-gb")
    monkeypatch.setenv(memory.ENV_VAR, "lots")
    with pytest.raises(ParameterError, match="PMSMJAX_MAX_MEMORY_GB='lots' is not a positive number"):
        memory.budget_bytes()


def test_log_rows_without_parsing(tmp_path):
    csv = tmp_path / "log.csv"
    csv.write_text("time,u_d\n0,1\n1,2\n2,3")  # no newline at the end
    assert log_rows(csv) == 3
    np.savez(tmp_path / "log.npz", time=np.arange(17.0), u_d=np.zeros(17))
    assert log_rows(tmp_path / "log.npz") == 17
    assert log_rows(tmp_path / "none.csv") is None


def refused(capsys, argv, out):
    """Run ``pmsmjax argv``: exit 2, one line on stderr, nothing written at ``out``; returns the line."""
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert not out.exists()
    return lines[0]


def test_demo_refused_with_the_decimation_that_fits(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv(memory.ENV_VAR, raising=False)
    out = tmp_path / "demo"
    line = refused(capsys, ["demo", "--duration-s", "1000", "--max-memory-gb", "4", "--out", str(out)], out)
    n_cols = 25
    d = memory.demo_decimate_to_fit(10_000_000, n_cols, 4e9)
    assert line.startswith("pmsmjax demo: error: --duration-s 1000 s at 10 kHz is 10,000,000 control periods")
    assert f"needs about {memory.gb(memory.demo_bytes(10_000_000, 1, n_cols))} of memory" in line
    assert f"pass --decimate {d} " in line and "--max-memory-gb" in line


def test_montecarlo_refused_with_the_runs_that_fit(tmp_path, capsys):
    out = tmp_path / "mc"
    argv = ["montecarlo", "--n", "100000000", "--max-memory-gb", "4", "--out", str(out), "--no-progress"]
    line = refused(capsys, argv, out)
    assert line.startswith("pmsmjax montecarlo: error: --n 100,000,000 runs")
    assert "above the budget of 4 GB (--max-memory-gb): give --n " in line


@pytest.mark.parametrize("command", ["identify", "replay"])
def test_long_log_refused_from_its_size(tmp_path, capsys, command):
    log = tmp_path / "log.npz"
    budget_gb = (memory.LOG_BASE_BYTES[command] + 0.2e9) / 1e9  # above what the command needs at any size
    rows = memory.log_rows_to_fit(command, budget_gb * 1e9) + 1
    np.savez(log, time=np.zeros(rows), u_d=np.zeros(1))  # the header's shape is all the plan reads
    out = tmp_path / "out"
    extra = ["--pole-pairs", "4"] if command == "identify" else ["--motor", "book"]
    line = refused(
        capsys, [command, str(log), "--max-memory-gb", str(budget_gb), "--out", str(out), *extra], out
    )
    assert f"the log {log} has {rows:,} rows; {command} needs about" in line
    assert f"give it at most {rows - 1:,} rows" in line


def test_a_budget_below_the_commands_own_need_asks_for_more_not_for_less_work(tmp_path, capsys):
    """Below what any run needs, a shorter run cannot fit: the refusal says so instead of a zero duration."""
    out = tmp_path / "out"
    assert main(["demo", "--max-memory-gb", "0.001", "--out", str(out)]) == 2
    line = capsys.readouterr().err.strip()
    assert "the command itself needs about 0.3 GB" in line and "at most 0 s" not in line
    assert not out.exists()
    with pytest.raises(ParameterError, match="needs about 0.3 GB whatever the size"):
        memory.check_fits(2 * memory.BASE_BYTES, "a run", "give less", 0.001, floor=memory.BASE_BYTES)
