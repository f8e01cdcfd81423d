"""``pmsmjax tune``: gradient auto-tuning of a control method's or an observer's gains on the book drive or
the user's drive file ([`tuning.autotune.job`][tuning.autotune.job]), optionally robust to the file's
tolerances.

Ctrl-C saves the checkpoint of the last finished iteration and ends with one line saying where, exit 130;
the same command resumes from it.
"""

from pathlib import Path

from pmsmjax.cli import checks, drive_flags
from pmsmjax.spec.validation import ParameterError, plain


def add_parser(sub):
    """Add the ``tune`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "tune",
        help="tune a control method's gains by gradients over a batch of speed/load scenarios",
        description=(
            "Gradient auto-tuning of a drive's gains (--motor: the book drive, a preset or your drive file; "
            "BFGS or Adam in log-space from the design-rule gains): --control pi (speed and current PIs, "
            "default), smc (c, eps, q and the current PIs; "
            "tuned with tanh switching, re-evaluated with the exact sign law), pr (Kp, Kr, w_c) or "
            "smc-dtc (the speed PI and the sliding-mode DTC's K_T, phi_T, K_psi, phi_psi for ITAE plus "
            "torque ripple; tuned with tanh, re-evaluated with the saturation law), over a "
            "seeded batch of speed steps and load steps from the drive file's [tuning] ranges (book: "
            "200-1500 r/min both directions, 0-10 N m), checked on a held-out batch; --robust trains over "
            "plant draws from the file's [tolerances], and every run reports the held-out nominal and "
            "worst-decile cost over such draws (the objective's penalties are priced for the drive's ITAE "
            "scale). Writes DIR/gains.toml "
            "(use it with --gains in demo, compare, pwm-compare and montecarlo), DIR/result.json, "
            "DIR/cost.png, DIR/responses.png and DIR/checkpoint.npz; running it again resumes (Ctrl-C keeps "
            "the last finished iteration; --fresh starts over). Settings: flags, then --config TOML "
            "([weights], [tune], [job] tables), then built-in defaults."
        ),
    )
    drive_flags.add_drive_flags(p, "tune_out")
    p.add_argument(
        "--robust",
        action="store_true",
        help="train over plant draws from the drive file's [tolerances] (uniform within each half-width; "
        "default: the nominal plant)",
    )
    p.add_argument(
        "--machine",
        choices=("three-phase", "six-phase", "five-phase"),
        help="three-phase drive (default), the six-phase drive (book ch. 7-9) or the five-phase drive "
        "(book ch. 10); the --motor file's n_phases must match",
    )
    p.add_argument(
        "--control",
        choices=("pi", "smc", "pr", "smc-dtc", "vsd", "double-dq", "conventional"),
        help="control method whose gains are tuned (default pi; six-phase: vsd, double-dq, conventional, "
        "pr, default vsd; five-phase: vsd, conventional, pr, default vsd)",
    )
    p.add_argument(
        "--estimator",
        choices=(
            "smo",
            "smo-pll",
            "adaptive-smo",
            "dq-smo",
            "mras",
            "ekf",
            "flux-observer",
            "hfi-rotating",
            "hfi-pulsating",
            "hybrid",
        ),
        help="tune this chapter 5 observer's parameters instead (on the drive's FOC drive; objective: speed "
        "ITAE plus angle-error RMS over scenarios started at speed, steps down to 5 %% of the top speed "
        "(book: 2000 r/min; twice the rated speed within the inverter's reach), load steps; chapter 6 "
        "hfi-rotating, hfi-pulsating, hybrid: filter and PLL gains (and the hybrid's crossover) on a "
        "salient motor (book: book_salient) at standstill and within +-10 %% of the rated speed (hybrid "
        "+-30 %%), angle modulo pi; on a drive file with a flux map the map-aware observer demo runs, a "
        "back-EMF observer's gains under the map's angle correction: estimator.observer.observer.NAME; "
        "default: none)",
    )
    p.add_argument(
        "--config", default=None, help="TOML with [weights], [tune] and [job] tables (default: none)"
    )
    p.add_argument("--iterations", type=checks.count(), help="maximum iterations (default 100)")
    p.add_argument("--train", type=checks.count(), help="training scenarios (default 64)")
    p.add_argument("--heldout", type=checks.count(), help="held-out scenarios (default 64)")
    p.add_argument(
        "--seed",
        type=checks.count(minimum=0),
        help="seed of the training batch (default 0; held-out: seed + 1)",
    )
    p.add_argument(
        "--duration-s",
        type=checks.positive("s", maximum=10.0),
        nargs=2,
        metavar=("LOW", "HIGH"),
        help="range of the scenario durations, s (default: the drive file's [tuning] duration_s, book "
        "0.3 0.5; observers half of it)",
    )
    p.add_argument(
        "--gains",
        nargs="+",
        help="names of the gains to tune: aliases speed, current, smc, pr, smc_dtc or names like "
        "controller.speed.kp "
        "(default: the control's own gains)",
    )
    p.add_argument(
        "--start-gains",
        metavar="FILE",
        default=None,
        help="start from the gains of a gains.toml (an earlier pmsmjax tune) instead of the design rules "
        "(default: design rules)",
    )
    p.add_argument(
        "--method",
        choices=("adam", "bfgs"),
        help="optimiser: bfgs (default; step-capped quasi-Newton on the cost with its penalty kinks rounded) "
        "or adam",
    )
    p.add_argument(
        "--learning-rate", type=checks.positive(maximum=2.0), help="Adam step in log-space (default 0.08)"
    )
    p.add_argument("--substeps", type=checks.count(), help="RK4 sub-steps while tuning (default 1)")
    p.add_argument(
        "--eval-substeps", type=checks.count(), help="RK4 sub-steps for before/after figures (default 10)"
    )
    p.add_argument(
        "--time-budget-s", type=checks.positive("s"), help="stop after this wall time, s (default: none)"
    )
    p.add_argument(
        "--min-phase-margin-deg",
        type=checks.positive("deg", maximum=89.0),
        help="constrain both loops' phase margin (linearised at the [tuning] ranges' middle speed and load, "
        "on every training plant) to at least this, deg (a penalty in the cost; default: none)",
    )
    p.add_argument(
        "--max-sensitivity-peak",
        type=checks.positive(),
        help="constrain both loops' sensitivity peak max|S| to at most this (> 1, e.g. 1.7; default: none)",
    )
    p.add_argument(
        "--anticogging",
        action="store_true",
        help="learn the FOC's anticogging table (q current over one electrical revolution) instead of the "
        "gains: minimises the speed ripple at --anticogging-rpm by Gauss-Newton through the closed loop; "
        "writes DIR/anticogging.csv and DIR/anticogging.json (the drive file needs [harmonics] cogging)",
    )
    p.add_argument(
        "--anticogging-rpm", type=checks.positive("r/min"), default=30.0, help="speed, r/min (default 30)"
    )
    p.add_argument("--anticogging-bins", type=checks.count(), default=128, help="table bins (default 128)")
    p.add_argument("--fresh", action="store_true", help="ignore and replace an existing checkpoint")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


MACHINE_PHASES = {None: 3, "three-phase": 3, "six-phase": 6, "five-phase": 5}


def precheck(args):
    """Checks that need no model (before JAX starts); returns the drive
    ([`DriveSpec`][pmsmjax.io.drive_files.DriveSpec])."""
    from pmsmjax.cli.gains import read_gains_flag
    from pmsmjax.io.drive_files import drive_spec

    checks.output_folder(args.out)
    if args.config is not None:
        checks.existing_file(args.config, "--config", "tuning config")
    spec = drive_spec(
        args.motor,
        n_phases=MACHINE_PHASES[args.machine],
        u_dc_v=args.u_dc,
        max_current_a=args.current_limit,
        flags={"u_dc_v": "--u-dc", "max_current_a": "--current-limit"},
    )
    robust = args.robust or _config_robust(args.config)
    if robust and not (spec.tolerances or spec.operating):  # the job draws from either table
        where = "--robust" if args.robust else f"--config {args.config}: [job] robust = true"
        raise ParameterError(
            f"{where}: the drive {spec.source} has no [tolerances] or [operating] table: add one to the "
            "drive file (relative half-widths, e.g. R = 0.1, J = 0.3; operating ranges, e.g. u_dc_v = "
            "[280, 330]) or tune without --robust."
        )
    if args.duration_s and args.duration_s[0] > args.duration_s[1]:
        low, high = args.duration_s
        raise ParameterError(
            f"--duration-s {plain(low)} {plain(high)}: LOW is above HIGH; give the range as LOW HIGH, "
            f"e.g. --duration-s {plain(high)} {plain(low)}."
        )
    for name in args.gains or ():
        if name.endswith(".toml") or Path(name).is_file():
            raise ParameterError(
                f"--gains {name}: tune's --gains takes the names of the gains to tune (speed, current, ...); "
                f"to start from a tuned gains file use --start-gains {name}."
            )
    read_gains_flag(args.start_gains, "--start-gains")
    return spec


def _config_robust(path) -> bool:
    """Whether the tuning config ``path`` (None: none) asks for ``[job] robust = true``; a file that does
    not parse is left to the config reader's message."""
    if path is None:
        return False
    from pmsmjax.io.toml_parser import read_toml

    try:
        return read_toml(path, "").get("job", {}).get("robust", False) is True
    except (ParameterError, OSError, AttributeError):
        return False


