"""Gradient tuning against derivative-free search on the same objective: cost reached vs wall time.

One process, one problem: the book drive with 1 RK4 sub-step per period (4e-7 of peak current from
scipy at 10 kHz), the 7 FOC gains in log-space from the design-rule gains, bounds 0.05-20x, a batch of
64 speed-step scenarios (``make_batch(64, seed=0)``) and the default
[`ObjectiveWeights`][tuning.autotune.objectives.ObjectiveWeights] (batch-mean ITAE + L1 penalties). On it:

1. the design-rule cost (the common starting point);
2. Nelder-Mead ([`tuning.autotune.baselines.nelder_mead`][tuning.autotune.baselines.nelder_mead]) with 2000
   evaluations, and CMA-ES with the same budget when the optional package ``cma`` is installed: best cost,
   wall time, time to its best, the best-so-far curve against wall time;
3. the gradient tuner ([`tuning.autotune.tuner.tune`][tuning.autotune.tuner.tune]) with Adam (up to 300
   iterations, its default stopping rules) and with ``method="bfgs"`` (up to 60 iterations; its default
   penalty rounding, 1 % overshoot and 0.1 A, and a sweep of the rounding widths, exact included, to show how
   much the outcome depends on them), every iteration's exact cost timestamped through its ``callback``;
4. the wall time at which the gradient tuner first reaches (<=) Nelder-Mead's best cost, and the ratio
   Nelder-Mead wall time / that time (``reached: false`` and no ratio when it never does); the converse
   too: when Nelder-Mead first reaches the gradient tuner's best;
5. every method's best gains re-evaluated on the 10-sub-step drive, on the training batch and on a
   held-out batch (``seed=1``);
6. the machine.

Wall times exclude compilation, which is reported separately: the searches compile their cost before
starting the clock; the tuner's timestamps have its reported ``compile_time_s`` (its ahead-of-time
compile) subtracted. ``*_incl_compile_s`` keys keep the raw figures.

``main(json_path)`` prints a table and writes the figures as JSON (atomically). ``quick=True`` shrinks
every size so the benchmark runs in seconds (smoke tests); its figures mean nothing.
"""

import argparse
import dataclasses
import math
import time

from benchmarks.bench_core import machine_info, publish
from pmsmjax.presets.three_phase import book_drive
from tuning.autotune import TuneConfig, tune
from tuning.autotune.baselines import (
    BaselineResult,
    cma_available,
    cma_es,
    design_rule_cost,
    lbfgs_b,
    nelder_mead,
)
from tuning.autotune.objectives import ObjectiveWeights
from tuning.autotune.scenario_batches import make_batch
from tuning.parameters import apply_gains

__all__ = ["run", "main", "format_table", "time_to_reach", "REQUIRED_KEYS"]


@dataclasses.dataclass(frozen=True)
class Sizes:
    """How much work the benchmark does.

    - `batch`: training scenarios (and held-out ones); `duration_s`: their duration range, s.
    - `search_evaluations`: cost evaluations given to Nelder-Mead and CMA-ES.
    - `tune_iterations`: the gradient tuner's ``max_iterations``.
    - `lbfgs_evaluations`: value-and-gradient evaluations given to L-BFGS-B.
    - `bfgs_iterations`: the BFGS tuner's ``max_iterations``; `bfgs_sweep`: its other penalty roundings.
    - `checkpoints_s`: wall times (s) at which the table compares the best costs so far.
    """

    batch: int
    duration_s: tuple[float, float]
    search_evaluations: int
    tune_iterations: int
    checkpoints_s: tuple[float, ...]
    lbfgs_evaluations: int = 300
    bfgs_iterations: int = 60
    bfgs_sweep: tuple = ()


#: Rounding widths (overshoot %, current A) of the BFGS sweep; the default (1 %, 0.1 A) is run as "bfgs".
BFGS_SWEEP = ((0.0, 0.0), (0.5, 0.05), (2.0, 0.2))

