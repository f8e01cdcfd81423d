"""Cost of every control method's drive relative to the PI drive, in one run.

Each drive of [`pmsmjax.presets.control_methods.CONTROLS`][pmsmjax.presets.control_methods.CONTROLS] (its
preset defaults: averaged bridge, float32 as the command line runs) simulates the same book scenario; the
calls are timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]), so their ratios
hold under a varying machine load. Figures per drive: control period, periods simulated, best run time,
compile time, cost per period and per simulated second, and both relative to the PI drive. The cost goal is
<= 1.5x per period for the methods that run at the PI drive's 10 kHz; hysteresis current control samples its
comparators at 100 kHz, so its cost is per simulated second at its own rate (ten periods for one of the PI
drive's).

    python -m benchmarks.bench_controllers --json controllers.json
"""

import argparse

import jax

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.presets.control_methods import CONTROLS, control_drive

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("controls", "duration_s", "dtype", "machine")


def run(quick: bool = False) -> dict:
    """Time every control's drive on the book scenario (``quick``: 0.02 s, 1 round; figures meaningless)."""
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 7
    scenario = presets.book_scenario(duration_s=duration, load_time_s=duration / 2)
    drives = {name: control_drive(name) for name in CONTROLS}
    calls = {name: (lambda d=d: jax.block_until_ready(simulate(d, scenario))) for name, d in drives.items()}
    first, best = time_interleaved(calls, reps)
    controls = {}
    for name, d in drives.items():
        periods = round(duration / d.Ts)
        controls[name] = {
            "control_period_s": d.Ts,
            "periods": periods,
            "n_substeps": d.n_substeps,
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "us_per_period": 1e6 * best[name] / periods,
            "wall_s_per_simulated_s": best[name] / duration,
        }
    pi = controls["pi"]
    for c in controls.values():
        c["per_period_vs_pi"] = c["us_per_period"] / pi["us_per_period"]
        c["per_simulated_s_vs_pi"] = c["wall_s_per_simulated_s"] / pi["wall_s_per_simulated_s"]
    dtype = str(jax.numpy.result_type(float))
    return {"controls": controls, "duration_s": duration, "dtype": dtype, "machine": machine_info()}


def format_table(r: dict) -> str:
    lines = [
        f"control methods on the book scenario ({r['duration_s']:g} s, {r['dtype']}), best of rounds",
        f"{'control':12s} {'Ts us':>6s} {'substeps':>8s} {'run ms':>8s} {'compile s':>9s} {'us/period':>9s} "
        f"{'x PI/period':>11s} {'x PI/sim s':>10s}",
    ]
    for name, c in r["controls"].items():
        lines.append(
            f"{name:12s} {c['control_period_s'] * 1e6:6g} {c['n_substeps']:8d} {c['run_s'] * 1e3:8.2f} "
            f"{c['compile_s']:9.2f} {c['us_per_period']:9.2f} {c['per_period_vs_pi']:11.2f} "
            f"{c['per_simulated_s_vs_pi']:10.2f}"
        )
    m = r["machine"]
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}, {m['backend']}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="cost of each control method's drive relative to PI")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
