"""Cost of the HF-injection drives (chapter 6): the per-period cost of the salient book drive with
rotating or pulsating injection relative to the same drive with the exact sensor, in one run.

Each drive ([`pmsmjax.presets.sensorless_drive`][pmsmjax.assemble.sensorless_drive] with ``hfi-rotating`` /
``hfi-pulsating`` on the salient book motor, design-rule filters; the sensored
[`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive] on the same motor; averaged bridge, 10
RK4 sub-steps, float32 as the command line runs) simulates the same scenario: standstill, 10 N m load step at
a quarter of the run. The calls are timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]) so their ratios hold under a
varying machine load. The cost goal is <= 1.5x per period. Beside it, the same scan keeping only the speed per
period (no Trace record: the drive's arithmetic alone), and each estimator alone on the rotating drive's log
([`pmsmjax.recorded.offline_observer.observe`][pmsmjax.recorded.offline_observer.observe]; the rotating one
with the carrier read from the voltages, as ``pmsmjax observe`` runs it; the pulsating one for its cost only).

    python -m benchmarks.bench_hfi --json hfi.json
"""

import argparse

import jax

from benchmarks.bench_core import publish
from benchmarks.bench_observers import format_estimator_table, time_estimator_drives
from pmsmjax import presets, simulate
from pmsmjax.estimators import INJECTION_OBSERVERS, make_observer
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.recorded.offline_observer import observe
from pmsmjax.scenarios import Profile, Scenario

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("drives", "duration_s", "dtype", "machine")


def run(quick: bool = False) -> dict:
    """Time the sensored drive and both injection drives (``quick``: 0.02 s, 1 round; figures meaningless)."""
    duration = 0.02 if quick else 0.4
    reps = 1 if quick else 7
    motor = presets.book_motor(salient=True)
    scenario = Scenario(duration, Profile.constant(0.0), Profile.step(duration / 4, 0.0, 10.0))
    drives = {"sensored": presets.book_drive(motor)}
    drives.update({name: presets.sensorless_drive(name, motor) for name in INJECTION_OBSERVERS})
    # initial states built once, outside the timed calls (eager init is host work, not the scan's)
    states = {name: d.init(theta_e=0.3) for name, d in drives.items()}
    ts = drives["sensored"].Ts
    # the log for the offline run: the same run, its load profile with one more breakpoint so that this
    # call does not compile (and so hide) the timed drive's program
    log_scenario = Scenario(
        duration, Profile.constant(0.0), Profile.piecewise([0, duration / 4, duration / 2], [0, 10, 10])
    )
    rot = drives["hfi-rotating"]
    tr = simulate(rot, log_scenario, initial_state=states["hfi-rotating"])
    u_ab, i_ab = abc_to_alpha_beta(tr.u_abc), abc_to_alpha_beta(tr.i_abc)
    # the pulsating estimator runs on the same log for its cost only (offline it cannot steer the
    # injection axis of the log's drive, so its angle there means nothing)
    offline_estimators = {
        "hfi-rotating": make_observer("hfi-rotating", motor, ts, carrier="measured"),
        "hfi-pulsating": make_observer("hfi-pulsating", motor, ts),
    }
    offline = {
        name: (lambda o=o: jax.block_until_ready(observe(o, u_ab, i_ab, ts).theta_e))
        for name, o in offline_estimators.items()
    }
    return time_estimator_drives(drives, states, scenario, offline, reps)


def format_table(r: dict) -> str:
    title = "HF-injection drives, salient book motor, standstill + 10 N m step"
    return format_estimator_table(r, title, alone="estimator alone")


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(
        description="cost of the HF-injection drives relative to the sensored one"
    )
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