FULL = Sizes(
    batch=64,
    duration_s=(0.3, 0.5),  # make_batch's default
    search_evaluations=2000,
    tune_iterations=300,
    checkpoints_s=(1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0),
    bfgs_sweep=BFGS_SWEEP,
)
QUICK = Sizes(
    batch=4,
    duration_s=(0.08, 0.1),
    search_evaluations=40,
    tune_iterations=5,
    checkpoints_s=(0.1, 1.0),
    lbfgs_evaluations=8,
    bfgs_iterations=4,
)


N_SUBSTEPS_TUNE = 1
N_SUBSTEPS_CHECK = 10
TRAIN_SEED, HELD_OUT_SEED = 0, 1

#: Keys every report holds (checked by the smoke test).
REQUIRED_KEYS = (
    "quick",
    "dtype",
    "problem",
    "design_rule_cost",
    "nelder_mead",
    "cma_es",
    "gradient",
    "bfgs",
    "bfgs_sweep",
    "comparison",
    "cost_at_wall_time",
    "reevaluated",
    "machine",
)


def time_to_reach(curve, target: float):
    """First wall time of ``curve [(wall_s, cost), ...]`` (in time order) with ``cost <= target``.

    None when no point reaches it.
    """
    return next((w for w, c in curve if c <= target), None)


def best_by(curve, t: float):
    """Best cost of ``curve [(wall_s, cost), ...]`` among the points at or before wall time ``t``."""
    costs = [c for w, c in curve if w <= t]
    return min(costs) if costs else None


def _search_report(result: BaselineResult) -> dict:
    return {
        "best_cost": result.best_cost,
        "initial_cost": result.initial_cost,
        "evaluations": result.evaluations,
        "stopped": result.stopped,
        "wall_time_s": result.wall_time_s,
        "time_to_best_s": result.time_to_best_s,
        "compile_time_s": result.compile_time_s,
        "wall_time_incl_compile_s": result.wall_time_s + result.compile_time_s,
        "seconds_per_evaluation": result.wall_time_s / result.evaluations,
        "gains": result.gains,
        "curve": [{"evaluations": e, "wall_s": w, "best_cost": c} for e, w, c in result.trace],
    }


def _run_gradient(drive, batch, weights, config: TuneConfig) -> tuple[dict, dict]:
    """The tuner with every iteration's cost timestamped; returns (report, gains)."""
    stamps = []
    start = time.perf_counter()
    result = tune(
        drive,
        batch,
        weights,
        config,
        progress=False,
        callback=lambda it, cost: stamps.append((it, time.perf_counter() - start, float(cost))),
    )
    compile_s = result.compile_time_s
    best, curve = math.inf, []
    for it, wall, cost in stamps:
        best = min(best, cost)
        curve.append(
            {
                "iteration": it,
                "wall_s": max(wall - compile_s, 0.0),
                "wall_incl_compile_s": wall,
                "cost": cost,
                "best_cost": best,
            }
        )
    points = [(row["wall_s"], row["cost"]) for row in curve]
    report = {
        "best_cost": result.best_cost,
        "initial_cost": result.initial_cost,
        "iterations": result.iterations,
        "stopped": result.stopped,
        "wall_time_s": max(result.wall_time_s - compile_s, 0.0),
        "time_to_best_s": time_to_reach(points, result.best_cost),
        "compile_time_s": compile_s,
        "wall_time_incl_compile_s": result.wall_time_s,
        "seconds_per_iteration": (curve[-1]["wall_s"] - curve[0]["wall_s"]) / max(len(curve) - 1, 1),
        "method": config.method,
        "learning_rate": config.learning_rate,
        "overshoot_smoothing_pct": config.overshoot_smoothing_pct,
        "current_smoothing_a": config.current_smoothing_a,
        "patience": config.patience,
        "gains": result.gains,
        "curve": curve,
    }
    return report, result.gains


