"""Tuned chapter 6 gains (``pmsmjax tune --estimator hfi-rotating|hfi-pulsating|hybrid``) on the fixed
scenarios of ``pmsmjax compare --estimator``: design rule against tuned, outside the batches the
tuner saw.

The tuning drive ([`tuning.autotune.hfi_tuning`][tuning.autotune.hfi_tuning]) wraps the estimator in a
sensored warm-up (path ``estimator.observer.*``) and the hybrid there has no polarity detector; the compare
drive ([`pmsmjax.jobs.estimator_comparison.chapter6_drive`][pmsmjax.jobs.estimator_comparison.chapter6_drive])
holds the estimator at ``estimator.*`` and the hybrid's injection inside its polarity detector
(``estimator.injection.observer.*``). The gains are moved to those
paths (`compare_paths`). The hybrid also runs ``compare``'s book scenario (1000 r/min from
standstill, 10 N m step). Each run starts 30 electrical degrees off the estimate, no noise, on the
saturated salient plant (averaged bridge by default), and is scored by
[`pmsmjax.analysis.observer_errors.observer_errors`][pmsmjax.analysis.observer_errors.observer_errors] (modulo
pi for the injection estimators), as ``compare`` does.

    python -m benchmarks.hfi_tuned_check hfi-rotating=tune_hfi-rotating/gains.toml \
        hfi-pulsating=tune_hfi-pulsating/gains.toml [--bridge switching] [--json out.json]
"""

import argparse
import json
import math
import sys

import jax

from pmsmjax.analysis.observer_errors import observer_errors
from pmsmjax.jobs.control_comparison import ControllerCompareSettings, run_control, window_periods
from pmsmjax.jobs.estimator_comparison import (
    CHAPTER6_INITIAL_ANGLE_DEG,
    ESTIMATOR_SCENARIOS,
    chapter6_drive,
    estimator_family,
    estimator_scenario,
    run_estimator_scenario,
)
from tuning.parameters import read_gains_toml, set_leaves


def compare_paths(name: str, gains: dict) -> dict:
    """Gains of the tuning drive renamed to the paths of
    [`chapter6_drive`][pmsmjax.jobs.estimator_comparison.chapter6_drive]'s drive."""
    out = {}
    for path, value in gains.items():
        rest = path.removeprefix("estimator.observer.")
        if name == "hybrid" and rest.startswith("injection."):
            rest = "injection.observer." + rest.removeprefix("injection.")
        out["estimator." + rest] = value
    return out


def run(name: str, gains: dict | None, scenario: str, bridge: str, load_nm: float = 10.0) -> dict:
    drive = chapter6_drive(name, bridge=bridge)
    if gains:
        renamed = compare_paths(name, gains)
        drive = set_leaves(drive, list(renamed), list(renamed.values()))
        drive.estimator.check_period(drive.Ts)
    start = drive.init(theta_e=math.radians(CHAPTER6_INITIAL_ANGLE_DEG))
    if scenario == "book":  # as compare runs it: the settings' book scenario, lock judged on speed too
        settings = ControllerCompareSettings(bridge=bridge, load_nm=load_nm)
        window_periods(drive, settings)
        result = run_control(name, drive, settings, start)
    else:
        result = run_estimator_scenario(drive, estimator_scenario(scenario, load_nm), start)
    errors = observer_errors(
        result["trace"],
        drive.Ts,
        modulo_pi=estimator_family(name) == "injection",
        speed_lock=scenario == "book",
    )
    keep = ("angle_error_rms_deg", "angle_error_max_deg", "lock_lost")
    return {**{k: errors[k] for k in keep}, "itae": result["entry"]["itae"]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tuned", nargs="+", help="NAME=gains.toml")
    p.add_argument("--bridge", default="averaged", choices=("averaged", "switching"))
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    rows = {}
    print("| estimator | scenario | angle RMS deg, rule -> tuned | angle max deg | ITAE rad s | lock lost |")
    print("|---|---|---|---|---|---|")
    for item in args.tuned:
        name, path = item.split("=", 1)
        gains = read_gains_toml(path)
        family = estimator_family(name)
        for scenario, (_, families) in ESTIMATOR_SCENARIOS.items():
            if family not in families:
                continue
            before, after = run(name, None, scenario, args.bridge), run(name, gains, scenario, args.bridge)
            rows[f"{name}/{scenario}"] = {"before": before, "after": after}
            print(
                f"| {name} | {scenario} | {before['angle_error_rms_deg']:.3f} -> "
                f"{after['angle_error_rms_deg']:.3f} | {before['angle_error_max_deg']:.2f} -> "
                f"{after['angle_error_max_deg']:.2f} | {before['itae']:.4f} -> {after['itae']:.4f} | "
                f"{before['lock_lost']} -> {after['lock_lost']} |",
                flush=True,
            )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"bridge": args.bridge, "device": str(jax.devices()[0]), "rows": rows}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
