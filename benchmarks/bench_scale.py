"""Scale: Monte Carlo studies and a tuning iteration, kernel time against the whole call, in one table.

Usage (from the repository root)::

    python -m benchmarks.bench_scale                       # CPU sizes: table + bench_scale.json
    python -m benchmarks.bench_scale --n-short 1000000     # a million short runs (host overhead)
    python -m benchmarks.bench_scale --n-book 1000000 --n-short 0 --tune-scenarios 0   # on a GPU

Rows, each on the devices JAX lists (on CPU the cores are split into devices first, as ``pmsmjax
montecarlo`` does; ``--devices`` overrides, ``XLA_FLAGS`` set by you wins):

1. ``montecarlo book``: ``run_study`` on the default study (the book drive and scenario, 1000 r/min step,
   10 N m load step at 0.2 s, 0.4 s = 4000 periods, 10 RK4 sub-steps, the default tolerances, chunk size
   ``"auto"``), ``--n-book`` runs (default 10,000), no sensitivities, no figures.
2. ``montecarlo short``: the same drive on a 2 ms scenario (20 periods, load step at 1 ms), ``--n-short``
   runs (default 200,000): the kernel is cheap, so the host's share (sampling, chunk files, summary,
   Spearman ranks) shows.
3. ``tune iteration``: [`tuning.autotune.tuner.tune`][tuning.autotune.tuner.tune] (BFGS, the 7 PI gains, book
   drive with one RK4 sub-step as ``pmsmjax tune`` runs it) on ``--tune-scenarios`` speed-step scenarios
   (default 1,024) of 20-30 ms, ``--tune-iterations`` iterations, with a progress bar (to stderr) and a
   checkpoint every 5 iterations as the command has.

``--unroll-substeps`` runs the Monte Carlo rows with the RK4 sub-steps written out
([`pmsmjax.inverters.averaged.AveragedBridge`][pmsmjax.inverters.averaged.AveragedBridge]), for comparing the
two program forms on a device.

Columns:

- **kernel**: Monte Carlo: the compiled chunk function alone, summed over the chunks (inputs already on
  the device, results left there); tuning: one cost-and-gradient evaluation of the batch (median of 7).
- **whole call**: Monte Carlo: ``run_study`` wall time, *cold* (first call for the study: compile
  included) and *warm* (the same study again into a new folder: compiled function reused; the median of
  ``--repeats`` calls, each followed by a kernel timing, the kernel column being their median); tuning:
  the median wall time per iteration inside ``tune`` (compile excluded).
- **host**: tuning only: CPU time of the Python thread per iteration (median; XLA computes on its own
  threads, so this is the host's own work: dispatch, optimiser step, progress bar, checkpoints).
- **periods/s, runs/s**: over the kernel time; for tuning, scenario-periods (and scenarios) differentiated
  per second of iteration wall time.
- the **device** (kind and count), the chunk size and what limited it
  ([`tuning.montecarlo.chunking`][tuning.montecarlo.chunking]), and the load average of the machine before and
  after each row (the 2-core machine these figures come from is shared: compare figures taken together, never
  across runs).

Precision is float32 (JAX's default) unless x64 is enabled. ``quick=True`` shrinks every size so the
benchmark runs in seconds (smoke tests); its figures mean nothing.
"""

import argparse
import dataclasses
import sys
import tempfile
import time

from tuning.montecarlo.cpu_devices import split_cpu

#: The short scenario of row 2: 20 periods at 10 kHz.
SHORT_SCENARIO = dict(duration_s=0.002, load_time_s=0.001, decimate=10)
#: Durations (s) of the tuning scenarios of row 3.
TUNE_DURATION_S = (0.02, 0.03)

#: Keys every row holds (checked by the smoke test).
ROW_KEYS = (
    "workload",
    "n",
    "periods_per_run",
    "kernel_s",
    "whole_s",
    "periods_per_s",
    "runs_per_s",
    "device",
    "load_before",
    "load_after",
)


def _load() -> float:
    try:
        with open("/proc/loadavg") as f:
            return float(f.read().split()[0])
    except OSError:
        return float("nan")


def _device() -> str:
    import jax

    devices = jax.devices()
    return f"{len(devices)} x {devices[0].device_kind}"


def kernel_time(runner, values, size: int, count: int) -> float:
    """Seconds of the compiled chunk function over ``count`` chunks of ``size`` rows of ``values``,
    inputs placed on the devices beforehand and results left there."""
    import jax

    from tuning.montecarlo.runner import _pad, _to_global

    fn = runner.compile("forward", size)
    total = 0.0
    for c in range(count):
        rows = _pad(values[c * size : (c + 1) * size], size).astype(runner.dtype)
        x = jax.block_until_ready(_to_global(rows, runner.sharding))
        start = time.perf_counter()
        jax.block_until_ready(fn(x))
        total += time.perf_counter() - start
    return total


