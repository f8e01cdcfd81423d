"""How many runs go into one chunk (one compiled call, one file on disk) when the study says ``"auto"``.

The rule ([`auto_chunk_size`][tuning.montecarlo.chunking.auto_chunk_size]), per device, then times the device
count::

    runs per device = min( floor(MEMORY_FRACTION * free bytes / bytes per run),   # what fits
                           target[platform] )                                      # what still pays
    target = THROUGHPUT_CAP, raised for short runs on a CPU to
             min(ceil(MIN_RUN_PERIODS / periods per run), MAX_RUNS)

rounded down to at least two runs per device
([`tuning.montecarlo.runner.chunk_layout`][tuning.montecarlo.runner.chunk_layout] then balances the chunks
over the study's ``n`` runs).

- **free bytes**: ``bytes_limit - bytes_in_use`` from ``device.memory_stats()`` (GPU, TPU), the smallest
  over this process's devices; on the CPU, which reports no memory statistics, the host's available RAM
  (``MemAvailable`` of /proc/meminfo, else ``sysconf``) shared by its CPU devices. With several processes
  (``jax.distributed``) every process takes the smallest of all processes' values, so they agree.
- **bytes per run** ([`bytes_per_run`][tuning.montecarlo.chunking.bytes_per_run]): an upper bound of what one
  run holds on the device, from shapes alone (nothing is traced or run): the parameter row, the metrics and
  the decimated record it returns, ``TEMP_FACTOR`` times the drive's scan carry (RK4 stages, the
  controller's intermediates, double-buffered carries) and, when the study varies a scenario parameter,
  the scenario's per-period inputs (``N`` values each: XLA materialises them per run then). On the book
  study (float32, 4000 periods) that is 1.9 kB per run against 1.3 kB in XLA's memory analysis of the
  compiled chunk function, and 66 kB against 17.5 kB with the speed step varied; tests/tuning/test_scale.py
  checks the bound against that analysis.
- **MEMORY_FRACTION** = 0.5: the other half is headroom for XLA's workspace, the input and output
  buffers of the next chunk (chunks are dispatched one ahead) and whatever else shares the device.
- **THROUGHPUT_CAP**: beyond some batch a device is saturated and a larger chunk only costs memory, a
  coarser resume and less overlap of file writing with computing. CPU: 1024 runs per device
  (``benchmarks/bench_montecarlo.py --sweep``: 2048 runs on 2 CPU devices were the fastest of 256-8192);
  GPU and TPU: 262,144 runs per device, the largest batch measured (one H100: 703 M periods/s,
  against 292 M at 65,536); larger batches are unmeasured, so not assumed to pay.
- **Short runs on a CPU** (``MIN_RUN_PERIODS``, ``MAX_RUNS``): every chunk costs the host about 1.5 ms
  (dispatch, fetch, file), and on a CPU the host shares the cores with the computation; a chunk of 2048
  runs of 20 periods computes in 3 ms. So a CPU chunk carries at least 2^18 run-periods per device, up to
  16,384 runs per device (a million 20-period runs on 2 CPU devices, measured: whole call 3.3 s with chunks
  of 2048, 2.4-2.6 s with 8k-32k, kernel throughput flat from 1k to 16k runs per device and down by a
  half at 60k, by cache misses). Runs of 256 periods or more keep the throughput cap.

An explicit ``chunk_size`` (study TOML or ``--chunk-size``) overrides the rule.
"""

import os

import jax
import numpy as np

#: Share of the free device memory a chunk may use.
MEMORY_FRACTION = 0.5
#: Multiple of the scan carry's bytes counted for a run's temporaries (see the module docstring).
TEMP_FACTOR = 16
#: Runs per device beyond which throughput was not measured to improve, by platform.
THROUGHPUT_CAP = {"cpu": 1024, "gpu": 262_144, "tpu": 262_144}
#: Least run-periods per device and chunk (short runs), and the most runs per device then, by platform.
MIN_RUN_PERIODS = {"cpu": 2**18}
MAX_RUNS = {"cpu": 16_384}
#: Free memory assumed when neither the device nor the operating system says (bytes).
FALLBACK_FREE_BYTES = 4 * 2**30


def tree_bytes(tree) -> int:
    """Bytes of every array leaf of ``tree`` (arrays or ``jax.ShapeDtypeStruct``)."""
    leaves = jax.tree.leaves(tree)
    return int(sum(np.prod(x.shape, dtype=np.int64) * np.dtype(x.dtype).itemsize for x in leaves))


