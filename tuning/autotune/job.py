"""The ``pmsmjax tune`` job: tune on a train batch, check on a held-out batch, write the results.

Outputs in the chosen folder: ``gains.toml`` (load with
[`tuning.parameters.apply_gains`][tuning.parameters.apply_gains]), ``result.json``, ``cost.png`` (cost against
iteration), ``responses.png`` (speed and current of a few scenarios before and after) and ``checkpoint.npz``
(resume point; running the same command again continues from it and ends at the same result).

The drive (``drive``): a drive file or preset name
([`pmsmjax.io.drive_files.drive_spec`][pmsmjax.io.drive_files.drive_spec], default ``book``) or its
[`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]; every drive is built from it by
[`pmsmjax.assemble.spec_drive`][pmsmjax.assemble.spec_drive], and every batch from its ``[tuning]`` ranges and
control period ([`tuning.autotune.drive_scaling`][tuning.autotune.drive_scaling]). ``--motor book`` gives the
book drive and batches bit for bit.

Control methods (``control``: ``pi``, ``smc``, ``pr``, ``smc-dtc``;
[`tuning.autotune.controls`][tuning.autotune.controls]): the drive of that control, its default gains and its
default objective weights (used when ``weights`` is None). ``machine="six-phase"``: the six-phase drive
(`pmsmjax.presets.six_phase.six_phase_drive`) under ``vsd``,
``double-dq``, ``conventional`` or ``pr`` (default ``vsd``); ``machine="five-phase"``: the five-phase drive
(`pmsmjax.presets.five_phase.five_phase_drive`) under ``vsd``
or ``conventional``.

Observers (``estimator``: ``smo``, ``smo-pll``, ``adaptive-smo``, ``dq-smo``, ``mras``, ``ekf``;
[`tuning.autotune.observers`][tuning.autotune.observers]): the drive's FOC drive on that observer behind a
sensored warm-up, its default parameters, the observer batches (start at speed, steps down to 5 % of the
batches' top speed, load steps; ``kinds=("step", "reversal")`` adds reversals) and the objective speed ITAE
plus angle-error RMS; the tuned gains' stability is checked with the observer's own ``check_period``.
``hfi-rotating``, ``hfi-pulsating``, ``hybrid`` (chapter 6,
[`tuning.autotune.hfi_tuning`][tuning.autotune.hfi_tuning]): the salient, saturated drive and low-speed
batches (standstill, +-10 % of the rated speed), the angle error scored modulo pi. The observer batches'
speeds, loads, noise and times are the book drive's scaled to the drive
([`tuning.autotune.drive_scaling`][tuning.autotune.drive_scaling]). Without ``weights`` the objective's
penalty weights are the defaults scaled to the drive's ITAE
([`tuning.autotune.drive_scaling.scaled_weights`][tuning.autotune.drive_scaling.scaled_weights]).

Robustness (``robust``): training over plant draws from the drive file's ``[tolerances]`` and
``[operating]`` bands (uniform
within +-half-width per parameter, the DC link included; the controller's model stays nominal). Every
run on a drive file with tolerances reports, for the held-out scenarios, the nominal cost (nominal
plant) and the worst-decile cost (mean of the worst 10 % of per-scenario costs over plant draws from the
tolerances), before and after (result.json ``robustness``).

Surrogate and exact model: tuning runs the drive with ``tune_substeps`` RK4 steps per period (1 by
default: 4e-7 of peak current from the exact solution at 10 kHz, and a 4x cheaper gradient) and with the
control's smooth surrogate (the SMC's ``tanh`` switching instead of ``sign``); every before/after figure is
re-evaluated on the exact model (``eval_substeps``, 10, the book setting, and the exact switching), and
result.json gives the cost on both, plus the held-out figures of the tuned gains on the smoothed model
(``heldout.after_surrogate``) where the surrogate differs by more than its sub-steps.
"""

import dataclasses
import json
import time
from pathlib import Path