def run(args) -> int:
    """Tune the gains by gradients over a scenario batch (resuming from checkpoint.npz); writes
    gains.toml, result.json and figures to ``--out``. Returns the exit status."""
    spec = precheck(args)
    if args.anticogging:
        return _anticogging(args, spec)
    # The command line is the one place where pmsmjax reaches up into the tuning workflows.
    import dataclasses

    from tuning.autotune.job import DEFAULT_CONFIG, read_tune_toml, run_tune_job
    from tuning.autotune.tuner import TuneInterrupted

    kwargs = read_tune_toml(args.config) if args.config else {}
    config = kwargs.pop("config", DEFAULT_CONFIG)
    if args.estimator is not None and config is DEFAULT_CONFIG:
        from tuning.autotune.observers import OBSERVER_CONFIG

        config = dataclasses.replace(DEFAULT_CONFIG, **OBSERVER_CONFIG)
    overrides = {
        "names": tuple(args.gains) if args.gains else None,
        "method": args.method,
        "learning_rate": args.learning_rate,
        "max_iterations": args.iterations,
        "time_budget_s": args.time_budget_s,
    }
    config = dataclasses.replace(config, **{k: v for k, v in overrides.items() if v is not None})
    for key, value in (
        ("n_train", args.train),
        ("n_heldout", args.heldout),
        ("train_seed", args.seed),
        ("heldout_seed", None if args.seed is None else args.seed + 1),
        ("duration_s", tuple(args.duration_s) if args.duration_s else None),
        ("tune_substeps", args.substeps),
        ("eval_substeps", args.eval_substeps),
        ("control", args.control),
        ("start_gains", args.start_gains),
        ("machine", args.machine),
        ("estimator", args.estimator),
        ("robust", args.robust or None),
        ("min_phase_margin_deg", args.min_phase_margin_deg),
        ("max_sensitivity_peak", args.max_sensitivity_peak),
    ):
        if value is not None:
            kwargs[key] = value
    checkpoint = Path(args.out) / "checkpoint.npz"
    if args.fresh and checkpoint.exists():
        checkpoint.unlink()
    try:
        data = run_tune_job(args.out, config=config, drive=spec, progress=not args.no_progress, **kwargs)
    except TuneInterrupted:
        raise
    except KeyboardInterrupt:
        kept = (
            f"; the checkpoint {checkpoint} is kept: rerun the same command to resume"
            if checkpoint.exists()
            else ""
        )
        raise KeyboardInterrupt(f"outside the iterations{kept}") from None
    import numpy as np

    tr, ho = data["train"], data["heldout"]
    cut = lambda d: 100.0 * (1.0 - d["after"]["itae"] / d["before"]["itae"])
    if data["resumed_from_iteration"]:
        print(f"resumed from iteration {data['resumed_from_iteration']}")
    print(
        f"train ITAE {tr['before']['itae']:.4f} -> {tr['after']['itae']:.4f} ({cut(tr):.1f} % lower), "
        f"held-out {ho['before']['itae']:.4f} -> {ho['after']['itae']:.4f} ({cut(ho):.1f} % lower)"
    )
    if data.get("estimator"):
        deg = lambda d: float(np.degrees(d["angle_error_rms_rad"]))
        angle_cut = lambda d: (
            100.0 * (1.0 - d["after"]["angle_error_rms_rad"] / d["before"]["angle_error_rms_rad"])
        )
        print(
            f"angle error RMS (mean over scenarios, electrical degrees): train {deg(tr['before']):.3f} -> "
            f"{deg(tr['after']):.3f} ({angle_cut(tr):.1f} % lower), held-out {deg(ho['before']):.3f} -> "
            f"{deg(ho['after']):.3f} ({angle_cut(ho):.1f} % lower); tuned gains {data['stability']}"
        )
    if "after_surrogate" in ho:
        print(
            f"held-out ITAE of the tuned gains on the smoothed surrogate "
            f"({', '.join(f'{k}={v}' for k, v in data['surrogate']['options'].items())}): "
            f"{ho['after_surrogate']['itae']:.4f}; on the exact law (above): {ho['after']['itae']:.4f}"
        )
    robustness = data["robustness"]
    if robustness is not None:
        nominal = robustness["nominal_cost"]
        line = f"held-out cost on the nominal plant {nominal['before']:.4f} -> {nominal['after']:.4f}"
        worst = robustness["worst_decile_cost"]
        if worst is not None:
            line += (
                f"; worst decile over plant draws from the tolerances {worst['before']:.4f} -> "
                f"{worst['after']:.4f}"
            )
        print(line + (" (trained robust)" if data["robust"] else ""))
    # observer scenarios start at speed and step both ways: their pre-load "overshoot" is not one
    overshoot = (
        ""
        if data.get("estimator")
        else f"overshoot {tr['before']['overshoot_pct']:.3f} -> {tr['after']['overshoot_pct']:.3f} % "
        "(train mean), "
    )
    print(
        f"{overshoot}peak current {tr['before']['max_peak_current_a']:.2f} -> "
        f"{tr['after']['max_peak_current_a']:.2f} A, scenarios over the limit: "
        f"{tr['before']['scenarios_over_current_limit']} -> "
        f"{tr['after']['scenarios_over_current_limit']} (train)"
    )
    print(
        f"{data['iterations']} iterations ({data['stopped']}), wall {data['wall_time_s']:.1f} s "
        f"(compile {data['compile_time_s']:.1f} s); wrote {args.out}/gains.toml, result.json, figures"
    )
    return 0


