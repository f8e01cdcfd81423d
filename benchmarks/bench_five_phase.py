"""Per-period cost of the five-phase drive against the three-phase book drive, in one run (BOOK.md ch. 10).

Every drive simulates the same book scenario (1000 r/min, 10 N m at 0.2 s, 0.4 s; float32 unless x64 is
enabled, as the command line runs), timed interleaved (:func:`benchmarks.bench_core.time_interleaved`) so
the ratios hold under a varying machine load:

- ``three-phase``: :func:`pmsmjax.presets.book_drive` (dq machine, SVPWM, averaged bridge, PI FOC);
- ``five-phase <scheme>``: :func:`pmsmjax.presets_five_phase.five_phase_drive` with each control scheme
  (dq + x-y machine integrated split, near-four-vector SVPWM, averaged bridge); ``five-phase vsd
  carrier``: min-max carrier PWM instead;
- ``five-phase vsd third-harmonic``: the preset with ``psi_f3 = 0.1 psi_f`` (the angle then drives x-y:
  the dq model integrates the whole state by RK4, no split);
- the switching-resolved bridges (7 segments per period for three legs, 11 for five);
- a ``vmap`` batch (``--batch``, default 64 runs) of the three-phase and the five-phase VSD drive.

    python -m benchmarks.bench_five_phase --json five_phase.json
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.inverters import SwitchingBridge
from pmsmjax.presets_five_phase import FIVE_PHASE_CONTROLS, five_phase_drive, five_phase_motor

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
    drives.update({f"five-phase {name}": five_phase_drive(control=name) for name in FIVE_PHASE_CONTROLS})
    drives["five-phase vsd carrier"] = five_phase_drive(pwm="carrier")
    drives["five-phase vsd third-harmonic"] = five_phase_drive(
        five_phase_motor(third_harmonic=0.1), pwm="carrier"
    )
    drives["three-phase switching"] = eqx.tree_at(
        lambda d: d.bridge, three, SwitchingBridge(three.bridge.u_dc)
    )
    drives["five-phase vsd switching"] = five_phase_drive(bridge="switching")
    calls = {name: (lambda d=d: jax.block_until_ready(simulate(d, scenario))) for name, d in drives.items()}

    def batched(drive):
        stacked = jax.tree.map(lambda x: jnp.stack([x] * batch) if eqx.is_array(x) else x, drive)
        f = eqx.filter_jit(eqx.filter_vmap(lambda d: simulate(d, scenario).omega_m))
        return lambda: jax.block_until_ready(f(stacked))

    calls[f"three-phase x{batch}"] = batched(three)
    calls[f"five-phase vsd x{batch}"] = batched(drives["five-phase vsd"])
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
        "three-phase switching": "three-phase switching",
        "five-phase vsd switching": "three-phase switching",
        f"three-phase x{batch}": f"three-phase x{batch}",
        f"five-phase vsd x{batch}": f"three-phase x{batch}",
    }
    for name, o in out.items():
        o["vs_three_phase"] = o["us_per_period"] / out[pairs.get(name, "three-phase")]["us_per_period"]
    dtype = str(jnp.result_type(float))
    return {"drives": out, "duration_s": duration, "batch": batch, "dtype": dtype, "machine": machine_info()}


def format_table(r: dict) -> str:
    lines = [
        f"five-phase vs three-phase drive, book scenario ({r['duration_s']:g} s, {r['dtype']}), best of "
        "rounds",
        f"{'drive':32s} {'runs':>5s} {'run ms':>9s} {'compile s':>9s} {'us/period/run':>13s} "
        f"{'x three-phase':>13s}",
    ]
    for name, o in r["drives"].items():
        lines.append(
            f"{name:32s} {o['runs']:5d} {o['run_s'] * 1e3:9.2f} {o['compile_s']:9.2f} "
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
    parser = argparse.ArgumentParser(description="per-period cost of the five-phase drive vs three-phase")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--batch", type=int, default=64, help="vmap batch size (default 64)")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick, args.batch)
