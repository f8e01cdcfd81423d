"""``pmsmjax replay``: run the machine under a recorded voltage sequence
([`pmsmjax.jobs.replay`][pmsmjax.jobs.replay])."""

from pathlib import Path

from pmsmjax.cli import checks, drive_flags, memory
from pmsmjax.spec.validation import ParameterError

#: The columns replay reads ([`pmsmjax.recorded.replay.LOG_COLUMNS`][pmsmjax.recorded.replay.LOG_COLUMNS]),
#: named here so that the flags are checked before anything heavy is imported.
READS = ("time", "u_d", "u_q", "omega_m", "T_L", "theta_e", "i_d", "i_q", "d_a", "d_b", "d_c", "U_dc")


def add_parser(sub):
    """Add the ``replay`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "replay",
        help="run the machine under a recorded voltage sequence",
        description=(
            "Replay a log (CSV/NPZ/MAT; columns mapped with --columns, units with --units or the names' "
            "suffixes, the file's dialect with --config [log]) with columns time,u_d,u_q (or the leg duties "
            "d_a,d_b,d_c and U_dc, through the averaged inverter with the drive file's [inverter] dead time "
            "and device drop, stator-frame hold) and optionally "
            "omega_m (imposed speed, mechanical rad/s), T_L (N m), theta_e, i_d, i_q (row 0: the initial "
            "state). Row k's voltage is held until row k+1. Writes DIR/replay.csv with "
            "time,i_d,i_q,omega_m,theta_e (row k = state at row k's time; time in s). A column that looks "
            "like a misspelt one of these (omega for omega_m) is refused; other columns are reported as not "
            "used."
        ),
    )
    drive_flags.add_logged_motor_flags(p, "the machine")
    checks.add_out_flag(p)
    p.add_argument(
        "--hold",
        choices=["auto", "rotor", "stator"],
        default="auto",
        help="frame the voltage is held in between rows: stator (a real inverter), rotor (dq-model "
        "simulators) or auto (default, as pmsmjax identify: the one whose replay matches the log's own "
        "i_d, i_q; stator when the log has none)",
    )
    checks.add_log_column_flags(
        p,
        "u_d=Ud",
        "e.g. time=ms omega_m=erpm (default: SI: s, V, A, rad/s, rad, or the unit in a column's name)",
    )
    p.add_argument(
        "--time-unit",
        choices=["s", "ms", "us"],
        default=None,
        help="unit of the time column, as --units time=UNIT (default s)",
    )
    p.add_argument(
        "--substeps", type=checks.count(), default=None, help="RK4 steps per row (default: automatic)"
    )
    p.add_argument(
        "--trust-units",
        action="store_true",
        help="accept a time step or motor values outside the plausible ranges (a 0.1 s step, an inductance "
        "above 1 H) instead of refusing them as a likely unit mistake",
    )
    memory.add_memory_flag(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """Run the machine under the log's recorded voltages ([`pmsmjax.jobs.replay`][pmsmjax.jobs.replay]);
    writes the simulated dq currents, speed and angle (replay.csv) to ``--out``. Returns the exit status."""
    checks.existing_file(args.log, "log", "log file")
    checks.output_folder(args.out)
    from pmsmjax.io.drive_files import drive_spec

    drive_spec(args.motor, check_units=not args.trust_units)  # refused here, before JAX starts
    columns, units, dialect, _ = checks.log_reading(args, set(), "replay", readable=READS)
    if args.time_unit is not None:
        if units.get("time", args.time_unit) != args.time_unit:
            raise ParameterError(
                f"--time-unit {args.time_unit} contradicts the time unit {units['time']} of --units or "
                "[units]: give one of them."
            )
        units["time"] = args.time_unit
    memory.check_log("replay", args.log, args.max_memory_gb)
    from pmsmjax.jobs.replay import ReplaySpec, run_replay

    spec = ReplaySpec(
        args.log,
        args.motor,
        hold=args.hold,
        n_substeps=args.substeps,
        check_units=not args.trust_units,
        columns=columns,
        units=units,
        dialect=dialect,
    )
    result = run_replay(spec)
    path = _write(result, args.out)
    for note in result.notes:
        print(note)
    print(f"wrote {path}")
    return 0


def _write(result, out) -> Path:
    """Write ``out/replay.csv`` (atomically) from a [`ReplayResult`][pmsmjax.jobs.replay.ReplayResult];
    returns its path."""
    from pmsmjax.io.logs import write_csv_atomic

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return write_csv_atomic(out / "replay.csv", result.columns)