import jax
import numpy as np

from pmsmjax.assemble import spec_drive
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.io.logs import atomic_write
from pmsmjax.io.toml_parser import read_toml
from pmsmjax.spec.drive_spec import DriveSpec
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rad_s_to_rpm
from tuning.autotune import drive_scaling
from tuning.autotune.controls import control_tuning
from tuning.autotune.drive_batches import drive_batches
from tuning.autotune.margin_constraints import margin_weights, margins_report
from tuning.autotune.objectives import (
    ObjectiveWeights,
    aggregate,
    batch_metrics,
    scaled_plant,
    scenario_cost,
)
from tuning.autotune.observers import OBSERVER_CONFIG, observer_drive, observer_tuning, tuned_names
from tuning.autotune.scenario_batches import ScenarioBatch
from tuning.autotune.tuner import TuneConfig, tune
from tuning.parameters import apply_gains, get_leaf, write_gains_toml

#: The reference configuration (book drive): 64 + 64 scenarios, 0.3-0.5 s, steps of 200-1500 r/min both
#: ways, 0-10 N m;
#: BFGS (its rounded-penalty default), which gets a 3x lower cost than Adam in fewer iterations. ``names``
#: None: the control's own gains (`tuning.autotune.controls.TUNABLE_CONTROLS`).
DEFAULT_CONFIG = TuneConfig(names=None, method="bfgs", max_iterations=100)

#: Keys of a tuning TOML file, by table; ``[job]`` holds the keyword arguments of
#: [`run_tune_job`][tuning.autotune.job.run_tune_job].
JOB_KEYS = (
    "n_train",
    "n_heldout",
    "train_seed",
    "heldout_seed",
    "duration_s",
    "kinds",
    "plant_spread",
    "tune_substeps",
    "eval_substeps",
    "control",
    "start_gains",
    "machine",
    "estimator",
    "robust",
    "min_phase_margin_deg",
    "max_sensitivity_peak",
)
#: How the machine names the drive file's phase count.
MACHINE_PHASES = {"three-phase": 3, "six-phase": 6, "five-phase": 5}


def read_tune_toml(path) -> dict:
    """Read a tuning config: ``[weights]`` (ObjectiveWeights), ``[tune]`` (TuneConfig), ``[job]``.

    Returns keyword arguments for [`run_tune_job`][tuning.autotune.job.run_tune_job] (``weights``, ``config``
    and the job keys). Unknown tables or keys are errors that name them.
    """
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"tuning config {path} does not exist.")
    data = read_toml(path, f"tuning config {path}")
    unknown = sorted(set(data) - {"weights", "tune", "job"})
    if unknown:
        raise ParameterError(f"tuning config {path}: unknown tables {unknown}; use [weights], [tune], [job].")
    out = {}
    for table, cls in (("weights", ObjectiveWeights), ("tune", TuneConfig)):
        fields = {f.name for f in dataclasses.fields(cls)}
        values = data.get(table, {})
        bad = sorted(set(values) - fields)
        if bad:
            raise ParameterError(
                f"tuning config {path}: unknown keys {bad} in [{table}]; allowed {sorted(fields)}."
            )
        if table == "tune":
            values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
            out["config"] = dataclasses.replace(DEFAULT_CONFIG, **values)
        else:
            out["weights"] = cls(**values)
    job = data.get("job", {})
    bad = sorted(set(job) - set(JOB_KEYS))
    if bad:
        raise ParameterError(f"tuning config {path}: unknown keys {bad} in [job]; allowed {list(JOB_KEYS)}.")
    out.update({k: tuple(v) if isinstance(v, list) else v for k, v in job.items()})
    return out