def _compare(search: dict, gradient: dict) -> dict:
    """When the gradient tuner reaches the search's best, and the search the tuner's best."""
    grad_curve = [(row["wall_s"], row["cost"]) for row in gradient["curve"]]
    search_curve = [(row["wall_s"], row["best_cost"]) for row in search["curve"]]
    target = search["best_cost"]
    t_grad = time_to_reach(grad_curve, target)
    reached = t_grad is not None
    it_grad = next((row["iteration"] for row in gradient["curve"] if row["cost"] <= target), None)
    # The converse: the search's time to the tuner's best (the tuner's time to it is its time_to_best).
    t_search_conv = time_to_reach(search_curve, gradient["best_cost"])
    t_grad_conv = gradient["time_to_best_s"]
    positive = lambda a, b: a / b if (a is not None and b) else None
    return {
        "target_cost": target,
        "reached": reached,
        "gradient_time_to_reach_s": t_grad,
        "gradient_iterations_to_reach": it_grad,
        "ratio_search_wall_over_gradient_time": positive(search["wall_time_s"], t_grad),
        "ratio_search_time_to_best_over_gradient_time": positive(search["time_to_best_s"], t_grad),
        "gradient_best_cost": gradient["best_cost"],
        "search_time_to_reach_gradient_best_s": t_search_conv,
        "gradient_time_to_own_best_s": t_grad_conv,
        "ratio_gradient_over_search_time_to_gradient_best": positive(t_grad_conv, t_search_conv),
    }


