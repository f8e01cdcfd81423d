"""Cost of a warm motor: the book drive with and without its winding thermal network, per control period.

The book drive (float32 as the command line runs, averaged bridge, 10 RK4 sub-steps) and the same drive with
a [`WindingThermal`][pmsmjax.machines.thermal.WindingThermal] network (R(T), psi_f(T), the network advanced
once per period), same scenario: one run, and a batch of ``batch`` runs under ``jax.vmap`` (initial winding
temperatures spread over 20-120 degC for the warm drive, the resistance +-10 % for the ideal one, so that both
batches vary a leaf); all timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]), so the ratios hold under
a varying load. Target: the warm drive costs at most 1.2x the ideal one per period. The saturated-ipm drive
file (flux-map plant) with and without a network is timed the same way.

    python -m benchmarks.thermal_cost --json thermal_cost.json
"""

import argparse

import jax
import jax.numpy as jnp

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.assemble import spec_drive, spec_scenario, with_parts
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.thermal import WindingThermal

__all__ = ["run", "main", "format_table"]

#: A 1-2 kW motor's winding: 0.5 K/W to ambient, 1500 J/K (a 750 s time constant), at 40 degC ambient.
NETWORK = dict(r_th=0.5, c_th=1500.0, ambient_k=313.15, initial_k=353.15, reference_k=293.15)


def run(quick: bool = False, batch: int = 64) -> dict:
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 7
    batch = 4 if quick else batch
    network = WindingThermal(**NETWORK, r_temp_coeff=0.00393, psi_f_temp_coeff=-0.0011)
    book = presets.book_drive()
    ipm_spec = drive_spec("saturated-ipm")
    ipm = spec_drive(ipm_spec)
    drives = {
        "ideal": book,
        "warm": with_parts(book, {"thermal": network}),
        "map_ideal": ipm,
        "map_warm": with_parts(ipm, {"thermal": network}),
    }
    scenarios = {
        "ideal": presets.book_scenario(duration_s=duration, load_time_s=duration / 2),
        "map_ideal": spec_scenario(ipm_spec, duration_s=duration, load_time_s=duration / 2),
    }
    scenarios["warm"], scenarios["map_warm"] = scenarios["ideal"], scenarios["map_ideal"]
    spread = jnp.linspace(0.0, 1.0, batch)

    def batched(name, drive, scenario):
        if name.endswith("warm"):
            vary = lambda x: with_parts(drive, {"thermal.initial_k": 293.15 + 100.0 * x})
        else:
            vary = lambda x: with_parts(drive, {"machine.motor.R": drive.machine.motor.R * (0.9 + 0.2 * x)})
        return jax.jit(jax.vmap(lambda x: simulate(vary(x), scenario).speed_rpm))

    calls = {
        k: (lambda d=d, s=scenarios[k]: jax.block_until_ready(simulate(d, s))) for k, d in drives.items()
    }
    for k, d in drives.items():
        f = batched(k, d, scenarios[k])
        calls[f"{k}_batch"] = lambda f=f: f(spread).block_until_ready()
    first, best = time_interleaved(calls, reps)
    periods = round(duration / book.Ts)
    cost = {
        k: {
            "run_s": best[k],
            "compile_s": compile_time(first[k], best[k]),
            "per_period_us": 1e6 * best[k] / periods / (batch if k.endswith("_batch") else 1),
        }
        for k in calls
    }
    ratio = lambda a, b: cost[a]["per_period_us"] / cost[b]["per_period_us"]
    warm_trace = simulate(drives["warm"], scenarios["warm"])
    return {
        "duration_s": duration,
        "periods": periods,
        "batch": batch,
        "cost": cost,
        "ratio_per_period": ratio("warm", "ideal"),
        "ratio_per_period_batch": ratio("warm_batch", "ideal_batch"),
        "ratio_per_period_map": ratio("map_warm", "map_ideal"),
        "ratio_per_period_map_batch": ratio("map_warm_batch", "map_ideal_batch"),
        "winding_c": [float(warm_trace.winding_temperature[i]) - 273.15 for i in (0, -1)],
        "dtype": str(jnp.result_type(float)),
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    lines = [f"{r['periods']} periods ({r['dtype']}):"]
    for k, c in r["cost"].items():
        label = k.replace("_batch", f" x{r['batch']}")
        lines.append(
            f"  {label:16s} run {c['run_s'] * 1e3:8.1f} ms  compile {c['compile_s']:6.2f} s  "
            f"{c['per_period_us']:7.2f} us/period (per run)"
        )
    lines.append(f"  book, warm / ideal per period, one run: {r['ratio_per_period']:.3f}x (target <= 1.2x)")
    lines.append(
        f"  book, warm / ideal per period, batch of {r['batch']}: {r['ratio_per_period_batch']:.3f}x"
    )
    lines.append(f"  flux map, warm / ideal, one run: {r['ratio_per_period_map']:.3f}x")
    lines.append(f"  flux map, warm / ideal, batch of {r['batch']}: {r['ratio_per_period_map_batch']:.3f}x")
    lines.append(f"  winding {r['winding_c'][0]:.3f} -> {r['winding_c'][1]:.3f} degC over the run")
    m = r["machine"]
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, {m.get('backend', '')}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False) -> dict:
    r = run(quick)
    return publish(r, format_table(r), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="tiny sizes (a smoke run; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