def speed_filter_names(spec: DriveSpec, estimator=None) -> tuple[str, ...]:
    """The speed-loop filters of the drive file's ``[control]`` (low-pass cut-off, notch centre, width and
    depth), tuned with the speed PI by default; none for an observer's tuning or a file without them."""
    keys = ("speed_filter_hz", "notch_hz", "notch_width_hz", "notch_depth_db")
    if estimator is not None:
        return ()
    return tuple(f"controller.speed.filters.{k}" for k in keys if k in spec.control)


def evaluate(drive, batch: ScenarioBatch, weights: ObjectiveWeights) -> dict:
    """Batch summary (means, worst cases, cost) and per-scenario metrics of ``drive`` on ``batch``."""
    m = jax.device_get(batch_metrics(drive, batch))
    costs = np.asarray(jax.vmap(lambda mm: scenario_cost(mm, weights))(m))
    summary = {k: float(np.mean(v)) for k, v in m.items()}
    summary.update(
        cost=float(aggregate(costs, weights)),
        max_peak_current_a=float(np.max(m["peak_current_a"])),
        max_overshoot_pct=float(np.max(m["overshoot_pct"])),
        scenarios_over_current_limit=int(np.sum(m["current_excess_a"] > 0)),
    )
    per_scenario = [
        {"kind": batch.kind[i], **{k: float(v[i]) for k, v in m.items()}, "cost": float(costs[i])}
        for i in range(batch.size)
    ]
    return {"summary": summary, "per_scenario": per_scenario}


