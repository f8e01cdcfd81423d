"""The memory plan of a command: its peak resident memory estimated from the size of the work before
anything compiles, and a one-line refusal (exit 2, nothing written) when that exceeds the budget.

Pure Python (no JAX): the estimates are arithmetic on the sizes a command knows from its flags, its drive
and the header of its log.

**Budget** ([`budget_bytes`][pmsmjax.cli.memory.budget_bytes]): ``--max-memory-gb GB`` if given, else the
environment variable ``PMSMJAX_MAX_MEMORY_GB``, else the lesser of `DEFAULT_CAP_GB` (4 GB) and half the
memory the machine has available now (``MemAvailable`` of /proc/meminfo, else free pages from
``os.sysconf``). 1 GB here is 10^9 bytes.

**Estimates** (bytes, each ``BASE_BYTES`` plus terms linear in the work; the coefficients were measured
with ``python -m benchmarks.memory_plan``, which prints estimate against measured peak RSS, and are meant
to hold to within a factor of 1.5 either way above a few hundred MB):

- `demo_bytes`: ``DEMO_PERIOD_BYTES`` per control period (the scenario's inputs sampled on the period
  grid, held for the whole run) plus ``DEMO_ROW_BYTES`` per trace column and recorded row (the device
  record, the NumPy trace, the column table written to the file and the figures' copies);
- `montecarlo_bytes`: per run, the samples (``MC_SAMPLE_COPIES`` float64 copies per parameter: unit
  samples, values, the stacked table, ranks), the metrics (``MC_METRIC_COPIES`` float64 copies each:
  results, sorted copies, ranks) and the decimated record (``MC_RECORD_COPIES`` copies: results, the
  percentiles of the fan chart), all held for the whole study, plus one chunk in flight;
- `log_fit_bytes`: ``LOG_ROW_BYTES[command]`` per log row (the log's columns, the resampled grid, the
  fit's residuals and Jacobian blocks over every sample for ``identify``; the replayed states for
  ``replay``).
"""

import os

from pmsmjax.spec.validation import ParameterError

__all__ = [
    "DEFAULT_CAP_GB",
    "ENV_VAR",
    "add_memory_flag",
    "available_bytes",
    "budget_bytes",
    "check_fits",
    "demo_bytes",
    "montecarlo_bytes",
    "log_fit_bytes",
    "gb",
]

#: Default cap of the budget, GB (10^9 bytes).
DEFAULT_CAP_GB = 4.0
#: Environment variable that sets the budget when ``--max-memory-gb`` is not given, GB.
ENV_VAR = "PMSMJAX_MAX_MEMORY_GB"
#: Resident memory of a command before its work: Python, NumPy, JAX and XLA's compiled programs, bytes.
BASE_BYTES = 300e6
#: demo: bytes per control period (sampled scenario inputs and their scan operands).
DEMO_PERIOD_BYTES = 90.0
#: demo: bytes per recorded row and trace column.
DEMO_ROW_BYTES = 32.0
#: montecarlo: float64 copies held per run and sampled parameter, per metric, and record copies.
MC_SAMPLE_COPIES = 5
MC_METRIC_COPIES = 4
MC_RECORD_COPIES = 3
#: montecarlo: device bytes of one run in a chunk (the scan carry and its temporaries), besides its record.
MC_RUN_DEVICE_BYTES = 4096
#: Bytes per log row held at the peak, and the resident memory besides, by command (observe: not
#: measured, taken as twice replay's).
LOG_ROW_BYTES = {"identify": 2100.0, "replay": 300.0, "observe": 600.0}
LOG_BASE_BYTES = {"identify": 600e6, "replay": 250e6, "observe": 300e6}


def gb(n_bytes: float) -> str:
    """``n_bytes`` as GB text with two significant digits at least (``'7.1 GB'``, ``'0.35 GB'``)."""
    value = n_bytes / 1e9
    return f"{value:.2g} GB" if value < 10 else f"{value:.0f} GB"


def add_memory_flag(p) -> None:
    """Add ``--max-memory-gb`` to the subcommand parser `p`."""
    from pmsmjax.cli import checks

    p.add_argument(
        "--max-memory-gb",
        type=checks.positive("GB"),
        default=None,
        help=f"memory budget, GB: a run whose estimated peak exceeds it is refused before any work "
        f"(default: ${ENV_VAR}, else the lesser of {DEFAULT_CAP_GB:g} GB and half the available memory)",
    )


