"""Core speed benchmark: the simulator's own figures ([`pmsmjax.jobs.bench`][pmsmjax.jobs.bench], what
``pmsmjax bench`` reports: compile time, one run, a vmapped batch, gradients, forward- vs reverse-mode
crossover, the machine) and, timed in the same rounds as the single run, the hand-written minimal loop
(`benchmarks.minimal_loop`) it is measured against: with literal constants and with run-time
parameters, the library/minimal time ratio of each, and the largest difference between the library's and
the minimal loop's speed trajectories (r/min).

``python -m benchmarks.bench_core [--quick] [--json FILE]`` prints a table and writes the figures as JSON
(atomically). ``--quick`` shrinks every size so the whole benchmark runs in seconds (for smoke tests); its
timings mean nothing. The other benchmarks report through `publish` and take the timing helpers
([`time_interleaved`][pmsmjax.jobs.bench.time_interleaved],
[`compile_time`][pmsmjax.jobs.bench.compile_time],
[`machine_info`][pmsmjax.jobs.bench.machine_info]) from here.
"""

import argparse
import json

import jax.numpy as jnp
import numpy as np

from benchmarks.minimal_loop import BOOK, make_minimal_loop
from pmsmjax.io.logs import atomic_write
from pmsmjax.jobs import bench as engine_timing
from pmsmjax.jobs.bench import compile_time, machine_info, time_interleaved
from pmsmjax.jobs.bench_report import format_table as library_table
from pmsmjax.jobs.bench_report import row
from pmsmjax.simulate import period_inputs, simulate
from pmsmjax.units import rad_s_to_rpm

__all__ = [
    "REQUIRED_KEYS",
    "compile_time",
    "format_table",
    "machine_info",
    "main",
    "publish",
    "run",
    "time_interleaved",
    "write_json_atomic",
]

#: Keys every benchmark JSON holds: the simulator's own, then the comparison with the minimal loop.
REQUIRED_KEYS = (
    *engine_timing.REQUIRED_KEYS,
    "minimal_loop_literal_ms",
    "minimal_loop_runtime_params_ms",
    "ratio_vs_minimal_literal",
    "ratio_vs_minimal_runtime_params",
    "max_speed_diff_rpm_literal",
    "max_speed_diff_rpm_runtime_params",
)


def run(quick: bool = False) -> dict:
    """[`pmsmjax.jobs.bench.run`][pmsmjax.jobs.bench.run] with the two minimal loops timed alongside the
    single run (same drive settings and scenario sampled on the period grid), their ratios and speed
    differences."""
    drive, scenario = engine_timing.book_problem(engine_timing.QUICK if quick else engine_timing.FULL)
    xs = period_inputs(scenario, drive.Ts)
    literal = make_minimal_loop(Ts=drive.Ts, n_sub=drive.n_substeps)
    runtime = make_minimal_loop(Ts=drive.Ts, n_sub=drive.n_substeps, runtime_parameters=True)
    params = {k: jnp.asarray(v, xs.speed_ref.dtype) for k, v in BOOK.items()}
    loops = {
        "literal": lambda: literal(xs.speed_ref, xs.load_torque),
        "runtime_params": lambda: runtime(xs.speed_ref, xs.load_torque, params),
    }
    results = engine_timing.run(quick, references=loops)
    minimal_ms = results.pop("references_ms")
    omega = np.asarray(simulate(drive, scenario).omega_m)
    for name, loop in loops.items():
        results[f"minimal_loop_{name}_ms"] = minimal_ms[name]
        results[f"ratio_vs_minimal_{name}"] = results["library_ms"] / minimal_ms[name]
        speed_diff = np.max(np.abs(omega - np.asarray(loop()[0])))
        results[f"max_speed_diff_rpm_{name}"] = float(rad_s_to_rpm(speed_diff))
    return results


def format_table(r: dict) -> str:
    """The simulator's table
    ([`pmsmjax.jobs.bench_report.format_table`][pmsmjax.jobs.bench_report.format_table]) and the minimal
    loops."""
    lines = [
        library_table(r),
        "",
        "hand-written minimal loop, timed in the same rounds as the single run:",
    ]
    loops = (
        ("literal", "literal constants", "literal"),
        ("runtime_params", "run-time parameters", "run-time"),
    )
    for name, label, short in loops:
        lines += [
            row(
                f"minimal loop, {label}",
                f"{r[f'minimal_loop_{name}_ms']:.2f} ms",
                f"library / minimal = {r[f'ratio_vs_minimal_{name}']:.2f}",
            ),
            row(f"  max |speed library - minimal|, {short}", f"{r[f'max_speed_diff_rpm_{name}']:.2e} r/min"),
        ]
    return "\n".join(lines)


def write_json_atomic(path: str, data: dict) -> None:
    """Write ``data`` as JSON to ``path`` atomically
    ([`pmsmjax.io.logs.atomic_write`][pmsmjax.io.logs.atomic_write])."""
    text = json.dumps(data, indent=2) + "\n"
    atomic_write(path, lambda f: f.write(text.encode()))


def publish(results: dict, table: str, json_path: str | None) -> dict:
    """Print a benchmark's ``table``; write its ``results`` as JSON to ``json_path`` if given (atomically).

    Every benchmark's ``main`` ends here, so they all report the same way. Returns ``results``.
    """
    print(table)
    if json_path is not None:
        write_json_atomic(json_path, results)
        print(f"wrote {json_path}")
    return results


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run the benchmark, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="pmsmjax core speed benchmark")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; timings meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