def run_tune_job(
    out_dir,
    *,
    n_train: int = 64,
    n_heldout: int = 64,
    train_seed: int = 0,
    heldout_seed: int = 1,
    duration_s: tuple[float, float] | None = None,
    kinds: tuple[str, ...] = ("step",),
    plant_spread: dict | None = None,
    tune_substeps: int = 1,
    eval_substeps: int = 10,
    control: str | None = None,
    start_gains: str | None = None,
    machine: str = "three-phase",
    estimator: str | None = None,
    drive: DriveSpec | str = "book",
    robust: bool = False,
    min_phase_margin_deg: float | None = None,
    max_sensitivity_peak: float | None = None,
    weights: ObjectiveWeights | None = None,
    config: TuneConfig = DEFAULT_CONFIG,
    progress: bool = True,
    callback=None,
) -> dict:
    """Tune the gains of ``drive`` (a [`DriveSpec`][pmsmjax.io.drive_files.DriveSpec], a preset name or a
    drive file; default the book drive) under ``control`` and write the outputs into ``out_dir``; returns
    result.json's content. `start_gains`: a gains TOML (an earlier run's gains.toml) to start from instead of
    the design-rule gains. `machine`: ``three-phase``, ``six-phase`` or ``five-phase`` (the drive file's phase
    count). `estimator`: tune that observer's parameters instead (module docstring; the three-phase FOC drive,
    control ``pi``). `duration_s` defaults to the drive file's ``[tuning] duration_s`` for a control and
    half of it for an observer (book: 0.3-0.5 s, 0.15-0.25 s). `robust`: train over plant draws from the
    drive file's ``[tolerances]`` (refused without them); `plant_spread` (``{parameter: half-width}``)
    sets such draws explicitly for the train and held-out batches. `min_phase_margin_deg`,
    `max_sensitivity_peak`: margin constraints of both loops on every training plant
    ([`tuning.autotune.margin_constraints`][tuning.autotune.margin_constraints]) at the ``[tuning]`` ranges'
    middle speed and load (control ``pi``, three-phase); result.json ``margins`` reports the margins
    before and
    after on the nominal plant and the worst over the held-out plant draws."""
    if machine not in MACHINE_PHASES:
        raise ParameterError(f"machine must be 'three-phase', 'six-phase' or 'five-phase', got {machine!r}.")
    spec = drive if isinstance(drive, DriveSpec) else drive_spec(drive, n_phases=MACHINE_PHASES[machine])
    tolerances = drive_scaling.plant_spread(spec)
    if robust:
        if not tolerances:
            raise ParameterError(
                f"--robust: the drive {spec.source} has no [tolerances] or [operating] table: add one to the "
                "drive file (relative half-widths, e.g. R = 0.1, J = 0.3; operating ranges, e.g. u_dc_v = "
                "[280, 330]) or tune without --robust."
            )
        plant_spread = {**tolerances, **(plant_spread or {})}
    if estimator is not None:
        if machine != "three-phase" or control not in (None, "pi"):
            raise ParameterError(
                f"--estimator {estimator} tunes an observer on the three-phase FOC drive (control pi); drop "
                f"--control {control} / --machine {machine} or tune the control's gains without --estimator."
            )
        control = "pi"
        tuning = observer_tuning(estimator)
        # no settings given: the observers' optimiser (observers.OBSERVER_CONFIG)
        if config is DEFAULT_CONFIG:
            config = dataclasses.replace(DEFAULT_CONFIG, **OBSERVER_CONFIG)

        batches = drive_batches(spec, estimator)

        def build(substeps, options):
            return observer_drive(
                estimator,
                spec=spec,
                n_substeps=substeps,
                observer_options=options,
                warmup_s=batches.warmup_s,
            )

        if tuning.chapter6:  # injection estimators, hybrid: the low-speed batches, scored modulo pi
            from tuning.autotune.hfi_tuning import INJECTION_KINDS

            kinds = INJECTION_KINDS if tuple(kinds) == ("step",) else tuple(kinds)
    else:
        if control is None:
            control = "pi" if machine == "three-phase" else "vsd"
        tuning = control_tuning(control, machine)

        def build(substeps, options):
            return spec_drive(spec, control, n_substeps=substeps, **options)

        batches = drive_batches(spec)
    if weights is None:  # the control's or observer's defaults, their penalties priced for the drive
        weights = drive_scaling.scaled_weights(ObjectiveWeights(**tuning.weights), spec)
    weights = margin_weights(
        weights, spec, control, machine, estimator, min_phase_margin_deg, max_sensitivity_peak
    )
    batch_maker = batches.make
    duration_s = batches.duration_s if duration_s is None else duration_s
    batch_options = dict(duration_s=duration_s, kinds=kinds)
    train = batch_maker(n_train, train_seed, plant_spread=plant_spread, **batch_options)
    heldout = batch_maker(n_heldout, heldout_seed, plant_spread=plant_spread, **batch_options)
    # The robustness figures: the held-out scenarios on the nominal plant and on draws from the tolerances
    # (the scenarios of a seed do not depend on the draws; make_batch draws the plants after them).
    nominal = heldout if not plant_spread else batch_maker(n_heldout, heldout_seed, **batch_options)
    drawn = None
    if tolerances:
        same = dict(plant_spread or {}) == tolerances
        if same:
            drawn = heldout
        else:
            drawn = batch_maker(n_heldout, heldout_seed, plant_spread=tolerances, **batch_options)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    surrogate = build(tune_substeps, tuning.surrogate)
    exact = build(eval_substeps, {})
    if config.names is None:  # an observer's paths in its drive (a map-aware wrapper puts it lower)
        own = tuning.names if estimator is None else tuned_names(estimator, surrogate)
        config = dataclasses.replace(config, names=own + speed_filter_names(spec, estimator))
    if start_gains is not None:
        surrogate, exact = apply_gains(surrogate, start_gains), apply_gains(exact, start_gains)

    result = tune(
        surrogate,
        train,
        weights,
        config,
        checkpoint_path=out / "checkpoint.npz",
        progress=progress,
        callback=callback,
    )
    tuned_exact = apply_gains(exact, result.gains)
    report = {
        "train": {"before": evaluate(exact, train, weights), "after": evaluate(tuned_exact, train, weights)},
        "heldout": {
            "before": evaluate(exact, heldout, weights),
            "after": evaluate(tuned_exact, heldout, weights),
        },
    }
    robustness = _robustness(exact, tuned_exact, heldout, nominal, drawn, report, weights, tolerances)
    if tuning.surrogate:  # the smoothed law at the exact model's sub-steps: what the optimiser saw
        smoothed = build(eval_substeps, tuning.surrogate)
        if start_gains is not None:
            smoothed = apply_gains(smoothed, start_gains)
        report["heldout"]["after_surrogate"] = evaluate(apply_gains(smoothed, result.gains), heldout, weights)
    before_gains = {n: float(get_leaf(exact, n)) for n in result.gains}
    data = {
        "train": {k: {**v["summary"], "per_scenario": v["per_scenario"]} for k, v in report["train"].items()},
        "heldout": {
            k: {**v["summary"], "per_scenario": v["per_scenario"]} for k, v in report["heldout"].items()
        },
        "control": control,
        "machine": machine,
        "estimator": estimator,
        "drive_file": spec.summary(),
        "robust": bool(robust),
        "robustness": robustness,
        "gains": {"before": before_gains, "after": result.gains},
        "surrogate": {
            "options": dict(tuning.surrogate),
            "tune_substeps": tune_substeps,
            "eval_substeps": eval_substeps,
            "train_cost_on_surrogate": {"before": result.initial_cost, "after": result.best_cost},
            "train_cost_on_exact": {
                "before": report["train"]["before"]["summary"]["cost"],
                "after": report["train"]["after"]["summary"]["cost"],
            },
        },
        "iterations": result.iterations,
        "resumed_from_iteration": result.resumed_from,
        "stopped": result.stopped,
        "cost_history": result.history,
        "wall_time_s": result.wall_time_s,
        "compile_time_s": result.compile_time_s,
        "weights": dataclasses.asdict(weights),
        "config": {
            **dataclasses.asdict(config),
            "n_train": n_train,
            "n_heldout": n_heldout,
            "duration_s": list(duration_s),
            "kinds": list(kinds),
            "plant_spread": dict(plant_spread or {}),
            **{k: list(v) if isinstance(v, tuple) else v for k, v in batches.ranges.items()},
        },
        "seeds": {"train": train_seed, "heldout": heldout_seed},
    }
    if estimator is not None:
        data["stability"] = _stability(tuned_exact)
    if estimator is None and control == "pi" and machine == "three-phase":
        data["margins"] = margins_report(exact, tuned_exact, drawn, weights, spec, scaled_plant)
    what = f"--estimator {estimator}" if estimator is not None else f"--control {control}"
    write_gains_toml(
        out / "gains.toml",
        list(result.gains),
        list(result.gains.values()),
        header=f"{estimator or control} gains tuned by pmsmjax tune {what} ({time.strftime('%Y-%m-%d')}); "
        "SI units.",
    )
    atomic_write(out / "result.json", lambda f: f.write(json.dumps(data, indent=2).encode()))
    _figures(out, exact, tuned_exact, train, result.history)
    return data


