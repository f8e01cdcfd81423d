"""Cost of the flux-map plant against the linear dq plant in the book drive, and gradient finiteness.

1. The salient book drive (float32 as the command line runs, averaged bridge, 10 RK4 sub-steps) with its
   linear [`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq] plant and with a
   [`PMSMFluxMapdq`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq] plant on the preset saturated IPM's map (41
   x 41 points), same scenario: one run, and a batch of ``batch`` runs under ``jax.vmap`` (resistance
   spread +-10 %, as Monte Carlo and tuning run); all four timed interleaved
   ([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]), so the ratios
   hold under a varying load. Target: the flux-map drive costs at most 2x the linear one per period.
2. The plants alone, open loop under a rotating voltage, one run and the batch; beside them the same
   flux-map plant on a map of one bicubic cell spanning the grid
   ([`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap] with the first cell's coefficients): the cell search,
   coefficient load, patch and 2x2 solve at every RK4 stage with a table that always answers from one cell,
   the floor any located piecewise-cubic map pays.
3. Gradients of a flux-map plant run (open loop, rotating voltage, 200 periods) with respect to the
   resistance and voltage amplitude over ``draws`` random draws under ``jax.vmap``: how many are finite.

    python -m benchmarks.flux_map_cost --json flux_map_cost.json
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.assemble import spec_flux_map
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines import MachineInput, advance
from pmsmjax.machines.pmsm_flux_map import FluxMap, PMSMFluxMapdq

__all__ = ["run", "main", "format_table"]


def run(quick: bool = False, draws: int = 1000, batch: int = 64) -> dict:
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 7
    batch = 4 if quick else batch
    scenario = presets.book_scenario(duration_s=duration, load_time_s=duration / 2)
    linear = presets.book_drive(presets.book_motor(salient=True))
    flux_map = spec_flux_map(drive_spec("saturated-ipm"))
    mapped = eqx.tree_at(lambda d: d.machine, linear, PMSMFluxMapdq(linear.machine.motor, flux_map))
    drives = {"linear": linear, "flux_map": mapped}
    resistance = jnp.linspace(0.9, 1.1, batch) * linear.machine.motor.R

    def batched(drive):
        with_r = lambda r: eqx.tree_at(lambda d: d.machine.motor.R, drive, r)
        return jax.jit(jax.vmap(lambda r: simulate(with_r(r), scenario).speed_rpm))

    calls = {k: (lambda d=d: jax.block_until_ready(simulate(d, scenario))) for k, d in drives.items()}
    for k, d in drives.items():
        f = batched(d)
        calls[f"{k}_batch"] = lambda f=f: f(resistance).block_until_ready()
    first, best = time_interleaved(calls, reps)
    periods = round(duration / linear.Ts)
    cost = {
        k: {
            "run_s": best[k],
            "compile_s": compile_time(first[k], best[k]),
            "per_period_us": 1e6 * best[k] / periods / (batch if k.endswith("_batch") else 1),
        }
        for k in calls
    }
    excursion = flux_map.excursion(np.asarray(simulate(mapped, scenario).i_dq))

    machine = PMSMFluxMapdq(linear.machine.motor, flux_map)
    one_cell = FluxMap(
        flux_map.coefficients[:1, :1], flux_map.lower, flux_map.upper - flux_map.lower, flux_map.upper
    )
    plants = {
        "linear": linear.machine,
        "flux_map": machine,
        "one_cell": PMSMFluxMapdq(linear.machine.motor, one_cell),
    }
    plant_periods = 200 if quick else 2000

    def plant_run(m, r):
        m = eqx.tree_at(lambda x: x.motor.R, m, r)

        def body(state, k):
            u = 100.0 * jnp.stack([jnp.cos(0.05 * k), jnp.sin(0.05 * k)])
            state = advance(m, state, MachineInput(u, jnp.asarray(0.5, u.dtype)), linear.Ts, 10)
            return state, state.currents[0]

        return jax.lax.scan(body, m.initial_state((0.0, 0.0), 10.0, 0.1), jnp.arange(float(plant_periods)))[1]

    plant_calls = {}
    for k, m in plants.items():
        one, many = jax.jit(lambda r, m=m: plant_run(m, r)), jax.jit(jax.vmap(lambda r, m=m: plant_run(m, r)))
        plant_calls[k] = lambda f=one: f(resistance[0]).block_until_ready()
        plant_calls[f"{k}_batch"] = lambda f=many: f(resistance).block_until_ready()
    _, plant_best = time_interleaved(plant_calls, reps)
    plant_cost = {
        k: 1e6 * t / plant_periods / (batch if k.endswith("_batch") else 1) for k, t in plant_best.items()
    }

    def final_speed(r, u_amp):
        m = eqx.tree_at(lambda x: x.motor.R, machine, r)
        s0 = m.initial_state((0.0, 0.0), 10.0, 0.1)

        def body(state, k):
            u = u_amp * jnp.stack([jnp.cos(0.3 * k), jnp.sin(0.3 * k)])
            return advance(m, state, MachineInput(u, jnp.asarray(0.5, u.dtype)), 1e-4, 4), None

        return jax.lax.scan(body, s0, jnp.arange(200.0))[0].omega_m

    n = 16 if quick else draws
    x = np.random.default_rng(0).uniform([0.3, 20.0], [2.0, 150.0], size=(n, 2)).astype(np.float32)
    grads = jax.jit(jax.vmap(jax.grad(final_speed, argnums=(0, 1))))(
        jnp.asarray(x[:, 0]), jnp.asarray(x[:, 1])
    )
    finite = np.all(np.isfinite(np.stack([np.asarray(g) for g in grads], -1)), axis=-1)
    return {
        "duration_s": duration,
        "periods": periods,
        "cost": cost,
        "ratio_per_period": cost["flux_map"]["per_period_us"] / cost["linear"]["per_period_us"],
        "ratio_per_period_batch": (
            cost["flux_map_batch"]["per_period_us"] / cost["linear_batch"]["per_period_us"]
        ),
        "batch": batch,
        "plant_per_period_us": plant_cost,
        "grid_excursion": excursion,
        "gradient_draws": n,
        "gradient_finite": int(finite.sum()),
        "dtype": str(jnp.result_type(float)),
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    lines = [f"book drive, {r['periods']} periods ({r['dtype']}):"]
    for k, c in r["cost"].items():
        label = k.replace("_batch", f" x{r['batch']}")
        lines.append(
            f"  {label:12s} run {c['run_s'] * 1e3:8.1f} ms  compile {c['compile_s']:6.2f} s  "
            f"{c['per_period_us']:7.2f} us/period (per run)"
        )
    lines.append(f"  flux map / linear per period, one run: {r['ratio_per_period']:.2f}x (target <= 2x)")
    lines.append(f"  flux map / linear per period, batch of {r['batch']}: {r['ratio_per_period_batch']:.2f}x")
    lines.append(f"  grid: {r['grid_excursion']['warning'] or 'the run stayed on the map grid'}")
    p = r["plant_per_period_us"]
    lines.append(
        f"plants alone, us/period (per run): linear {p['linear']:.3f}, flux map {p['flux_map']:.3f} "
        f"({p['flux_map'] / p['linear']:.2f}x); batch of {r['batch']}: linear {p['linear_batch']:.3f}, "
        f"flux map {p['flux_map_batch']:.3f} ({p['flux_map_batch'] / p['linear_batch']:.2f}x)"
    )
    lines.append(
        f"  one-cell map (the floor of a located cubic patch): {p['one_cell']:.3f} "
        f"({p['one_cell'] / p['linear']:.2f}x); batch {p['one_cell_batch']:.3f} "
        f"({p['one_cell_batch'] / p['linear_batch']:.2f}x)"
    )
    lines.append(f"gradients finite: {r['gradient_finite']} of {r['gradient_draws']} draws (vmap)")
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
