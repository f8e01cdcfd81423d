"""Observer tuning by gradients against Nelder-Mead on the same loss: time to equal cost.

Per observer (default ``smo`` and ``ekf``; ``--observers`` for others): the book FOC drive on the observer
behind the sensored warm-up
([`tuning.autotune.observers.observer_drive`][tuning.autotune.observers.observer_drive], 1 RK4 sub-step per
period), its default parameters (`tuning.autotune.observers.TUNABLE_OBSERVERS`) in log-space from the design
rule, the observer objective (speed ITAE + angle-error RMS) on ``make_observer_batch(BATCH, seed=0)``. Both
methods start from the design rule (theta = 0) with the same parameterisation and bounds
([`tuning.autotune.observers.OBSERVER_CONFIG`][tuning.autotune.observers.OBSERVER_CONFIG]):

1. Nelder-Mead ([`tuning.autotune.baselines.nelder_mead`][tuning.autotune.baselines.nelder_mead]:
   ``scipy.optimize.minimize(method= "Nelder-Mead")`` on one jit-compiled batch cost, simplex edge 0.5) with
   ``NM_EVALUATIONS`` evaluations;
2. the gradient tuner ([`tuning.autotune.tuner.tune`][tuning.autotune.tuner.tune], ``OBSERVER_CONFIG``: Adam,
   lr 0.1), every iteration's exact cost timestamped through its callback;
3. the wall time (compile excluded for both) at which each first reaches Nelder-Mead's best cost, and the
   ratio Nelder-Mead / gradient (no ratio when the tuner never reaches it).

``python -m benchmarks.bench_observer_tuning [--observers smo,ekf] [--json out.json]`` prints the table.
"""

import argparse
import dataclasses
import time

from benchmarks.bench_core import machine_info, publish
from tuning.autotune import tune
from tuning.autotune.baselines import nelder_mead
from tuning.autotune.job import DEFAULT_CONFIG
from tuning.autotune.objectives import ObjectiveWeights
from tuning.autotune.observers import OBSERVER_CONFIG, make_observer_batch, observer_drive, observer_tuning

BATCH = 32
NM_EVALUATIONS = 400


def time_to_reach(curve, target: float):
    """First wall time of ``curve [(wall_s, cost), ...]`` with ``cost <= target``; None if never."""
    return next((w for w, c in curve if c <= target), None)


def run_observer(name: str, batch_size: int = BATCH, nm_evaluations: int = NM_EVALUATIONS) -> dict:
    tuning = observer_tuning(name)
    drive = observer_drive(name, n_substeps=1)
    batch = make_observer_batch(batch_size, 0, kinds=("step",))
    weights = ObjectiveWeights(**tuning.weights)
    config = dataclasses.replace(DEFAULT_CONFIG, names=tuning.names, **OBSERVER_CONFIG)

    nm = nelder_mead(
        drive, batch, weights, tuning.names, max_evaluations=nm_evaluations, bounds=config.bounds
    )
    nm_curve = [(w, c) for _, w, c in nm.trace]

    stamps = []
    start = time.perf_counter()
    result = tune(
        drive,
        batch,
        weights,
        config,
        progress=False,
        callback=lambda it, cost: stamps.append((time.perf_counter() - start, float(cost))),
    )
    grad_curve = [(max(w - result.compile_time_s, 0.0), c) for w, c in stamps]
    t_grad = time_to_reach(grad_curve, nm.best_cost)
    t_nm = nm.time_to_best_s
    return {
        "observer": name,
        "parameters": list(tuning.names),
        "initial_cost": nm.initial_cost,
        "nelder_mead": {
            "best_cost": nm.best_cost,
            "evaluations": nm.evaluations,
            "time_to_best_s": t_nm,
            "wall_time_s": nm.wall_time_s,
            "seconds_per_evaluation": nm.wall_time_s / nm.evaluations,
            "compile_time_s": nm.compile_time_s,
            "time_to_reach_gradient_best_s": time_to_reach(nm_curve, result.best_cost),
        },
        "gradient": {
            "best_cost": result.best_cost,
            "iterations": result.iterations,
            "stopped": result.stopped,
            "wall_time_s": max(result.wall_time_s - result.compile_time_s, 0.0),
            "compile_time_s": result.compile_time_s,
            "seconds_per_iteration": (grad_curve[-1][0] - grad_curve[0][0]) / max(len(grad_curve) - 1, 1),
            "time_to_reach_nelder_mead_best_s": t_grad,
            "curve": grad_curve,
        },
        "speedup": (t_nm / t_grad) if t_grad else None,
    }


def format_table(results: dict) -> str:
    m = results["machine"]
    rows = [
        (
            "observer",
            "design cost",
            "NM best",
            "NM evals",
            "NM s to best",
            "grad best",
            "iters",
            "grad s to NM best",
            "speed-up",
        ),
    ]
    for r in results["observers"]:
        nm, g = r["nelder_mead"], r["gradient"]
        t = g["time_to_reach_nelder_mead_best_s"]
        rows.append(
            (
                r["observer"],
                f"{r['initial_cost']:.4f}",
                f"{nm['best_cost']:.4f}",
                str(nm["evaluations"]),
                f"{nm['time_to_best_s']:.1f}",
                f"{g['best_cost']:.4f}",
                str(g["iterations"]),
                "never" if t is None else f"{t:.1f}",
                "-" if r["speedup"] is None else f"{r['speedup']:.1f}x",
            )
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    head = (
        f"Observer tuning: gradient (Adam) vs Nelder-Mead, same loss, start and bounds; {results['batch']} "
        f"scenarios; wall s, compile excluded; {m['cpu']} ({m['cpu_count']} cores, {m['backend']})"
    )
    return "\n".join(
        [head] + [" | ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in rows]
    )


def main(json_path: str | None = None, observers=("smo", "ekf"), batch_size: int = BATCH) -> dict:
    results = {
        "batch": batch_size,
        "nm_evaluations": NM_EVALUATIONS,
        "observers": [run_observer(n, batch_size) for n in observers],
        "machine": machine_info(),
    }
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--observers", default="smo,ekf")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    main(args.json, tuple(args.observers.split(",")))