def _robustness(before, after, heldout, nominal, drawn, report, weights, tolerances) -> dict:
    """The held-out cost of the drives ``before`` and ``after`` tuning on the nominal plant (``nominal``
    batch) and the worst-decile cost over plant draws from the tolerances (``drawn`` batch; None without
    tolerances); evaluations already in ``report`` (on ``heldout``) are reused."""

    def costs(batch):
        if batch is heldout:
            return {k: report["heldout"][k] for k in ("before", "after")}
        return {"before": evaluate(before, batch, weights), "after": evaluate(after, batch, weights)}

    nominal_eval = costs(nominal)
    data = {
        "tolerances": dict(tolerances),
        "worst_share": drive_scaling.WORST_SHARE,
        "nominal_cost": {k: v["summary"]["cost"] for k, v in nominal_eval.items()},
        "nominal_itae": {k: v["summary"]["itae"] for k, v in nominal_eval.items()},
        "worst_decile_cost": None,
    }
    if drawn is not None:
        drawn_eval = costs(drawn)
        per_scenario = {k: [s["cost"] for s in v["per_scenario"]] for k, v in drawn_eval.items()}
        data.update(
            worst_decile_cost={k: drive_scaling.worst_share_mean(c) for k, c in per_scenario.items()},
            drawn_mean_cost={k: v["summary"]["cost"] for k, v in drawn_eval.items()},
            drawn_per_scenario_cost=per_scenario,
            drawn_scenarios_over_current_limit={
                k: v["summary"]["scenarios_over_current_limit"] for k, v in drawn_eval.items()
            },
            plant_scale={k: np.asarray(v).tolist() for k, v in drawn.plant_scale.items()},
        )
    return data


