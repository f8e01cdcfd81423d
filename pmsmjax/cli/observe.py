"""``pmsmjax observe``: run a chapter 5 observer, or the rotating HF-injection estimator of chapter 6, offline
on a recorded drive log ([`pmsmjax.jobs.observe`][pmsmjax.jobs.observe]).

``hfi-rotating`` reads the carrier from the log's voltages (``carrier="measured"``: the log's drive
injected it, this run does not), and its angle is the d axis modulo pi: ``estimate.csv`` gives it in
[-pi/2, pi/2) and the errors are taken modulo pi, unless ``--polarity-known``. ``hfi-pulsating`` is
refused: its demodulation needs the injection axis of the drive that made the log, which a log does not
record.
"""

import json

from pmsmjax.cli import checks, drive_flags, memory
from pmsmjax.spec.validation import ParameterError


def add_parser(sub):
    """Add the ``observe`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "observe",
        help="run a sensorless observer offline on a logged drive run (estimate.csv, figure)",
        description=(
            "Estimate the rotor angle and speed from a log's stator-frame voltages and currents "
            "(CSV/NPZ/MAT; columns time,u_alpha,u_beta,i_alpha,i_beta, or u_a,u_b,u_c / duties d_a,d_b,d_c "
            "with U_dc, and i_a,i_b,i_c; the voltage of row k is the one applied from row k to row k+1, the "
            "current is sampled at row k). Other columns are ignored unless named with --truth-columns, then "
            "the estimate's errors are reported. Writes DIR/estimate.csv (time,theta_e,omega_m: electrical "
            "rad in [-pi, pi), mechanical rad/s), DIR/observe.json and DIR/observe.png. hfi-rotating runs on "
            "logs of a salient machine with rotating injection (give --hf-voltage and --hf-frequency of the "
            "log's carrier); its angle is the d axis modulo pi, in [-pi/2, pi/2), unless --polarity-known."
        ),
    )
    drive_flags.add_logged_motor_flags(p, "the observer's motor model and pole pairs")
    p.add_argument(
        "--observer",
        required=True,
        help="smo, smo-pll, adaptive-smo, dq-smo, mras, ekf, or hfi-rotating (logs of a salient machine with "
        "rotating injection)",
    )
    checks.add_out_flag(p)
    checks.add_log_column_flags(
        p, "i_alpha=Ialpha", "e.g. time=ms omega_m=rpm (default: SI, or the unit in a column's name)"
    )
    p.add_argument(
        "--truth-columns",
        default="",
        metavar="theta_e,omega_m",
        help="score the estimate against these logged columns (electrical rad, mechanical rad/s; "
        "default: none)",
    )
    p.add_argument(
        "--settle-s", type=float, default=0.05, help="time excluded from the error figures, s (default 0.05)"
    )
    p.add_argument(
        "--u-dc",
        type=float,
        default=None,
        help="DC-link voltage, V, for duty logs without U_dc (default: none)",
    )
    p.add_argument("--resample", action="store_true", help="resample an irregular time grid (with a warning)")
    checks.add_key_values_flag(
        p,
        "--option",
        "NAME=VALUE",
        "observer design-rule options, e.g. switching=sign pll_bandwidth=500 (default: the design rule)",
    )
    p.add_argument(
        "--hf-voltage",
        type=float,
        default=None,
        help="hfi-rotating: the log's carrier amplitude, V (default: the design rule's)",
    )
    p.add_argument(
        "--hf-frequency",
        type=float,
        default=None,
        help="hfi-rotating: the log's carrier frequency, Hz (default: a tenth of the sampling frequency)",
    )
    p.add_argument(
        "--polarity-known",
        action="store_true",
        help="hfi-rotating: report the angle in [-pi, pi) and score it modulo 2 pi (default: modulo pi)",
    )
    p.add_argument(
        "--observer-model",
        choices=("map", "constant"),
        help="on a drive file with a flux map: the observer reads the map at the operating current (map, the "
        "default there) or the file's constant L_d, L_q, psi_f (constant)",
    )
    p.add_argument("--no-figures", action="store_true", help="do not write observe.png")
    memory.add_memory_flag(p)
    p.set_defaults(func=run)


def _pairs(items, what) -> dict:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ParameterError(f"{what}: {item!r} is not KEY=VALUE.")
        out[key.strip()] = value.strip()
    return out


def _number_or_text(value: str):
    try:
        return float(value)
    except ValueError:
        return value


def run(args) -> int:
    """Run the chosen observer offline on the log ([`pmsmjax.jobs.observe`][pmsmjax.jobs.observe]); writes
    estimate.csv, observe.json and observe.png to ``--out``. Returns the exit status."""
    from pmsmjax.io.drive_files import drive_spec

    drive = drive_spec(args.motor)  # checked before JAX starts
    memory.check_log("observe", args.log, args.max_memory_gb)
    from pmsmjax.io.logs import check_output_folder
    from pmsmjax.jobs.observe import ObserveSpec, check_observer, run_observer

    # The command line is the one place where pmsmjax reaches up into the tuning workflows (the log reader
    # is shared with `pmsmjax identify`).
    from tuning.identify.stator_log import load_stator_log

    hf_flags = {"--hf-voltage": args.hf_voltage, "--hf-frequency": args.hf_frequency}
    given = [flag for flag, value in hf_flags.items() if value is not None]
    if args.polarity_known:
        given.append("--polarity-known")
    check_observer(args.observer, given)
    if args.observer_model is not None and drive.flux_map is None:
        raise ParameterError(
            f"--observer-model applies to a drive file with a flux map ([motor] flux_map); {args.motor} has "
            "none: drop it."
        )
    out = check_output_folder(args.out)
    if args.settle_s < 0:
        raise ParameterError(f"--settle-s must be >= 0 s, got {args.settle_s}.")
    truth = tuple(c.strip() for c in args.truth_columns.split(",") if c.strip())
    columns, units, dialect, log_table = checks.log_reading(args, {"u_dc", "resample"}, "observe")
    log = load_stator_log(
        args.log,
        columns=columns,
        units=units,
        u_dc=args.u_dc if args.u_dc is not None else log_table.get("u_dc"),
        resample=args.resample or bool(log_table.get("resample", False)),
        truth=truth,
        pole_pairs=drive.motor["pole_pairs"],
        dialect=dialect,
    )
    _check_excitation(log, drive, args.log)
    spec = ObserveSpec(
        observer=args.observer,
        drive=drive,
        motor=str(args.motor),
        log=str(args.log),
        settle_s=args.settle_s,
        truth=truth,
        options={k: _number_or_text(v) for k, v in _pairs(args.option, "--option").items()},
        hf_voltage=args.hf_voltage,
        hf_frequency=args.hf_frequency,
        polarity_known=args.polarity_known,
        observer_model=args.observer_model,
    )
    result = run_observer(spec, log)
    written = _write(result, out, figure_title=None if args.no_figures else f"{args.observer} on {args.log}")
    for line in result.report:
        print(line)
    print(
        f"{args.observer}: {log.n} samples in {result.summary['wall_time_s']:.2f} s; wrote "
        f"{', '.join(f'{out}/{w}' for w in written)}"
    )
    return 0


#: A log whose currents and voltages all stay below this share of the drive's current limit and DC link
#: carries no excitation: every observer would report its initial guess, and an error of 0 against it.
EXCITATION_SHARE = 1e-3


def _check_excitation(log, drive, path) -> None:
    """Refuse a log in which the drive did nothing (all-zero currents and voltages), before any compile."""
    import numpy as np

    i_peak = float(np.max(np.abs(log.i_ab))) if log.n else 0.0
    u_peak = float(np.max(np.abs(log.u_ab))) if log.n else 0.0
    i_floor = EXCITATION_SHARE * drive.current_limit_a
    u_floor = EXCITATION_SHARE * drive.u_dc_v
    if i_peak <= i_floor and u_peak <= u_floor:
        raise ParameterError(
            f"log {path}: no excitation (currents at most {i_peak:.3g} A, voltages at most {u_peak:.3g} V, "
            f"below {i_floor:.3g} A and {u_floor:.3g} V): an observer has nothing to estimate from and would "
            "report its starting guess; give a log of the drive running (check --columns and --units)."
        )


def _write(result, out, figure_title: str | None) -> list[str]:
    """Write estimate.csv, observe.json and (with a `figure_title`) observe.png of a
    [`ObserveResult`][pmsmjax.jobs.observe.ObserveResult] into the folder `out`; returns the names written."""
    from pmsmjax.io.logs import atomic_write, write_csv_atomic

    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(
        out / "estimate.csv", {"time": result.time, "theta_e": result.theta_e, "omega_m": result.omega_m}
    )
    atomic_write(out / "observe.json", lambda f: f.write(json.dumps(result.summary, indent=2).encode()))
    written = ["estimate.csv", "observe.json"]
    if figure_title is not None:
        from pmsmjax.plotting.observers import observer_log_figure
        from pmsmjax.plotting.traces import save_figure

        figure = observer_log_figure(
            result.time,
            result.theta_e,
            result.omega_m,
            result.truth,
            title=figure_title,
            modulo_pi=result.modulo_pi,
        )
        save_figure(figure, out / "observe.png")
        written.append("observe.png")
    return written
