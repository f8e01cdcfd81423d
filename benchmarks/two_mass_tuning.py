"""A speed PI with a notch, tuned by gradients over a spread of shaft resonances, against the design-rule
loop, on a two-mass servo axis (the servo-two-mass preset: 200 Hz resonance, 115 Hz anti-resonance, load
inertia twice the rotor's).

Gain sets:

- ``design rules``: the preset as it is: the speed PI with active damping designed for the total inertia at
  the file's speed bandwidth, no filters;
- ``rules + notch``: the same PI with a notch at the nominal resonance (200 Hz, 100 Hz wide, 20 dB) and a
  1 kHz low-pass on the speed feedback, untuned (the tuning's starting point);
- ``tuned PI only``: the same tuning of the PIs alone on the file without filters (what the filters add);
- ``tuned``: ``pmsmjax tune --robust`` of the speed PI, the current PI and the filters (notch centre, width,
  depth, low-pass cut-off) over training scenarios whose plants are drawn from the file's ``[tolerances]``:
  the shaft stiffness +-40 % (the resonance +-20 %), load inertia +-10 %, ``J`` +-5 %, ``R`` +-10 %,
  ``psi_f`` +-5 %;
- ``tuned, PM >= X``: the same with ``--min-phase-margin-deg X`` (both loops' phase margin, linearised at
  the ``[tuning]`` ranges' middle speed and load, at least X on every training plant).

Every set's margins: both loops linearised at that operating point on the nominal plant, and the smallest
phase margin and largest sensitivity peak over the held-out plant draws.

The preset's ``[tuning]`` ranges (steps of 60-600 r/min, loads of 0.2-1.27 N m) keep the moves inside the
current limit, where the loop's bandwidth, and so the shaft, sets the ITAE.

Each set runs the same held-out scenarios (the tune job's held-out seed 1, plants drawn from the same
tolerances, scenarios the tuning never trained on) on the exact model (10 RK4 sub-steps): batch-mean ITAE and
cost. Then ``pmsmjax montecarlo`` runs each set on ``--mc`` draws of the tolerances (the file's [scenario]:
a rated-speed step, then 80 % of the rated torque): failure rates (divergence, current limit, settling).

The Monte Carlo runs also linearise every draw (``--linear-stability``): a draw whose linearised loop has a
spectral radius >= 1 counts as the failure ``unstable_linearisation``.

``python -m benchmarks.two_mass_tuning [--iterations 60] [--train 16] [--eval 32] [--mc 1000] [--min-pm 40]
[--json FILE]``
"""

import argparse
import json
import time
from pathlib import Path

from benchmarks.bench_core import machine_info, publish
from pmsmjax.cli import main as pmsmjax
from pmsmjax.io.drive_files import preset_path, write_drive_file
from pmsmjax.io.toml_parser import read_toml

PRESET = "servo-two-mass"
#: The untuned filters: a notch at the nominal resonance, half as wide, 20 dB deep, and a low-pass at five
#: times the resonance on the speed feedback.
START_FILTERS = {
    "speed_filter_hz": 1000.0,
    "notch_hz": 200.0,
    "notch_width_hz": 100.0,
    "notch_depth_db": 20.0,
}


def drive_file(path: Path, filters: dict | None) -> Path:
    """The preset written to ``path``, with ``filters`` (``[control]`` keys) added."""
    source = preset_path(PRESET)
    tables = {k: dict(v) for k, v in read_toml(source, str(source)).items()}
    tables["control"].update(filters or {})
    write_drive_file(path, tables, header=f"{PRESET}{' with speed-loop filters' if filters else ''}")
    return path


def tune(path: Path, out: Path, train: int, iterations: int, extra: tuple = ()) -> float:
    """``pmsmjax tune --robust`` (and the ``extra`` flags) on ``path`` into ``out``; returns its wall time,
    s."""
    argv = ["tune", "--motor", str(path), "--robust", "--train", str(train), "--heldout", "8", *extra]
    argv += ["--iterations", str(iterations), "--no-progress", "--out", str(out)]
    start = time.perf_counter()
    if pmsmjax(argv) != 0:
        raise SystemExit(f"tune {path} failed")
    return time.perf_counter() - start


def evaluate_sets(sets: dict, n_eval: int) -> dict:
    """``{name: figures}`` of each ``{name: (drive file, gains.toml or None)}`` on ``n_eval`` held-out
    scenarios (seed 1) with plants drawn from the file's tolerances, on the exact model."""
    import dataclasses

    import jax
    import numpy as np

    from pmsmjax.analysis.margins import drive_margins
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec
    from tuning.autotune import drive_scaling
    from tuning.autotune.controls import control_tuning
    from tuning.autotune.drive_batches import drive_batches
    from tuning.autotune.job import evaluate
    from tuning.autotune.margin_constraints import margin_operating_point, plant_margins
    from tuning.autotune.objectives import ObjectiveWeights, scaled_plant
    from tuning.parameters import apply_gains

    out = {}
    for name, (path, gains) in sets.items():
        spec = drive_spec(str(path))
        weights = drive_scaling.scaled_weights(
            ObjectiveWeights(**control_tuning("pi", "three-phase").weights), spec
        )
        batches = drive_batches(spec)
        batch = batches.make(
            n_eval, 1, duration_s=batches.duration_s, kinds=("step",),
            plant_spread=drive_scaling.plant_spread(spec),
        )  # fmt: skip
        drive = spec_drive(spec, "pi", n_substeps=10)
        drive = drive if gains is None else apply_gains(drive, str(gains))
        s = evaluate(drive, batch, weights)["summary"]
        keys = ("itae", "cost", "max_peak_current_a", "max_overshoot_pct", "scenarios_over_current_limit")
        out[name] = {k: s[k] for k in keys}
        speed, load = margin_operating_point(spec)
        point = dataclasses.replace(weights, margin_speed_rad_s=speed, margin_load_nm=load)
        m = jax.device_get(plant_margins(drive, batch, point, scaled_plant))
        out[name]["margins_nominal"] = drive_margins(drive, speed, load)
        out[name]["margins_worst_heldout"] = {
            loop: {
                "phase_margin_deg": float(np.min(v.phase_margin_deg)),
                "sensitivity_peak": float(np.max(v.sensitivity_peak)),
            }
            for loop, v in m.items()
        }
    return out