def _stability(drive) -> str:
    """``"stable"``, or the observer's own ``check_period`` refusal of the tuned gains (a tuned point
    outside the linearised stability region is reported, not hidden)."""
    try:
        drive.estimator.check_period(drive.Ts)
    except ParameterError as err:
        return f"refused by check_period: {err}"
    return "stable"


def _figures(out: Path, before, after, batch: ScenarioBatch, history) -> None:
    import matplotlib.pyplot as plt

    import pmsmjax
    from pmsmjax.plotting.traces import save_figure

    fig, ax = plt.subplots(figsize=(7.5, 3.4))
    it = np.arange(1, len(history) + 1)
    cost = np.asarray(history, dtype=float)
    # Every trial the optimiser evaluated (a rejected BFGS trial costs more: it backs off), and the best
    # so far, which is what tuning has achieved at each iteration.
    ax.semilogy(it, cost, "o", ms=3, color="0.6", label="each trial (rejected ones included)")
    ax.semilogy(
        it, np.minimum.accumulate(np.where(np.isfinite(cost), cost, np.inf)), "-", lw=1.8, label="best so far"
    )
    ax.set(
        xlabel="iteration",
        ylabel="batch cost / (rad s)",
        title="Tuning cost on the training batch (surrogate model): mean ITAE + penalties",
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    save_figure(fig, out / "cost.png")

    picks = [0, int(np.argmax(np.abs(np.asarray(batch.scenarios.speed_ref.values[:, -1]))))]
    fig, axes = plt.subplots(2, len(picks), figsize=(11, 6), squeeze=False)
    for col, k in enumerate(picks):
        scenario = jax.tree.map(lambda a, k=k: a[k], batch.scenarios)
        for drive, label, fmt in ((before, "design rules", "-"), (after, "tuned", "-")):
            start = None
            if batch.initial_speed_m is not None:  # observer batches start at speed
                start = drive.init(batch.initial_speed_m[k], batch.initial_theta_e[k])
            tr = pmsmjax.simulate(drive, scenario, initial_state=start)
            t, end = np.asarray(tr.t), float(batch.duration_s[k])
            keep = t < end
            axes[0, col].plot(t[keep], rad_s_to_rpm(np.asarray(tr.omega_m))[keep], fmt, label=label)
            axes[1, col].plot(t[keep], np.asarray(tr.i_dq)[keep, 1], fmt, label=label)
        axes[0, col].plot(
            t[keep], rad_s_to_rpm(np.asarray(tr.speed_ref))[keep], "k--", lw=0.8, label="reference"
        )
        limit = float(np.asarray(before.controller.current_limit))
        low, high = axes[1, col].get_ylim()
        for k_sign, sign in enumerate(s for s in (1.0, -1.0) if (high if s > 0 else -low) > 0.2 * limit):
            label = "current limit" if k_sign == 0 else None
            axes[1, col].axhline(sign * limit, color="tab:red", ls=":", lw=1.2, label=label)
        axes[0, col].set(title=f"scenario {k} ({batch.kind[k]})", ylabel="n / (r/min)")
        axes[1, col].set(xlabel="t / s", ylabel="$i_q$ / A")
        for ax in axes[:, col]:
            ax.grid(alpha=0.3)
            ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    save_figure(fig, out / "responses.png")
