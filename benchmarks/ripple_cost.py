"""Cost of ripple: a drive with and without magnet flux harmonics, cogging torque and a two-mass shaft, per
control period.

The book drive (float32 as the command line runs, averaged bridge, 10 RK4 sub-steps, dq plant), the ideal
one (rigid shaft, sinusoidal flux) against the same drive with a
[`MagnetHarmonics`][pmsmjax.machines.harmonics.MagnetHarmonics] (the drive-file reference's 5th and 7th flux
harmonics, 6th and 12th cogging orders) and a compliant shaft ([`two_mass`][benchmarks.ripple_cost.two_mass]:
the drive's inertia split a third to the motor, two thirds to the load, a 200 Hz resonance with 2 % modal
damping, as the servo-two-mass drive file), same scenario: one run, and a batch of ``batch`` runs under
``jax.vmap`` (the resistance spread +-10 % in both, so that both batches vary a leaf); all timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]), so the ratios hold under
a varying load. Target: at most 1.5x the ideal drive per period. The alpha-beta plant and the saturated-ipm
drive file (flux-map plant), ideal and with ripple and shaft, are timed the same way; the book dq drive with
the harmonics alone (``harmonics``) and with the shaft alone (``shaft``) shows what each part costs.

    python -m benchmarks.ripple_cost --json ripple_cost.json
"""

import argparse

import jax
import jax.numpy as jnp

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.assemble import spec_drive, spec_scenario, with_parts
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.harmonics import MagnetHarmonics

__all__ = ["run", "main", "format_table", "two_mass", "FLUX", "COGGING", "RESONANCE_HZ"]

#: The drive-file reference's example: ``[order, amplitude (Wb / N m), phase (rad)]``.
FLUX = [[5, 0.0019, 0.4], [7, 0.0009, -1.1]]
COGGING = [[6, 0.045, 0.3], [12, 0.018, -0.8]]
#: The shaft's resonance, Hz (the servo-two-mass drive file's).
RESONANCE_HZ = 200.0


def two_mass(drive) -> dict:
    """``with_parts`` changes that give ``drive`` a compliant shaft of the same total inertia: the motor a
    third of it, the load two thirds, the stiffness ``K = w_r^2 J_m J_L / (J_m + J_L)`` for a
    [`RESONANCE_HZ`][benchmarks.ripple_cost.RESONANCE_HZ] resonance and the damping 2 % of the critical
    ``2 sqrt(K J_m J_L / (J_m + J_L))`` (pmsmjax/machines/shaft.py)."""
    J = drive.machine.motor.J
    J_m, J_L = J / 3.0, 2.0 * J / 3.0
    K = (2.0 * jnp.pi * RESONANCE_HZ) ** 2 * J_m * J_L / J
    D = 0.02 * 2.0 * jnp.sqrt(K * J_m * J_L / J)
    return {
        "machine.motor.J": J_m, "machine.motor.load_inertia": J_L, "machine.motor.shaft_stiffness": K,
        "machine.motor.shaft_damping": D,
    }  # fmt: skip


def run(quick: bool = False, batch: int = 64) -> dict:
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 7
    batch = 4 if quick else batch
    harmonics = {"machine.harmonics": MagnetHarmonics.from_rows(FLUX, COGGING)}
    ripple = lambda drive: with_parts(drive, {**harmonics, **two_mass(drive)})
    book = presets.book_drive()
    book_ab = presets.book_drive(frame="alpha_beta")
    ipm_spec = drive_spec("saturated-ipm")
    ipm = spec_drive(ipm_spec)
    drives = {
        "ideal": book,
        "ripple": ripple(book),
        "harmonics": with_parts(book, harmonics),
        "shaft": with_parts(book, two_mass(book)),
        "ab_ideal": book_ab,
        "ab_ripple": ripple(book_ab),
        "map_ideal": ipm,
        "map_ripple": ripple(ipm),
    }
    book_scenario = presets.book_scenario(duration_s=duration, load_time_s=duration / 2)
    ipm_scenario = spec_scenario(ipm_spec, duration_s=duration, load_time_s=duration / 2)
    scenarios = {k: ipm_scenario if k.startswith("map") else book_scenario for k in drives}
    spread = jnp.linspace(0.0, 1.0, batch)

    def batched(drive, scenario):
        vary = lambda x: with_parts(drive, {"machine.motor.R": drive.machine.motor.R * (0.9 + 0.2 * x)})
        return jax.jit(jax.vmap(lambda x: simulate(vary(x), scenario).speed_rpm))

    calls = {
        k: (lambda d=d, s=scenarios[k]: jax.block_until_ready(simulate(d, s))) for k, d in drives.items()
    }
    for k, d in drives.items():
        f = batched(d, scenarios[k])
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
    parts = {f"{k}{suffix}": ratio(f"{k}{suffix}", f"ideal{suffix}") for k in ("harmonics", "shaft")
             for suffix in ("", "_batch")}  # fmt: skip
    return {
        "duration_s": duration,
        "periods": periods,
        "batch": batch,
        "cost": cost,
        "ratios": {
            f"{prefix}{suffix}": ratio(f"{prefix}ripple{suffix}", f"{prefix}ideal{suffix}")
            for prefix in ("", "ab_", "map_")
            for suffix in ("", "_batch")
        },
        "parts": parts,
        "dtype": str(jnp.result_type(float)),
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    lines = [f"{r['periods']} periods ({r['dtype']}):"]
    for k, c in r["cost"].items():
        label = k.replace("_batch", f" x{r['batch']}")
        lines.append(
            f"  {label:18s} run {c['run_s'] * 1e3:8.1f} ms  compile {c['compile_s']:6.2f} s  "
            f"{c['per_period_us']:7.2f} us/period (per run)"
        )
    names = {"": "book dq", "ab_": "book alpha-beta", "map_": "flux map"}
    for key, value in r["ratios"].items():
        prefix, batched = key.replace("_batch", ""), key.endswith("_batch")
        prefix = prefix + "_" if prefix and not prefix.endswith("_") else prefix
        how = f"batch of {r['batch']}" if batched else "one run"
        lines.append(f"  {names[prefix]}, ripple / ideal per period, {how}: {value:.3f}x (target <= 1.5x)")
    for key, value in r["parts"].items():
        how = f"batch of {r['batch']}" if key.endswith("_batch") else "one run"
        lines.append(f"  book dq, {key.replace('_batch', '')} alone / ideal per period, {how}: {value:.3f}x")
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