def montecarlo_row(workload: str, n: int, repeats: int = 3, **study_kwargs) -> dict:
    """Row 1 or 2 of the module docstring: one cold call, then ``repeats`` warm calls and kernel timings
    in turn (medians), so that a change in the shared machine's load falls on both alike."""
    import numpy as np

    from tuning.montecarlo import run_study
    from tuning.montecarlo import study as mc_study
    from tuning.montecarlo.distributions import sample
    from tuning.montecarlo.runner import _runner

    load_before = _load()
    study = mc_study.Study(n=n, sensitivity_runs=0, **study_kwargs)
    warm, kernel = [], []
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        summary = run_study(study, f"{tmp}/cold", progress=False, figures=False)
        cold = time.perf_counter() - start
        runner = _runner(study, None)
        dists = mc_study.distributions(study, runner.drive)
        samples = sample(dists, study.n, study.seed, study.sampling)
        values = np.stack([samples[k] for k in runner.names], axis=1)
        size, count = summary["chunks"]["size"], summary["chunks"]["count"]
        for k in range(repeats):
            start = time.perf_counter()
            warm_summary = run_study(study, f"{tmp}/warm{k}", progress=False, figures=False)
            warm.append(time.perf_counter() - start)
            kernel.append(kernel_time(runner, values, size, count))
    warm, kernel = float(np.median(warm)), float(np.median(kernel))
    periods = study.n_periods
    return {
        "workload": workload,
        "n": n,
        "periods_per_run": periods,
        "n_substeps": study.n_substeps,
        "unroll_substeps": study.unroll_substeps,
        "chunk_size": size,
        "n_chunks": count,
        "chunk_rule": summary["chunk_rule"],
        "kernel_s": kernel,
        "whole_s": cold,
        "whole_warm_s": warm,
        "compile_s": summary["compile_time_s"],
        "run_time_s": warm_summary["run_time_s"],
        "whole_over_kernel": cold / kernel,
        "warm_over_kernel": warm / kernel,
        "periods_per_s": n * periods / kernel,
        "runs_per_s": n / kernel,
        "dtype": summary["precision"],
        "device": _device(),
        "load_before": load_before,
        "load_after": _load(),
    }


def tuning_row(n_scenarios: int, iterations: int, duration_s=TUNE_DURATION_S) -> dict:
    """Row 3 of the module docstring."""
    import jax
    import numpy as np

    from pmsmjax.presets.three_phase import book_drive
    from tuning.autotune import TuneConfig, tune
    from tuning.autotune.objectives import ObjectiveWeights
    from tuning.autotune.scenario_batches import make_batch
    from tuning.autotune.tuner import compile_value_and_grad
    from tuning.parameters import LogParameterisation

    load_before = _load()
    drive = book_drive(n_substeps=1)
    batch = make_batch(n_scenarios, seed=0, duration_s=duration_s)
    weights = ObjectiveWeights()
    config = TuneConfig(method="bfgs", max_iterations=iterations, patience=10 * iterations)
    wall, cpu = [], []

    def stamp(it, cost):
        wall.append(time.perf_counter())
        cpu.append(time.thread_time())

    with tempfile.TemporaryDirectory() as tmp:
        result = tune(drive, batch, weights, config, checkpoint_path=f"{tmp}/c.npz", callback=stamp)
    per_iteration = float(np.median(np.diff(wall)))
    host = float(np.median(np.diff(cpu)))
    # The device time of one evaluation: the same compiled function, alone.
    param = LogParameterisation(drive, config.names, config.bounds)
    theta = param.initial_theta()
    follow = dataclasses.replace(
        weights,
        overshoot_smoothing_pct=config.overshoot_smoothing_pct,
        current_smoothing_a=config.current_smoothing_a,
    )  # the cost BFGS follows, as tune() builds it
    evaluate = compile_value_and_grad(theta, drive, batch, follow, param)
    jax.block_until_ready(evaluate(theta))
    times = []
    for _ in range(7):
        start = time.perf_counter()
        jax.block_until_ready(evaluate(theta))
        times.append(time.perf_counter() - start)
    kernel = float(np.median(times))
    periods = int(round(batch.horizon_s / drive.Ts))
    return {
        "workload": "tune iteration",
        "n": n_scenarios,
        "periods_per_run": periods,
        "n_substeps": drive.n_substeps,
        "iterations": result.iterations,
        "kernel_s": kernel,
        "whole_s": per_iteration,
        "host_s": host,
        "compile_s": result.compile_time_s,
        "whole_over_kernel": per_iteration / kernel,
        "periods_per_s": n_scenarios * periods / per_iteration,
        "runs_per_s": n_scenarios / per_iteration,
        "device": str(jax.devices()[0].device_kind) + " (one device)",
        "load_before": load_before,
        "load_after": _load(),
    }


