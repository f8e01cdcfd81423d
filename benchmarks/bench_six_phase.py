"""Per-period cost of the six-phase drive against the three-phase book drive, in one run.

Every drive simulates the same book scenario (1000 r/min, 10 N m at 0.2 s, 0.4 s; float32 unless x64 is
enabled, as the command line runs), timed interleaved (:func:`benchmarks.bench_core.time_interleaved`) so
the ratios hold under a varying machine load:

- ``three-phase``: :func:`pmsmjax.presets.book_drive` (dq machine, SVPWM, averaged bridge, PI FOC);
- ``six-phase <scheme>``: :func:`pmsmjax.presets_six_phase.six_phase_drive` with each control scheme
  (dq + z1-z2 machine, four-vector SVPWM, averaged bridge);
- the same two with the switching-resolved bridges (7 segments against 13 per period); the six-phase PR
  scheme against the three-phase PR drive (:func:`pmsmjax.presets.pr_drive`);
- a ``vmap`` batch (``--batch``, default 64 runs) of the three-phase and the six-phase VSD drive: the
  per-run cost that Monte Carlo studies and tuning pay.

The issue's goal: the six-phase drive's per-period cost at most 2.5 times the three-phase one's.

    python -m benchmarks.bench_six_phase --json six_phase.json
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.inverters import SwitchingBridge
from pmsmjax.presets_six_phase import SIX_PHASE_CONTROLS, six_phase_drive

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("drives", "duration_s", "batch", "dtype", "machine")


def run(quick: bool = False, batch: int = 64) -> dict:
    """Time every drive on the book scenario (``quick``: 0.02 s, 1 round, batch 4; figures meaningless)."""
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 5
    batch = 4 if quick else batch
    scenario = presets.book_scenario(duration_s=duration, load_time_s=duration / 2)
    three = presets.book_drive()
    drives = {"three-phase": three}
    drives.update({f"six-phase {name}": six_phase_drive(control=name) for name in SIX_PHASE_CONTROLS})
    drives["three-phase pr"] = presets.pr_drive()
    drives["three-phase switching"] = eqx.tree_at(
        lambda d: d.bridge, three, SwitchingBridge(three.bridge.u_dc)
    )
    drives["six-phase vsd switching"] = six_phase_drive(control="vsd", bridge="switching")
    calls = {name: (lambda d=d: jax.block_until_ready(simulate(d, scenario))) for name, d in drives.items()}

    def batched(drive):
        stacked = jax.tree.map(lambda x: jnp.stack([x] * batch) if eqx.is_array(x) else x, drive)
        f = eqx.filter_jit(eqx.filter_vmap(lambda d: simulate(d, scenario).omega_m))
        return lambda: jax.block_until_ready(f(stacked))

    calls[f"three-phase x{batch}"] = batched(three)
    calls[f"six-phase vsd x{batch}"] = batched(drives["six-phase vsd"])
    first, best = time_interleaved(calls, reps)
    out = {}
    for name in calls:
        runs = batch if name.endswith(f"x{batch}") else 1
        d = drives.get(name, three)
        periods = round(duration / d.Ts)
        out[name] = {
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "runs": runs,
            "us_per_period": 1e6 * best[name] / (periods * runs),
        }
    pairs = {
        "three-phase": "three-phase",
        "six-phase pr": "three-phase pr",
        "three-phase pr": "three-phase pr",
        "three-phase switching": "three-phase switching",
        "six-phase vsd switching": "three-phase switching",
        f"three-phase x{batch}": f"three-phase x{batch}",
        f"six-phase vsd x{batch}": f"three-phase x{batch}",
    }
    for name, o in out.items():
        o["vs_three_phase"] = o["us_per_period"] / out[pairs.get(name, "three-phase")]["us_per_period"]
    dtype = str(jnp.result_type(float))
    return {"drives": out, "duration_s": duration, "batch": batch, "dtype": dtype, "machine": machine_info()}


def format_table(r: dict) -> str:
    lines = [
        f"six-phase vs three-phase drive, book scenario ({r['duration_s']:g} s, {r['dtype']}), best of "
        "rounds",
        f"{'drive':28s} {'runs':>5s} {'run ms':>9s} {'compile s':>9s} {'us/period/run':>13s} "
        f"{'x three-phase':>13s}",
    ]
    for name, o in r["drives"].items():
        lines.append(
            f"{name:28s} {o['runs']:5d} {o['run_s'] * 1e3:9.2f} {o['compile_s']:9.2f} "
            f"{o['us_per_period']:13.3f} {o['vs_three_phase']:13.2f}"
        )
    m = r["machine"]
    lines.append("ratios: against the three-phase drive with the same bridge and batch")
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}, {m['backend']}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False, batch: int = 64) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick, batch=batch)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="per-period cost of the six-phase drive vs three-phase")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--batch", type=int, default=64, help="vmap batch size (default 64)")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick, args.batch)
