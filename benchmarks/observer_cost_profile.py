"""Where the per-period cost of a sensorless drive goes (the cost goal: <= 1.5x the sensored drive).

The same drive scan ([`pmsmjax.simulate`][pmsmjax.simulate.simulate]'s checkpointed drive step from a flying
start at 1000 r/min, 10 N m load step half way) is timed with different per-period outputs, for run lengths of
``--durations`` seconds, interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved], best of
``--reps``):

- ``none``: no per-period output (the final state only): what the drive's arithmetic costs;
- ``speed``: the speed only;
- ``packed``: the packed record row (``ravel_pytree`` of
  [`pmsmjax.drive.PeriodRecord`][pmsmjax.drive.PeriodRecord]), as ``simulate`` writes it, without deriving the
  Trace afterwards;
- ``separate``: the packed row without the estimate, and the estimate ``(2,)`` as a second scan output;
- ``blocked``: the same rows written by an inner scan of 100 periods inside an outer scan (does the size
  of the buffer the row goes into matter?);
- ``simulate``: [`pmsmjax.simulate`][pmsmjax.simulate.simulate] itself (rows, then the Trace).

Plus ``dup``: the sensored drive whose record also carries the plant's own angle and speed as an
"estimate" (what a pass-through estimator records), to separate recording from observing.

    python -m benchmarks.observer_cost_profile --durations 0.1,0.8 --observers smo,ekf
"""

import argparse

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from benchmarks.bench_core import time_interleaved
from benchmarks.bench_observers import running_start
from pmsmjax import presets, simulate
from pmsmjax.drive import Drive, PeriodRecord
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import period_inputs
from pmsmjax.units import rpm_to_rad_s

MODES = ("none", "speed", "packed", "separate", "blocked", "simulate")


class DuplicatingDrive(Drive):
    """The drive, recording the plant's angle and speed a second time as if they were an estimate."""

    def step(self, state, x):
        state, rec = Drive.step(self, state, x)
        ms = rec.machine
        return state, PeriodRecord(
            ms, rec.duties, rec.u_dq_ref, rec.i_dq_ref, jnp.stack([ms.theta_e, ms.omega_m])
        )


def duplicating(drive: Drive) -> Drive:
    d = drive
    return DuplicatingDrive(
        d.machine, d.controller, d.modulator, d.bridge, d.Ts, d.n_substeps, d.computation_delay, d.estimator
    )


def scan_with(mode: str):
    """A jitted ``(drive, state, xs) -> output`` for one of the `MODES` other than simulate."""

    @eqx.filter_jit
    def run(drive, state, xs):
        step = jax.checkpoint(lambda d, s, x: d.step(s, x))

        def body(s, x):
            s, rec = step(drive, s, x)
            if mode == "none":
                return s, None
            if mode == "speed":
                return s, rec.machine.omega_m
            if mode == "separate":
                rest = PeriodRecord(rec.machine, rec.duties, rec.u_dq_ref, rec.i_dq_ref, None)
                return s, (ravel_pytree(rest)[0], rec.estimate)
            return s, ravel_pytree(rec)[0]

        if mode == "none":
            return jax.lax.scan(body, state, xs)[0]
        if mode == "blocked":
            blocks = jax.tree.map(lambda a: a.reshape((-1, 100) + a.shape[1:]), xs)
            _, rows = jax.lax.scan(lambda c, xb: jax.lax.scan(body, c, xb), state, blocks)
            return rows.reshape((-1,) + rows.shape[2:])
        return jax.lax.scan(body, state, xs)[1]

    return run


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--durations", default="0.1,0.8", help="run lengths, s (multiples of 0.01 s)")
    p.add_argument("--observers", default="smo,ekf")
    p.add_argument("--reps", type=int, default=12)
    p.add_argument("--modes", default=",".join(MODES))
    args = p.parse_args(argv)
    w = rpm_to_rad_s(1000.0)
    base = presets.book_drive()
    drives = {"sensored": base, "dup": duplicating(base)}
    drives.update({n: presets.sensorless_drive(n) for n in args.observers.split(",")})
    for duration in (float(x) for x in args.durations.split(",")):
        scenario = Scenario(duration, Profile.constant(w), Profile.step(duration / 2, 0.0, 10.0))
        xs = period_inputs(scenario, base.Ts)
        calls = {}
        modes = args.modes.split(",")
        for mode in modes:
            fn = scan_with(mode) if mode != "simulate" else None
            for name, d in drives.items():
                s = running_start(d, w)
                if fn is None:
                    calls[name, mode] = lambda d=d, s=s, sc=scenario: jax.block_until_ready(
                        simulate(d, sc, initial_state=s)
                    )
                else:
                    calls[name, mode] = lambda d=d, s=s, fn=fn, xs=xs: jax.block_until_ready(fn(d, s, xs))
        _, best = time_interleaved(calls, args.reps)
        periods = xs.speed_ref.shape[0]
        print(f"\n{duration:g} s ({periods} periods): us per period (x the sensored drive with no output)")
        print(f"{'drive':10s}" + "".join(f"{m:>18s}" for m in modes))
        ref = best["sensored", modes[0]]
        for name in drives:
            cells = [f"{1e6 * best[name, m] / periods:8.2f} ({best[name, m] / ref:4.2f}x)" for m in modes]
            print(f"{name:10s}" + "".join(f"{c:>18s}" for c in cells))


if __name__ == "__main__":
    main()
