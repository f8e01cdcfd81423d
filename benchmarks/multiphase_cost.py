"""Per-period cost of multi-phase drives against the three-phase book drive, timed in one run: the engine
behind `benchmarks.bench_six_phase` and `benchmarks.bench_five_phase`.

Every drive simulates the same book scenario (1000 r/min, 10 N m half way; float32 unless x64 is enabled),
timed interleaved ([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved])
so the ratios hold under a varying machine load. The three-phase references are always timed: ``three-phase``
(book drive), ``three-phase switching`` (switching-resolved bridge) and a ``vmap`` batch ``three-phase xB``;
each multi-phase drive is compared with the reference named in ``pairs`` (default ``three-phase``).
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from benchmarks.bench_core import compile_time, machine_info, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.inverters import SwitchingBridge

__all__ = ["time_against_three_phase", "format_cost_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("drives", "duration_s", "batch", "dtype", "machine")


def time_against_three_phase(
    make_drives, batched_drive: str, pairs: dict, quick: bool = False, batch: int = 64
) -> dict:
    """Time the three-phase references and ``make_drives(three_phase_drive) -> {name: drive}``.

    - `batched_drive`: the name of the multi-phase drive also timed as a ``vmap`` batch of ``batch`` runs
      (named ``"<name> x<batch>"``, compared with ``three-phase x<batch>``).
    - `pairs`: ``{name: reference name}`` for the drives not compared with ``three-phase``.
    - `quick`: 0.02 s, 1 round, batch 4 (a smoke test; figures meaningless).

    **Returns:** ``{"drives": {name: {run_s, compile_s, runs, us_per_period, vs_three_phase}}, "duration_s",
    "batch", "dtype", "machine"}``.
    """
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 5
    batch = 4 if quick else batch
    scenario = presets.book_scenario(duration_s=duration, load_time_s=duration / 2)
    three = presets.book_drive()
    drives = {"three-phase": three}
    switching = SwitchingBridge(three.bridge.u_dc)
    drives["three-phase switching"] = eqx.tree_at(lambda d: d.bridge, three, switching)
    drives.update(make_drives(three))
    calls = {name: (lambda d=d: jax.block_until_ready(simulate(d, scenario))) for name, d in drives.items()}

    def batched(drive):
        stacked = jax.tree.map(lambda x: jnp.stack([x] * batch) if eqx.is_array(x) else x, drive)
        f = eqx.filter_jit(eqx.filter_vmap(lambda d: simulate(d, scenario).omega_m))
        return lambda: jax.block_until_ready(f(stacked))

    calls[f"three-phase x{batch}"] = batched(three)
    calls[f"{batched_drive} x{batch}"] = batched(drives[batched_drive])
    first, best = time_interleaved(calls, reps)
    out = {}
    for name in calls:
        runs = batch if name.endswith(f"x{batch}") else 1
        periods = round(duration / drives.get(name, three).Ts)
        out[name] = {
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "runs": runs,
            "us_per_period": 1e6 * best[name] / (periods * runs),
        }
    references = ("three-phase switching", f"three-phase x{batch}")
    pairs = {**pairs, f"{batched_drive} x{batch}": f"three-phase x{batch}", **{r: r for r in references}}
    for name, o in out.items():
        o["vs_three_phase"] = o["us_per_period"] / out[pairs.get(name, "three-phase")]["us_per_period"]
    dtype = str(jnp.result_type(float))
    return {"drives": out, "duration_s": duration, "batch": batch, "dtype": dtype, "machine": machine_info()}


def format_cost_table(r: dict, what: str) -> str:
    """The figures of `time_against_three_phase` as a text table; ``what``: e.g. ``"six-phase"``."""
    width = max(len(name) for name in r["drives"]) + 2
    lines = [
        f"{what} vs three-phase drive, book scenario ({r['duration_s']:g} s, {r['dtype']}), best of rounds",
        f"{'drive':{width}s} {'runs':>5s} {'run ms':>9s} {'compile s':>9s} {'us/period/run':>13s} "
        f"{'x three-phase':>13s}",
    ]
    for name, o in r["drives"].items():
        lines.append(
            f"{name:{width}s} {o['runs']:5d} {o['run_s'] * 1e3:9.2f} {o['compile_s']:9.2f} "
            f"{o['us_per_period']:13.3f} {o['vs_three_phase']:13.2f}"
        )
    m = r["machine"]
    lines.append("ratios: against the three-phase drive with the same bridge and batch")
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}, {m['backend']}")
    return "\n".join(lines)