def _anticogging(args, spec) -> int:
    """``--anticogging``: learn the table on the drive file's drive and write it to ``--out``."""
    if not spec.harmonics.get("cogging"):
        raise ParameterError(
            f"--anticogging: the drive {spec.source} has no [harmonics] cogging: add the cogging torque "
            "(e.g. cogging = [[6, 0.045, 0.3]]) to the drive file."
        )
    from tuning.autotune.anticogging_job import run_anticogging_job

    data = run_anticogging_job(
        args.out, spec, args.control or "pi", n_bins=args.anticogging_bins, speed_rpm=args.anticogging_rpm
    )
    b, a = data["speed_error_before_rpm"], data["speed_error_after_rpm"]
    print(
        f"speed error at {plain(args.anticogging_rpm)} r/min: RMS {b['rms_rpm']:.4f} -> {a['rms_rpm']:.4f} "
        f"r/min ({data['rms_cut']:.1f}x), peak-to-peak {b['peak_to_peak_rpm']:.4f} -> "
        f"{a['peak_to_peak_rpm']:.4f} r/min ({data['peak_to_peak_cut']:.1f}x); {data['steps']} steps, wall "
        f"{data['wall_time_s']:.1f} s; wrote {args.out}/anticogging.csv, anticogging.json"
    )
    return 0