def run(quick: bool = False, learning_rate: float | None = None) -> dict:
    """Run every measurement and return the figures (see the module docstring).

    Runs in the process's default precision (float32 unless x64 is enabled, as in the test suite);
    ``dtype`` records which. Costs are batch costs (dimensionless sums of weighted metrics), times in s.
    `learning_rate`: the tuner's Adam step (None: the [`TuneConfig`][tuning.autotune.tuner.TuneConfig]
    default); its other settings are the defaults but ``max_iterations``.
    """
    sizes = QUICK if quick else FULL
    drive = book_drive(n_substeps=N_SUBSTEPS_TUNE)
    batch = make_batch(sizes.batch, seed=TRAIN_SEED, duration_s=sizes.duration_s)
    weights = ObjectiveWeights()
    design = design_rule_cost(drive, batch, weights)

    nm = nelder_mead(drive, batch, weights, max_evaluations=sizes.search_evaluations)
    searches = {"nelder_mead": _search_report(nm)}
    gains = {"design_rule": {}, "nelder_mead": nm.gains}
    # Gradient-based too: L-BFGS-B handles the active bounds the optimum sits on; each evaluation is a
    # value and gradient of the batch.
    qn = lbfgs_b(drive, batch, weights, max_evaluations=sizes.lbfgs_evaluations)
    searches["lbfgs_b"] = _search_report(qn)
    gains["lbfgs_b"] = qn.gains
    if cma_available():
        cma = cma_es(drive, batch, weights, max_evaluations=sizes.search_evaluations)
        searches["cma_es"] = {"available": True, **_search_report(cma)}
        gains["cma_es"] = cma.gains
    else:
        searches["cma_es"] = {"available": False, "reason": "optional package 'cma' is not installed"}

    config = TuneConfig(max_iterations=sizes.tune_iterations)
    if learning_rate is not None:
        config = dataclasses.replace(config, learning_rate=learning_rate)
    gradient, gains["gradient"] = _run_gradient(drive, batch, weights, config)
    bfgs_config = TuneConfig(
        method="bfgs", max_iterations=sizes.bfgs_iterations, patience=sizes.bfgs_iterations
    )
    bfgs, gains["bfgs"] = _run_gradient(drive, batch, weights, bfgs_config)
    sweep = []
    for width_pct, width_a in sizes.bfgs_sweep:  # none in the quick run: 3 more compilations
        cfg = dataclasses.replace(bfgs_config, overshoot_smoothing_pct=width_pct, current_smoothing_a=width_a)
        run_report, _ = _run_gradient(drive, batch, weights, cfg)
        c = _compare(searches["nelder_mead"], run_report)
        sweep.append(
            {
                "overshoot_smoothing_pct": width_pct,
                "current_smoothing_a": width_a,
                "best_cost": run_report["best_cost"],
                "time_to_best_s": run_report["time_to_best_s"],
                "reached_nelder_mead_best": c["reached"],
                "time_to_reach_s": c["gradient_time_to_reach_s"],
                "ratio_search_time_to_best_over_gradient_time": c[
                    "ratio_search_time_to_best_over_gradient_time"
                ],
            }
        )

    comparison = {
        "nelder_mead": _compare(searches["nelder_mead"], gradient),
        "bfgs_vs_nelder_mead": _compare(searches["nelder_mead"], bfgs),
    }
    lb_curve = [(row["wall_s"], row["best_cost"]) for row in searches["lbfgs_b"]["curve"]]
    nm_best, nm_wall = searches["nelder_mead"]["best_cost"], searches["nelder_mead"]["wall_time_s"]
    t_lb = time_to_reach(lb_curve, nm_best)
    comparison["lbfgs_b_vs_nelder_mead"] = {
        "target_cost": nm_best,
        "reached": t_lb is not None,
        "lbfgs_b_time_to_reach_s": t_lb,
        "ratio_search_wall_over_gradient_time": nm_wall / t_lb if t_lb else None,
        "lbfgs_b_best_cost": searches["lbfgs_b"]["best_cost"],
        "gap_to_target": searches["lbfgs_b"]["best_cost"] / nm_best - 1.0,
        "nelder_mead_time_to_reach_lbfgs_b_best_s": time_to_reach(
            [(row["wall_s"], row["best_cost"]) for row in searches["nelder_mead"]["curve"]],
            searches["lbfgs_b"]["best_cost"],
        ),
        "lbfgs_b_time_to_best_s": searches["lbfgs_b"]["time_to_best_s"],
    }
    if searches["cma_es"]["available"]:
        comparison["cma_es"] = _compare(searches["cma_es"], gradient)

    curves = {
        "gradient": [(row["wall_s"], row["cost"]) for row in gradient["curve"]],
        "bfgs": [(row["wall_s"], row["cost"]) for row in bfgs["curve"]],
    }
    for name, report in searches.items():
        if report.get("available", True):
            curves[name] = [(row["wall_s"], row["best_cost"]) for row in report["curve"]]
    cost_at = [
        {"wall_s": t, **{name: best_by(curve, t) for name, curve in curves.items()}}
        for t in sizes.checkpoints_s
    ]

    # Each method's gains on the accurate drive (10 sub-steps), training and held-out batches.
    check_drive = book_drive(n_substeps=N_SUBSTEPS_CHECK)
    held_out = make_batch(sizes.batch, seed=HELD_OUT_SEED, duration_s=sizes.duration_s)
    reevaluated = {
        name: {
            "train": design_rule_cost(apply_gains(check_drive, g) if g else check_drive, batch, weights),
            "held_out": design_rule_cost(
                apply_gains(check_drive, g) if g else check_drive, held_out, weights
            ),
        }
        for name, g in gains.items()
    }

    return {
        "quick": quick,
        "dtype": str(drive.machine.motor.R.dtype),
        "problem": {
            "drive": "book_drive",
            "n_substeps": N_SUBSTEPS_TUNE,
            "Ts_s": drive.Ts,
            "gains": list(nm.gains),
            "bounds": [0.05, 20.0],
            "batch_size": sizes.batch,
            "batch_seed": TRAIN_SEED,
            "duration_s": list(sizes.duration_s),
            "weights": dataclasses.asdict(weights),
            "search_evaluations": sizes.search_evaluations,
            "tune_iterations": sizes.tune_iterations,
        },
        "design_rule_cost": design,
        **searches,
        "gradient": gradient,
        "bfgs": bfgs,
        "bfgs_sweep": sweep,
        "comparison": comparison,
        "cost_at_wall_time": cost_at,
        "reevaluated": {"n_substeps": N_SUBSTEPS_CHECK, "held_out_seed": HELD_OUT_SEED, **reevaluated},
        "machine": machine_info(),
    }


