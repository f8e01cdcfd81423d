"""Where a ``simulate`` call's time goes on XLA:CPU, and whether the loop body's size still matters.

XLA:CPU's runtime once ran a loop body sequentially on the calling thread only when every buffer the
body touched was at most 512 bytes, and otherwise ran its kernels as a task graph on the thread pool,
whose hand-offs cost a drive step (kernels on scalars) more than its arithmetic: a flat scan over the
periods, which slices the whole inputs and writes the whole record, was never sequential, and the
engine cut its scan into blocks of periods. With the loop limit [`pmsmjax.xla_cpu`][pmsmjax.xla_cpu] sets, a
period's loops compile into one kernel each and the block length no longer changes the time; this benchmark is
how to see that again on another machine or jax version. Two tables, every call timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved], best of
``--reps``), float32 unless x64 is enabled:

1. **book drive against the hand loop** (`benchmarks.minimal_loop`, literal constants), 4000 periods
   from rest: the hand loop; ``simulate``; the engine's scan keeping only the speed (its arithmetic); the
   engine's step recording the packed row in one flat scan.
2. **block length sweep**: the sensored drive (11-element record row) and the ``--observers`` drives
   (13 elements: the estimate too) from a flying start at 1000 r/min, 10 N m load step half way, each
   recording the packed row (``ravel_pytree`` of the record, as ``simulate`` writes it) in blocks of
   ``--blocks`` periods; the header gives ``B * row bytes`` for each, and the speed-only scan (4-byte
   rows) is the arithmetic the record adds to.

    python -m benchmarks.engine_cost_profile --observers smo,mras --blocks 1,8,10,20,100
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from benchmarks.bench_core import time_interleaved
from benchmarks.bench_observers import running_start, speed_only
from benchmarks.minimal_loop import make_minimal_loop
from pmsmjax import presets, simulate
from pmsmjax.jobs import bench as engine_timing
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import period_inputs
from pmsmjax.units import rpm_to_rad_s


def step_scan(block: int, keep: str):
    """A jitted ``(drive, state, xs) -> per-period output`` of the engine's checkpointed drive step, in
    blocks of ``block`` periods (1: one flat scan). ``keep``: ``"speed"`` (the speed, one scalar per
    period) or ``"record"`` (the packed record row, as ``simulate`` writes it)."""

    @eqx.filter_jit
    def run(drive, state, xs):
        step = jax.checkpoint(lambda d, s, x: d.step(s, x))

        def body(s, x):
            s, rec = step(drive, s, x)
            return s, rec.machine.omega_m if keep == "speed" else ravel_pytree(rec)[0]

        if block == 1:
            return jax.lax.scan(body, state, xs)[1]
        blocks = jax.tree.map(lambda a: a.reshape((-1, block) + a.shape[1:]), xs)
        rows = jax.lax.scan(lambda c, xb: jax.lax.scan(body, c, xb), state, blocks)[1]
        return rows.reshape((-1,) + rows.shape[2:])

    return run


def row_bytes(drive, state, xs) -> int:
    """Bytes of one packed record row of ``drive``."""
    rec = jax.eval_shape(drive.step, state, jax.tree.map(lambda a: a[0], xs))[1]
    leaves = jax.tree.leaves(rec)
    return sum(leaf.size for leaf in leaves) * jnp.result_type(*leaves).itemsize


def book_against_hand_loop(reps: int) -> None:
    drive, scenario = engine_timing.book_problem(engine_timing.FULL)
    xs = period_inputs(scenario, drive.Ts)
    state = drive.init()
    hand_loop = make_minimal_loop(Ts=drive.Ts, n_sub=drive.n_substeps)
    flat_record = step_scan(1, "record")
    calls = {
        "hand loop": lambda: hand_loop(xs.speed_ref, xs.load_torque),
        "simulate": lambda: simulate(drive, scenario),
        "engine scan, speed only": lambda: speed_only(drive, state, xs),
        "engine step, record in a flat scan": lambda: flat_record(drive, state, xs),
    }
    _, best = time_interleaved(calls, reps)
    ref = best["hand loop"]
    periods = xs.speed_ref.shape[0]
    print(f"book drive, {periods} periods, {jnp.result_type(float)} (x the hand loop)")
    for name, t in best.items():
        print(f"  {name:40s} {1e3 * t:7.2f} ms {1e6 * t / periods:6.2f} us/period ({t / ref:4.2f}x)")


def block_sweep(observers: list[str], blocks: list[int], reps: int) -> None:
    w = rpm_to_rad_s(1000.0)
    scenario = Scenario(0.4, Profile.constant(w), Profile.step(0.2, 0.0, 10.0))
    drives = {"sensored": presets.book_drive()}
    drives.update({name: presets.sensorless_drive(name) for name in observers})
    xs = period_inputs(scenario, drives["sensored"].Ts)
    scans = {b: step_scan(b, "record") for b in blocks}
    calls, sizes = {}, {}
    for name, d in drives.items():
        s = running_start(d, w)
        sizes[name] = row_bytes(d, s, xs)
        calls[name, "speed only"] = lambda d=d, s=s: speed_only(d, s, xs)
        calls[name, "simulate"] = lambda d=d, s=s: simulate(d, scenario, initial_state=s)
        for b, fn in scans.items():
            calls[name, b] = lambda d=d, s=s, fn=fn: fn(d, s, xs)
    _, best = time_interleaved(calls, reps)
    periods = xs.speed_ref.shape[0]
    cols = ["speed only", "simulate", *blocks]
    print(f"\nrecord in blocks of B periods, {periods} periods: us per period [B * row bytes]")
    print(f"{'drive':10s} {'row B':>5s}" + "".join(f"{str(c):>14s}" for c in cols))
    for name in drives:
        cells = []
        for c in cols:
            size = f"[{c * sizes[name]}]" if isinstance(c, int) else ""
            cells.append(f"{1e6 * best[name, c] / periods:6.2f} {size:>7s}")
        print(f"{name:10s} {sizes[name]:5d}" + "".join(f"{cell:>14s}" for cell in cells))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--observers", default="smo,mras")
    p.add_argument("--blocks", default="1,8,10,20,100", help="block lengths (divisors of 4000)")
    p.add_argument("--reps", type=int, default=20)
    args = p.parse_args(argv)
    book_against_hand_loop(args.reps)
    block_sweep(args.observers.split(","), [int(b) for b in args.blocks.split(",")], args.reps)


if __name__ == "__main__":
    main()