def montecarlo(path: Path, gains: Path | None, n: int, out: Path) -> dict:
    """``pmsmjax montecarlo`` of ``n`` draws of the file's tolerances; its failure rates and wall time."""
    argv = ["montecarlo", "--motor", str(path), "--n", str(n), "--out", str(out), "--no-figures"]
    argv += ["--no-progress", "--sensitivity-runs", "0", "--linear-stability"]
    argv += ["--gains", str(gains)] if gains else []
    start = time.perf_counter()
    if pmsmjax(argv) != 0:
        raise SystemExit(f"montecarlo {path} failed")
    summary = json.loads((out / "summary.json").read_text())
    rates = {k: v["rate"] for k, v in summary["failures"].items() if isinstance(v, dict) and "rate" in v}
    drawn = sorted(summary["parameters"])
    return {
        "failure_rates": rates,
        "max_spectral_radius": summary.get("max_spectral_radius"),
        "linear_stability_s": summary.get("linear_stability_time_s"),
        "parameters": drawn,
        "wall_s": time.perf_counter() - start,
    }


def run(iterations: int, train: int, n_eval: int, n_mc: int, folder: Path, min_pm: float = 40.0) -> dict:
    rule = drive_file(folder / "rules.toml", None)
    notch = drive_file(folder / "notch.toml", START_FILTERS)
    seconds = {"tune": tune(notch, folder / "tune", train, iterations)}
    seconds["tune without filters"] = tune(rule, folder / "tune_pi", train, iterations)
    pm_flags = ("--min-phase-margin-deg", f"{min_pm:g}")
    seconds["tune with PM constraint"] = tune(notch, folder / "tune_pm", train, iterations, pm_flags)
    gains = folder / "tune" / "gains.toml"
    sets = {
        "design rules": (rule, None),
        "rules + notch": (notch, None),
        "tuned PI only": (rule, folder / "tune_pi" / "gains.toml"),
        "tuned": (notch, gains),
        f"tuned, PM >= {min_pm:g}": (notch, folder / "tune_pm" / "gains.toml"),
    }
    start = time.perf_counter()
    table = evaluate_sets(sets, n_eval)
    seconds["evaluation"] = time.perf_counter() - start
    result = json.loads((folder / "tune" / "result.json").read_text())
    mc = {}
    if n_mc:
        for name, (path, g) in sets.items():
            mc[name] = montecarlo(path, g, n_mc, folder / f"mc_{name.replace(' ', '_').replace('+', '')}")
    return {
        "preset": PRESET,
        "iterations": iterations,
        "train": train,
        "eval": n_eval,
        "montecarlo_runs": n_mc,
        "heldout": table,
        "gains": result["gains"],
        "gains_constrained": json.loads((folder / "tune_pm" / "result.json").read_text())["gains"],
        "min_phase_margin_deg": min_pm,
        "montecarlo": mc,
        "seconds": seconds,
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    lines = [
        f"{'gain set':<18}{'ITAE rad s':>12}{'cost':>10}{'peak A':>9}{'overshoot %':>13}"
        f"{'PM spd':>8}{'Ms spd':>8}{'worst PM':>10}{'worst Ms':>10}{'PM cur':>8}"
    ]
    for name, s in r["heldout"].items():
        nom, worst = s["margins_nominal"], s["margins_worst_heldout"]
        lines.append(
            f"{name:<18}{s['itae']:>12.4g}{s['cost']:>10.4g}{s['max_peak_current_a']:>9.3g}"
            f"{s['max_overshoot_pct']:>13.3g}{nom['speed']['phase_margin_deg']:>8.1f}"
            f"{nom['speed']['sensitivity_peak']:>8.2f}{worst['speed']['phase_margin_deg']:>10.1f}"
            f"{worst['speed']['sensitivity_peak']:>10.2f}{nom['current']['phase_margin_deg']:>8.1f}"
        )
    for name, m in r["montecarlo"].items():
        lines.append(f"Monte Carlo {name}: {m['failure_rates']}")
    lines.append("gains: " + ", ".join(f"{k.split('.')[-1]} {v:.4g}" for k, v in r["gains"]["after"].items()))
    return "\n".join(lines)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--iterations", type=int, default=60)
    p.add_argument("--train", type=int, default=16)
    p.add_argument("--eval", type=int, default=32)
    p.add_argument("--mc", type=int, default=1000)
    p.add_argument(
        "--min-pm", type=float, default=40.0, help="phase-margin floor of the constrained set, deg"
    )
    p.add_argument("--folder", default="two_mass_tuning_out")
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    folder = Path(a.folder)
    folder.mkdir(parents=True, exist_ok=True)
    results = run(a.iterations, a.train, a.eval, a.mc, folder, a.min_pm)
    return publish(results, format_table(results), a.json)


if __name__ == "__main__":
    main()