def _fmt(x, spec: str = ".4f", none: str = "-") -> str:
    return none if x is None else format(x, spec)


def format_table(r: dict) -> str:
    """A readable plain-text table of the figures returned by `run`."""
    m, p = r["machine"], r["problem"]
    quick = "  [QUICK: sizes shrunk, figures not meaningful]" if r["quick"] else ""
    lines = [
        f"pmsmjax tuning benchmark ({r['dtype']}): book drive, {p['n_substeps']} RK4 sub-step per period, "
        f"{len(p['gains'])} gains in log-space (bounds {p['bounds'][0]}-{p['bounds'][1]}x),{quick}",
        f"  {p['batch_size']} scenarios of {p['duration_s'][0]}-{p['duration_s'][1]} s "
        f"(make_batch seed {p['batch_seed']}), cost = batch-mean ITAE + L1 penalties (ObjectiveWeights())",
        f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}, {m['backend']} ({m['device']})",
        "wall times exclude compilation (own column)",
        "",
        f"{'method':<22}{'evals/its':>10}{'best cost':>11}{'wall s':>9}{'to best s':>11}"
        f"{'s/eval':>9}{'compile s':>11}  stopped",
        f"{'design rule':<22}{1:>10}{r['design_rule_cost']:>11.5f}",
    ]
    rows = [
        ("Nelder-Mead", r["nelder_mead"], "evaluations", "seconds_per_evaluation"),
        ("L-BFGS-B (AD grad)", r["lbfgs_b"], "evaluations", "seconds_per_evaluation"),
    ]
    if r["cma_es"]["available"]:
        rows.append(("CMA-ES", r["cma_es"], "evaluations", "seconds_per_evaluation"))
    label = f"Adam, lr {r['gradient']['learning_rate']:g}"
    rows.append((label, r["gradient"], "iterations", "seconds_per_iteration"))
    rows.append(("BFGS (tune)", r["bfgs"], "iterations", "seconds_per_iteration"))
    for label, s, count, per in rows:
        lines.append(
            f"{label:<22}{s[count]:>10}{s['best_cost']:>11.5f}{s['wall_time_s']:>9.1f}"
            f"{_fmt(s['time_to_best_s'], '.1f'):>11}{s[per]:>9.3f}{s['compile_time_s']:>11.2f}"
            f"  {s['stopped']}"
        )
    if not r["cma_es"]["available"]:
        lines.append(f"{'CMA-ES':<22}  not run: {r['cma_es']['reason']}")

    c = r["comparison"]["lbfgs_b_vs_nelder_mead"]
    lines.append("")
    if c["reached"]:
        lines.append(
            f"L-BFGS-B reaches Nelder-Mead's best ({c['target_cost']:.5f}) at "
            f"{c['lbfgs_b_time_to_reach_s']:.1f} s: Nelder-Mead wall / L-BFGS-B = "
            f"{c['ratio_search_wall_over_gradient_time']:.2f}x"
        )
    else:
        lines.append(
            f"L-BFGS-B does NOT reach Nelder-Mead's best ({c['target_cost']:.5f}): it stops at "
            f"{c['lbfgs_b_best_cost']:.5f} ({100 * c['gap_to_target']:.1f} % above) after "
            f"{_fmt(c['lbfgs_b_time_to_best_s'], '.1f')} s; Nelder-Mead needs "
            f"{_fmt(c['nelder_mead_time_to_reach_lbfgs_b_best_s'], '.1f')} s to get that low"
        )
    # Each gradient tuner against each search, from the same _compare() figures.
    pairs = (
        ("nelder_mead", "Adam", "gradient", "Nelder-Mead"),
        ("cma_es", "Adam", "gradient", "CMA-ES"),
        ("bfgs_vs_nelder_mead", "BFGS", "bfgs", "Nelder-Mead"),
    )
    for name, tuner, key, label in pairs:
        c = r["comparison"].get(name)
        if c is None:
            continue
        lines.append("")
        if c["reached"]:
            lines.append(
                f"{tuner} reaches {label}'s best ({c['target_cost']:.5f}) at "
                f"{c['gradient_time_to_reach_s']:.1f} s (iteration {c['gradient_iterations_to_reach']})"
            )
            lines.append(
                f"  {label} wall / {tuner} time to reach = "
                f"{c['ratio_search_wall_over_gradient_time']:.2f}x; {label} time to its best / {tuner} = "
                f"{c['ratio_search_time_to_best_over_gradient_time']:.2f}x"
            )
        else:
            lines.append(
                f"{tuner} does NOT reach {label}'s best ({c['target_cost']:.5f}): its best is "
                f"{c['gradient_best_cost']:.5f} after {r[key]['iterations']} iterations "
                f"(reached: false, no ratio)"
            )
        t_s = c["search_time_to_reach_gradient_best_s"]
        if t_s is not None:
            lines.append(
                f"  {label} reaches {tuner}'s best ({c['gradient_best_cost']:.5f}) at {t_s:.1f} s; "
                f"{tuner} at {_fmt(c['gradient_time_to_own_best_s'], '.1f')} s ({tuner} / {label} = "
                f"{_fmt(c['ratio_gradient_over_search_time_to_gradient_best'], '.2f')}x)"
            )
        else:
            lines.append(f"  {label} never reaches {tuner}'s best ({c['gradient_best_cost']:.5f})")
    lines.append("")
    lines.append(
        "BFGS with other penalty roundings (overshoot %, current A): best cost, time to NM's best, ratio"
    )
    for row in r["bfgs_sweep"]:
        lines.append(
            f"    {row['overshoot_smoothing_pct']:>4g} % {row['current_smoothing_a']:>5g} A"
            f"{row['best_cost']:>11.5f}{_fmt(row['time_to_reach_s'], '.1f', 'not reached'):>13}"
            f"{_fmt(row['ratio_search_time_to_best_over_gradient_time'], '.2f'):>8}"
        )

    names = [k for k in r["cost_at_wall_time"][0] if k != "wall_s"]
    lines += [
        "",
        "best cost so far at wall time (compile excluded)",
        f"{'wall s':>8}" + "".join(f"{n:>14}" for n in names),
    ]
    for row in r["cost_at_wall_time"]:
        lines.append(f"{row['wall_s']:>8g}" + "".join(f"{_fmt(row[n], '.5f'):>14}" for n in names))

    re = r["reevaluated"]
    lines += [
        "",
        f"best gains re-evaluated at {re['n_substeps']} sub-steps: cost on the training batch / "
        f"held-out batch (seed {re['held_out_seed']})",
    ]
    for name in ("design_rule", "nelder_mead", "lbfgs_b", "cma_es", "gradient", "bfgs"):
        if name in re:
            lines.append(f"  {name:<20}{re[name]['train']:>11.5f}{re[name]['held_out']:>11.5f}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False, learning_rate: float | None = None) -> dict:
    """Run the benchmark, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick, learning_rate=learning_rate)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="pmsmjax tuning benchmark: gradient vs Nelder-Mead/CMA-ES")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    parser.add_argument("--learning-rate", type=float, help="the tuner's Adam step (default: TuneConfig's)")
    args = parser.parse_args()
    main(args.json, args.quick, args.learning_rate)
