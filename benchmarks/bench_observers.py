"""Cost of each chapter 5 observer: the sensorless drive's per-period cost relative to the sensored book
drive, and the observer alone on a log (``pmsmjax observe``), in one run.

Every drive of [`pmsmjax.presets.sensorless_drive`][pmsmjax.assemble.sensorless_drive] (design-rule gains,
averaged bridge, 10 RK4 sub-steps, float32 as the command line runs) and the sensored
[`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive] simulate the same scenario: started at
1000 r/min (the observer cold, a flying start; the speed loop's integral set as if it had been running), 10 N
m load step half way. The calls are timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]) so their ratios hold under a
varying machine load. The cost goal is <= 1.5x per period. Two diagnostics beside it: the same drive scan
keeping only the speed per period (no Trace record: what the drive's arithmetic costs), and
[`pmsmjax.recorded.offline_observer.observe`][pmsmjax.recorded.offline_observer.observe] over the sensored
run's log (the observer's own cost per sample, without the plant).

    python -m benchmarks.bench_observers --json observers.json
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.estimators import OBSERVERS
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.recorded.offline_observer import observe
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import period_inputs
from pmsmjax.units import rpm_to_rad_s

__all__ = ["run", "main", "format_table", "speed_only", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("drives", "duration_s", "dtype", "machine")


def running_start(drive, speed_rad_s: float):
    """The drive's state at ``speed_rad_s`` (mechanical) with the speed PI's integral where it would be
    after running there unloaded (else the active-damping term brakes hard at the first period)."""
    motor = drive.machine.motor
    state = drive.init(speed_m=speed_rad_s, theta_e=1.0)
    damping = drive.controller.speed.active_damping
    integral = motor.B * speed_rad_s / motor.torque_constant + damping * speed_rad_s
    return eqx.tree_at(
        lambda s: s.controller.speed, state, jnp.asarray(integral, state.machine.omega_m.dtype)
    )


@eqx.filter_jit
def speed_only(drive, state, xs):
    """The simulate scan (checkpointed drive step) recording only the speed: the drive's arithmetic."""
    step = jax.checkpoint(lambda d, s, x: d.step(s, x))

    def body(s, x):
        s, record = step(drive, s, x)
        return s, record.machine.omega_m

    return jax.lax.scan(body, state, xs)[1]


def run(quick: bool = False, names=tuple(OBSERVERS)) -> dict:
    """Time the sensored drive and each observer's drive (``quick``: 0.02 s, 1 round; figures meaningless)."""
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 7
    w = rpm_to_rad_s(1000.0)
    scenario = Scenario(duration, Profile.constant(w), Profile.step(duration / 2, 0.0, 10.0))
    drives = {"sensored": presets.book_drive()}
    drives.update({name: presets.sensorless_drive(name) for name in names})
    states = {name: running_start(d, w) for name, d in drives.items()}
    # The observers alone on the sensored run's log (the observer's state machine, no plant).
    tr = simulate(drives["sensored"], scenario, initial_state=states["sensored"])
    u_ab, i_ab = abc_to_alpha_beta(tr.u_abc), abc_to_alpha_beta(tr.i_abc)
    ts = drives["sensored"].Ts
    offline = {
        name: (lambda o=drives[name].estimator: jax.block_until_ready(observe(o, u_ab, i_ab, ts).theta_e))
        for name in names
    }
    return time_estimator_drives(drives, states, scenario, offline, reps)


def time_estimator_drives(drives: dict, states: dict, scenario, offline: dict, reps: int) -> dict:
    """Time ``drives`` (``{"sensored": drive, name: drive, ...}``) on ``scenario`` from ``states``, each
    also as the bare scan recording only the speed, and the ``offline`` calls (``{name: estimator alone on
    a log}``), interleaved; every estimator drive's figures are also given relative to ``sensored``.

    **Returns:** ``{"drives": {name: {run_s, compile_s, us_per_period, speed_only_us_per_period,
    per_period_vs_sensored, speed_only_vs_sensored, offline_us_per_sample, offline_compile_s}},
    "duration_s", "periods", "dtype", "machine"}``.
    """
    ts = drives["sensored"].Ts
    xs = period_inputs(scenario, ts)
    calls = {
        name: (lambda d=d, s=states[name]: jax.block_until_ready(simulate(d, scenario, initial_state=s)))
        for name, d in drives.items()
    }
    bare = {
        f"{name} (speed only)": (lambda d=d, s=states[name]: jax.block_until_ready(speed_only(d, s, xs)))
        for name, d in drives.items()
    }
    alone = {f"{name} (offline)": call for name, call in offline.items()}
    first, best = time_interleaved({**calls, **bare, **alone}, reps)
    periods = round(scenario.duration_s / ts)
    out = {}
    for name in drives:
        out[name] = {
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "us_per_period": 1e6 * best[name] / periods,
            "speed_only_us_per_period": 1e6 * best[f"{name} (speed only)"] / periods,
        }
    for name in drives:
        if name == "sensored":
            continue
        out[name]["per_period_vs_sensored"] = out[name]["us_per_period"] / out["sensored"]["us_per_period"]
        out[name]["speed_only_vs_sensored"] = (
            out[name]["speed_only_us_per_period"] / out["sensored"]["speed_only_us_per_period"]
        )
        if name in offline:
            key = f"{name} (offline)"
            out[name]["offline_us_per_sample"] = 1e6 * best[key] / periods
            out[name]["offline_compile_s"] = compile_time(first[key], best[key])
    return {
        "drives": out,
        "duration_s": scenario.duration_s,
        "periods": periods,
        "dtype": str(jnp.result_type(float)),
        "machine": machine_info(),
    }


def format_estimator_table(r: dict, title: str, alone: str = "observer alone") -> str:
    """The figures of `time_estimator_drives` as a text table, headed by ``title``."""
    head = f"{alone} us/sample"
    w = len(head)
    lines = [
        f"{title} ({r['duration_s']:g} s, {r['periods']} periods, {r['dtype']}), best of rounds",
        f"{'drive':14s} {'run ms':>8s} {'compile s':>9s} {'us/period':>9s} {'x sensored':>10s} "
        f"{'speed-only us/period':>20s} {'x sensored':>10s} {head:>{w}s}",
    ]
    for name, c in r["drives"].items():
        ratio = c.get("per_period_vs_sensored", 1.0)
        bare = c.get("speed_only_vs_sensored", 1.0)
        cell = f"{c['offline_us_per_sample']:{w}.3f}" if "offline_us_per_sample" in c else f"{'-':>{w}s}"
        lines.append(
            f"{name:14s} {c['run_s'] * 1e3:8.2f} {c['compile_s']:9.2f} {c['us_per_period']:9.2f} "
            f"{ratio:10.2f} {c['speed_only_us_per_period']:20.2f} {bare:10.2f} {cell}"
        )
    m = r["machine"]
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}, {m['backend']}")
    return "\n".join(lines)


def format_table(r: dict) -> str:
    return format_estimator_table(r, "sensorless drives, 1000 r/min flying start + 10 N m step")


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="cost of each sensorless drive relative to the sensored one")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
