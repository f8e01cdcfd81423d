"""``pmsmjax tune --control pi`` on the example drive files: how much the held-out speed ITAE drops from the
design rules ([`pmsmjax.spec.design_rules`][pmsmjax.spec.design_rules]) on drives other than the book's.

Per drive (servo-400w, industrial-5k6w, outer-rotor-24v; ``pmsmjax/presets/motors/``): the tune job
([`tuning.autotune.job.run_tune_job`][tuning.autotune.job.run_tune_job]) on batches from the file's
``[tuning]`` ranges, modest sizes (`SETTINGS`: 16 train / 32 held-out scenarios, 30 BFGS iterations, 1 RK4
sub-step while tuning; the industrial drive's 1.5-2.5 s scenarios at 5 kHz with fewer scenarios), then prints
the held-out ITAE before and after, its cut, the held-out scenarios over the current limit and the largest
peak current (against the file's limit), and the held-out nominal and worst-decile costs over plant draws from
the file's tolerances. The checks: at least a `MIN_CUT_PCT` % cut and no held-out scenario over the
limit.

The current limit sets a floor under the ITAE that no gains can cut (`current_limit_floor`): a
step to ``w`` takes at least ``t_a = J w / T_max`` at the limit's MTPA torque ``T_max``, and its error
falls at best linearly over it, ``ITAE >= w t_a^2 / 6`` (friction and the load step only add to it).
The benchmark prints the floor and the cut of the ITAE above it.

``python -m benchmarks.user_drive_tuning [--drives servo-400w,...] [--iterations 30] [--robust]
[--json out.json]`` (``--robust``: trained over plant draws from the tolerances).
"""

import argparse
import tempfile
import time

import numpy as np

from benchmarks.bench_core import write_json_atomic
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.spec.design_rules import torque_at_current
from tuning.autotune.drive_batches import drive_batches
from tuning.autotune.job import DEFAULT_CONFIG, run_tune_job

#: Per drive: train and held-out scenarios, RK4 sub-steps of the before/after figures.
SETTINGS = {
    "servo-400w": dict(n_train=16, n_heldout=32, eval_substeps=4),
    "industrial-5k6w": dict(n_train=8, n_heldout=16, eval_substeps=2),
    "outer-rotor-24v": dict(n_train=16, n_heldout=32, eval_substeps=4),
}
MIN_CUT_PCT = 25.0


def current_limit_floor(spec, n: int, seed: int = 1) -> float:
    """Mean over the held-out batch (``n`` scenarios of ``seed``) of the ITAE floor of a step at the
    current limit's torque, rad s (module docstring)."""
    batches = drive_batches(spec)
    batch = batches.make(n, seed, duration_s=batches.duration_s)
    w = np.abs(np.asarray(batch.scenarios.speed_ref.values[:, -1]))
    t_a = spec.motor["J"] * w / torque_at_current(spec.motor, spec.current_limit_a)
    return float(np.mean(w * t_a**2 / 6.0))


def tune_drive(name: str, iterations: int, **overrides) -> dict:
    """One tune job on drive ``name``; the figures the benchmark prints."""
    import dataclasses

    spec = drive_spec(name)
    settings = {**SETTINGS[name], **overrides}
    config = dataclasses.replace(DEFAULT_CONFIG, max_iterations=iterations)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        data = run_tune_job(out, drive=spec, config=config, progress=False, tune_substeps=1, **settings)
    wall = time.perf_counter() - start
    ho = data["heldout"]
    before, after = ho["before"]["itae"], ho["after"]["itae"]
    r = data["robustness"]
    floor = current_limit_floor(spec, settings["n_heldout"])
    return {
        "drive": name,
        **settings,
        "iterations": data["iterations"],
        "stopped": data["stopped"],
        "heldout_itae_before": before,
        "heldout_itae_after": after,
        "cut_pct": 100.0 * (1.0 - after / before),
        "current_limit_floor_itae": floor,
        "cut_above_floor_pct": 100.0 * (1.0 - (after - floor) / (before - floor)),
        "current_limit_a": spec.current_limit_a,
        "max_peak_current_a": {k: ho[k]["max_peak_current_a"] for k in ("before", "after")},
        "heldout_over_limit": {k: ho[k]["scenarios_over_current_limit"] for k in ("before", "after")},
        "max_current_excess_a": {
            k: max(s["current_excess_a"] for s in ho[k]["per_scenario"]) for k in ("before", "after")
        },
        "heldout_overshoot_pct": {k: ho[k]["overshoot_pct"] for k in ("before", "after")},
        "voltage_saturation": {k: ho[k]["voltage_saturation"] for k in ("before", "after")},
        "nominal_cost": r["nominal_cost"],
        "worst_decile_cost": r["worst_decile_cost"],
        "gains": data["gains"],
        "wall_s": wall,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--drives", default=",".join(SETTINGS))
    p.add_argument("--iterations", type=int, default=30)
    p.add_argument("--robust", action="store_true", help="train over plant draws from the tolerances")
    p.add_argument("--json", default=None, help="write the rows to this JSON file")
    args = p.parse_args(argv)
    rows = []
    for name in args.drives.split(","):
        row = tune_drive(name, args.iterations, robust=args.robust)
        rows.append(row)
        ok = row["cut_pct"] >= MIN_CUT_PCT and row["heldout_over_limit"]["after"] == 0
        print(
            f"{name}: held-out ITAE {row['heldout_itae_before']:.5g} -> "
            f"{row['heldout_itae_after']:.5g} rad s "
            f"({row['cut_pct']:.1f} % cut; current-limit floor {row['current_limit_floor_itae']:.3g}, "
            f"{row['cut_above_floor_pct']:.1f} % of the ITAE above it cut), over the "
            f"{row['current_limit_a']:g} A limit "
            f"{row['heldout_over_limit']['before']} -> {row['heldout_over_limit']['after']} of "
            f"{row['n_heldout']} (peak {row['max_peak_current_a']['before']:.2f} -> "
            f"{row['max_peak_current_a']['after']:.2f} A, largest excess "
            f"{row['max_current_excess_a']['after']:.2g} A); cost nominal "
            f"{row['nominal_cost']['before']:.4g} -> "
            f"{row['nominal_cost']['after']:.4g}, worst decile {row['worst_decile_cost']['before']:.4g} -> "
            f"{row['worst_decile_cost']['after']:.4g}; {row['iterations']} iterations ({row['stopped']}), "
            f"{row['wall_s']:.0f} s: {'ok' if ok else 'CHECK FAILED'}",
            flush=True,
        )
    if args.json:
        write_json_atomic(args.json, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