def host_available_bytes() -> int:
    """RAM the host can give without swapping: ``MemAvailable`` (Linux), else free pages, else
    `FALLBACK_FREE_BYTES`."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024  # kB
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return FALLBACK_FREE_BYTES


def device_free_bytes(devices) -> int:
    """Free memory of the fullest of ``devices`` (this process's), bytes; CPU devices share the host's
    available RAM equally."""
    free = []
    for d in devices:
        stats = d.memory_stats() if hasattr(d, "memory_stats") else None
        if stats and "bytes_limit" in stats:
            free.append(int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0)))
    if free:
        return min(free)
    return host_available_bytes() // max(len(devices), 1)


def _agree_min(x: int) -> int:
    """The smallest ``x`` bytes over every process (identity with one process), to the MiB below.

    Gathered in MiB as int32: without x64, JAX would narrow an int64 byte count (20 GB of RAM
    wrapped round to a negative number, seen on two CPU processes)."""
    if jax.process_count() == 1:
        return x
    from jax.experimental import multihost_utils

    mib = np.asarray(min(x // 2**20, np.iinfo(np.int32).max), np.int32)
    return int(np.min(multihost_utils.process_allgather(mib))) * 2**20


def auto_chunk_size(
    n_runs: int,
    n_devices: int,
    per_run_bytes: int,
    *,
    n_periods: int | None = None,
    free_bytes: int | None = None,
    platform: str | None = None,
) -> tuple[int, dict]:
    """Runs per chunk by the module's rule, and how it was reached (for summary.json).

    **Arguments:** `n_runs`: the study's runs; `n_devices`: devices in the mesh (all processes);
    `per_run_bytes`: [`bytes_per_run`][tuning.montecarlo.chunking.bytes_per_run]; `n_periods`: periods per run
    (None: no short-run rule); `free_bytes` (per device) and `platform` (``"cpu"``, ``"gpu"``, ...) default to
    what this process's devices report.

    **Returns:** ``(runs per chunk, {"rule", "platform", "per_run_bytes", "free_bytes_per_device",
    "limited_by"})``; ``limited_by`` is ``"memory"``, ``"throughput"`` or ``"runs"`` (the study is smaller).
    """
    local = jax.local_devices()
    platform = local[0].platform if platform is None else platform
    if free_bytes is None:
        free_bytes = _agree_min(device_free_bytes(local))
    by_memory = int(MEMORY_FRACTION * free_bytes) // max(int(per_run_bytes), 1)
    cap = THROUGHPUT_CAP.get(platform, THROUGHPUT_CAP["gpu"])
    if n_periods and platform in MIN_RUN_PERIODS:
        cap = max(cap, min(-(-MIN_RUN_PERIODS[platform] // n_periods), MAX_RUNS[platform]))
    per_device = max(min(by_memory, cap), 2)
    size = per_device * n_devices
    limited_by = "memory" if by_memory < cap else "throughput"
    if size >= n_runs:
        size, limited_by = n_runs, "runs"
    detail = {
        "rule": "auto",
        "platform": platform,
        "per_run_bytes": int(per_run_bytes),
        "free_bytes_per_device": int(free_bytes),
        "limited_by": limited_by,
    }
    return size, detail


def bytes_per_run(outputs, n_params: int, dtype, carry, period_inputs) -> int:
    """Upper bound of the device bytes of one run (see the module docstring).

    **Arguments:** `outputs`: one run's outputs (arrays or shape structs); `n_params`: P, the sampled
    parameters; `dtype`: their dtype; `carry`: a pytree of the scan carry (``drive.init()``, arrays or
    shape structs);
    `period_inputs`: the per-run scenario inputs over every period (arrays or shape structs).
    """
    row = jax.ShapeDtypeStruct((n_params,), dtype)
    return tree_bytes(row) + tree_bytes(outputs) + tree_bytes(period_inputs) + TEMP_FACTOR * tree_bytes(carry)


__all__ = [
    "auto_chunk_size",
    "bytes_per_run",
    "device_free_bytes",
    "host_available_bytes",
    "MEMORY_FRACTION",
    "TEMP_FACTOR",
    "THROUGHPUT_CAP",
    "MIN_RUN_PERIODS",
    "MAX_RUNS",
]