def run(
    n_book: int = 10_000,
    n_short: int = 200_000,
    tune_scenarios: int = 1024,
    tune_iterations: int = 20,
    quick: bool = False,
    unroll_substeps: bool = False,
    repeats: int = 3,
) -> dict:
    from benchmarks.bench_core import machine_info

    if quick:
        n_book, n_short, tune_scenarios, tune_iterations, repeats = 8, 64, 4, 3, 1
    rows = []
    drive = {"unroll_substeps": True} if unroll_substeps else {}
    if n_book:
        book = dict(duration_s=0.02, load_time_s=0.01, decimate=20) if quick else {}
        rows.append(montecarlo_row("montecarlo book", n_book, repeats, **book, **drive))
    if n_short:
        rows.append(montecarlo_row("montecarlo short", n_short, repeats, **SHORT_SCENARIO, **drive))
    if tune_scenarios:
        rows.append(tuning_row(tune_scenarios, tune_iterations, (0.002, 0.003) if quick else TUNE_DURATION_S))
    return {"quick": quick, "rows": rows, "machine": machine_info()}


def format_table(r: dict) -> str:
    head = (
        "workload",
        "N",
        "periods",
        "chunk (limit)",
        "kernel",
        "whole call",
        "whole/kernel",
        "compile",
        "M periods/s",
        "runs/s",
        "device",
        "load",
    )
    lines = []
    for row in r["rows"]:
        if row["workload"].startswith("montecarlo"):
            limit = row["chunk_rule"].get("limited_by", "given")
            chunk = f"{row['n_chunks']} x {row['chunk_size']} ({limit})"
            whole = f"{row['whole_s']:.2f} s cold, {row['whole_warm_s']:.2f} s warm"
            ratio = f"{row['whole_over_kernel']:.2f} cold, {row['warm_over_kernel']:.2f} warm"
        else:
            chunk = "-"
            whole = f"{1e3 * row['whole_s']:.1f} ms/it (host {1e3 * row['host_s']:.2f} ms)"
            ratio = f"{row['whole_over_kernel']:.2f}"
        kernel = row["kernel_s"]
        lines.append(
            (
                row["workload"],
                f"{row['n']:,}",
                str(row["periods_per_run"]),
                chunk,
                f"{kernel:.3f} s" if kernel >= 1 else f"{1e3 * kernel:.1f} ms",
                whole,
                ratio,
                f"{row['compile_s']:.1f} s",
                f"{row['periods_per_s'] / 1e6:.2f}",
                f"{row['runs_per_s']:,.0f}",
                row["device"],
                f"{row['load_before']:.1f} -> {row['load_after']:.1f}",
            )
        )
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(head)]
    fmt = lambda cells: " | ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True))
    m = r["machine"]
    out = [fmt(head), "-+-".join("-" * w for w in widths), *(fmt(line) for line in lines)]
    out.append(f"machine: {m['cpu']} ({m['cpu_count']} cores), jax {m['jax']}, backend {m['backend']}")
    return "\n".join(out)


def _parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n-book", type=int, default=10_000, help="book-scenario runs (default 10000; 0: skip)")
    p.add_argument("--n-short", type=int, default=200_000, help="short-scenario runs (200000; 0: skip)")
    p.add_argument("--tune-scenarios", type=int, default=1024, help="tuning batch (default 1024; 0: skip)")
    p.add_argument("--tune-iterations", type=int, default=20, help="tuning iterations timed (default 20)")
    p.add_argument("--devices", type=int, default=None, help="CPU devices (default: one per core)")
    p.add_argument("--unroll-substeps", action="store_true", help="Monte Carlo rows: RK4 sub-steps unrolled")
    p.add_argument("--repeats", type=int, default=3, help="warm calls and kernel timings per row (3)")
    p.add_argument("--quick", action="store_true", help="tiny sizes (smoke test; timings meaningless)")
    p.add_argument("--json", default="bench_scale.json", help="output JSON (default bench_scale.json)")
    return p.parse_args(argv)


def main(argv=None) -> dict:
    args = _parse(argv)
    split_cpu(args.devices)
    from benchmarks.bench_core import publish

    results = run(
        args.n_book,
        args.n_short,
        args.tune_scenarios,
        args.tune_iterations,
        args.quick,
        args.unroll_substeps,
        args.repeats,
    )
    return publish(results, format_table(results), args.json)


if __name__ == "__main__":
    main(sys.argv[1:])