def available_bytes() -> int | None:
    """Memory the machine can give without swapping, bytes: ``MemAvailable`` of /proc/meminfo, else
    available pages times the page size, else None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def budget_bytes(max_memory_gb: float | None = None) -> tuple[float, str]:
    """The memory budget, bytes, and where it came from (for messages).

    Args:
        max_memory_gb: ``--max-memory-gb``, GB, or None.

    Returns:
        ``(bytes, source)``; source is ``"--max-memory-gb"``, the environment variable's name, or
        ``"default"``.

    Raises:
        ParameterError: for an environment variable that is not a positive number.
    """
    if max_memory_gb is not None:
        return float(max_memory_gb) * 1e9, "--max-memory-gb"
    text = os.environ.get(ENV_VAR)
    if text:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not value > 0 or value == float("inf"):
            raise ParameterError(f"{ENV_VAR}={text!r} is not a positive number of GB: set e.g. {ENV_VAR}=8.")
        return value * 1e9, ENV_VAR
    cap = DEFAULT_CAP_GB * 1e9
    free = available_bytes()
    return (cap if free is None else min(cap, 0.5 * free)), "default"


def check_fits(
    need: float, what: str, fix: str, max_memory_gb: float | None = None, floor: float = 0.0
) -> None:
    """Refuse work whose estimated peak memory `need` (bytes) exceeds the budget, in one line.

    Args:
        need: estimated peak resident memory, bytes.
        what: the work, e.g. ``"--duration-s 1000 s at 10 kHz: 10,000,000 periods"``.
        fix: what to change, e.g. ``"pass --decimate 100 (about 1.6 GB)"``.
        max_memory_gb: ``--max-memory-gb``, GB, or None for the default budget.
        floor: what the command needs whatever the size of its work, bytes: a budget below it can only be
            raised (a smaller run would not fit either).

    Raises:
        ParameterError: ``"<what> needs about X GB of memory (estimate), above the budget of Y GB
            (<source>): <fix>, or raise --max-memory-gb if the machine has the memory."``
    """
    budget, source = budget_bytes(max_memory_gb)
    if need <= budget:
        return
    origin = {
        "default": f"the lesser of {DEFAULT_CAP_GB:g} GB and half the available memory",
        "--max-memory-gb": "--max-memory-gb",
    }.get(source, source)
    if budget < floor:
        fix = f"the command itself needs about {gb(floor)} whatever the size of the work"
    raise ParameterError(
        f"{what} needs about {gb(need)} of memory (estimate), above the budget of {gb(budget)} "
        f"({origin}): {fix}, or raise --max-memory-gb if the machine has the memory."
    )


def demo_bytes(n_periods: int, decimate: int, n_columns: int) -> float:
    """Estimated peak memory of ``pmsmjax demo``, bytes.

    Args:
        n_periods: control periods of the run (duration over the control period).
        decimate: ``--decimate``: one recorded row per this many periods.
        n_columns: columns of the trace.
    """
    rows = n_periods // max(int(decimate), 1)
    return BASE_BYTES + DEMO_PERIOD_BYTES * n_periods + DEMO_ROW_BYTES * n_columns * rows


def demo_decimate_to_fit(n_periods: int, n_columns: int, budget: float) -> int | None:
    """The smallest decimation dividing `n_periods` whose `demo_bytes` fit `budget` (bytes), or None."""
    for d in _divisors(n_periods):
        if demo_bytes(n_periods, d, n_columns) <= budget:
            return d
    return None


def _divisors(n: int) -> list[int]:
    small = [d for d in range(1, int(n**0.5) + 1) if n % d == 0]
    return sorted(set(small + [n // d for d in small]))


def montecarlo_bytes(
    n_runs: int, n_params: int, n_metrics: int, n_record: int, chunk: int, itemsize: int = 4
) -> float:
    """Estimated peak memory of ``pmsmjax montecarlo``, bytes.

    Args:
        n_runs: runs of the study.
        n_params: sampled parameters.
        n_metrics: metric columns per run.
        n_record: recorded values per run (signals times decimated periods).
        chunk: runs per chunk (one chunk in flight on the device and one being written).
        itemsize: bytes of the simulation's floats (4: float32).
    """
    samples = 8 * MC_SAMPLE_COPIES * n_params
    per_run = samples + 8 * MC_METRIC_COPIES * n_metrics + MC_RECORD_COPIES * itemsize * n_record
    per_chunk_run = 2 * (MC_RUN_DEVICE_BYTES + itemsize * (n_record + n_metrics))
    return BASE_BYTES + per_run * n_runs + per_chunk_run * chunk


def montecarlo_runs_to_fit(n_params: int, n_metrics: int, n_record: int, chunk: int, budget: float) -> int:
    """The most runs whose `montecarlo_bytes` fit `budget` (bytes); 0 if none does."""
    one = montecarlo_bytes(1, n_params, n_metrics, n_record, chunk) - montecarlo_bytes(
        0, n_params, n_metrics, n_record, chunk
    )
    return max(int((budget - montecarlo_bytes(0, n_params, n_metrics, n_record, chunk)) // one), 0)


def log_fit_bytes(command: str, n_rows: int) -> float:
    """Estimated peak memory of ``identify``, ``replay`` or ``observe`` on a log of `n_rows` rows, bytes."""
    return LOG_BASE_BYTES[command] + LOG_ROW_BYTES[command] * n_rows


def log_rows_to_fit(command: str, budget: float) -> int:
    """The most log rows whose `log_fit_bytes` fit `budget` (bytes)."""
    return max(int((budget - LOG_BASE_BYTES[command]) // LOG_ROW_BYTES[command]), 0)


def check_log(command: str, path, max_memory_gb: float | None = None) -> int | None:
    """Refuse a log too long for `command` within the budget, from its size alone (nothing is parsed).

    Args:
        command: ``"identify"``, ``"replay"`` or ``"observe"``.
        path: the log file.
        max_memory_gb: ``--max-memory-gb``, GB, or None.

    Returns:
        The log's row count (an upper bound for a CSV file), or None when it cannot be told.

    Raises:
        ParameterError: when `log_fit_bytes` exceeds the budget, naming the rows, the estimate and the
            most rows that fit.
    """
    from pmsmjax.io.logs import log_rows

    n_rows = log_rows(path)
    if n_rows is None:
        return None
    budget, _ = budget_bytes(max_memory_gb)
    fit = log_rows_to_fit(command, budget)
    check_fits(
        log_fit_bytes(command, n_rows),
        f"the log {path} has {n_rows:,} rows; {command}",
        f"give it at most {fit:,} rows (cut the log to the part that matters, or decimate it: keep every "
        f"{-(-n_rows // max(fit, 1)):,}th row)",
        max_memory_gb,
        floor=LOG_BASE_BYTES[command],
    )
    return n_rows
