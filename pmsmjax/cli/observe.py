"""``pmsmjax observe``: run a chapter 5 observer, or the rotating HF-injection estimator of chapter 6, offline
on a recorded drive log ([`pmsmjax.studies.offline_observer`][pmsmjax.studies.offline_observer]).

``hfi-rotating`` reads the carrier from the log's voltages (``carrier="measured"``: the log's drive
injected it, this run does not), and its angle is the d axis modulo pi: ``estimate.csv`` gives it in
[-pi/2, pi/2) and the errors are taken modulo pi, unless ``--polarity-known``. ``hfi-pulsating`` is
refused: its demodulation needs the injection axis of the drive that made the log, which a log does not
record.
"""

import json
import time

from pmsmjax.checks.validation import ParameterError


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
    p.add_argument("log", help="log file (.csv, .npz or .mat)")
    p.add_argument(
        "--motor",
        required=True,
        help="the observer's motor model and pole pairs: a preset name (book, book_salient, servo-400w, ...) "
        "or a drive TOML file (its [motor]; a seven-value motor file is one)",
    )
    p.add_argument(
        "--observer",
        required=True,
        help="smo, smo-pll, adaptive-smo, dq-smo, mras, ekf, or hfi-rotating (logs of a salient machine with "
        "rotating injection)",
    )
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument(
        "--config", default=None, help="TOML with [columns], [units] and [log] tables (default: none)"
    )
    p.add_argument(
        "--columns",
        nargs="+",
        default=[],
        metavar="CANONICAL=NAME",
        help="column map, e.g. i_alpha=Ialpha (default: the canonical names)",
    )
    p.add_argument(
        "--units", nargs="+", default=[], metavar="COLUMN=UNIT", help="e.g. time=ms omega_m=rpm (default: SI)"
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
    p.add_argument(
        "--option",
        nargs="+",
        default=[],
        metavar="NAME=VALUE",
        help="observer design-rule options, e.g. switching=sign pll_bandwidth=500 (default: the design rule)",
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
    p.add_argument("--no-figures", action="store_true", help="do not write observe.png")
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
    """Run the chosen observer offline on the log; writes estimate.csv, observe.json and observe.png
    to ``--out``. Returns the exit status."""
    from pmsmjax.io.drive_files import drive_spec

    spec = drive_spec(args.motor)  # checked before JAX starts
    import numpy as np

    from pmsmjax.analysis.observer_errors import error_statistics
    from pmsmjax.estimators.registry import INJECTION_OBSERVERS, check_observer_name, make_observer
    from pmsmjax.frames.three_phase import wrap_angle
    from pmsmjax.io.logs import atomic_write, check_output_folder, write_csv_atomic
    from pmsmjax.presets.user_drive import spec_motor
    from pmsmjax.studies.offline_observer import observe

    # The command line is the one place where pmsmjax reaches up into the tuning workflows (the log reader
    # is shared with `pmsmjax identify`).
    from tuning.identify.log import load_stator_log, read_log_config

    check_observer_name(args.observer)
    injection = args.observer in INJECTION_OBSERVERS
    if args.observer == "hfi-pulsating":
        raise ParameterError(
            "observer 'hfi-pulsating' cannot run offline: its demodulation needs the injection axis of the "
            "drive that made the log, which a log does not record; use --observer hfi-rotating on logs "
            "with rotating injection."
        )
    if args.observer == "hybrid":
        raise ParameterError(
            "observer 'hybrid' cannot run offline: it commands start-up polarity pulses and fades its "
            "carrier with its own speed estimate, which a recorded log cannot follow; run its parts, "
            "--observer hfi-rotating and a chapter 5 observer, on the log instead."
        )
    hf_flags = {"--hf-voltage": args.hf_voltage, "--hf-frequency": args.hf_frequency}
    given = [flag for flag, value in hf_flags.items() if value is not None]
    if args.polarity_known:
        given.append("--polarity-known")
    if given and not injection:
        raise ParameterError(
            f"{', '.join(given)} apply to the HF-injection observer hfi-rotating only, not {args.observer!r}."
        )
    out = check_output_folder(args.out)
    motor = spec_motor(spec)
    if args.settle_s < 0:
        raise ParameterError(f"--settle-s must be >= 0 s, got {args.settle_s}.")
    truth = tuple(c.strip() for c in args.truth_columns.split(",") if c.strip())
    cfg = read_log_config(args.config) if args.config else {"columns": {}, "units": {}, "log": {}}
    bad = sorted(set(cfg["log"]) - {"u_dc", "resample"})
    if bad:
        raise ParameterError(f"[log] table: unknown keys {bad}; allowed for observe: u_dc, resample.")
    log = load_stator_log(
        args.log,
        columns={**cfg["columns"], **_pairs(args.columns, "--columns")},
        units={**cfg["units"], **_pairs(args.units, "--units")},
        u_dc=args.u_dc if args.u_dc is not None else cfg["log"].get("u_dc"),
        resample=args.resample or bool(cfg["log"].get("resample", False)),
        truth=truth,
        pole_pairs=motor.pole_pairs,
    )
    options = {k: _number_or_text(v) for k, v in _pairs(args.option, "--option").items()}
    if injection:
        # the log's drive injected the carrier: take its phase from the logged voltages
        options.setdefault("carrier", "measured")
        if args.hf_voltage is not None:
            options["hf_voltage"] = args.hf_voltage
        if args.hf_frequency is not None:
            options["hf_frequency"] = args.hf_frequency
    observer = make_observer(args.observer, motor, log.Ts, **options)

    t0 = time.perf_counter()
    est = observe(observer, log.u_ab, log.i_ab, log.Ts)
    theta, omega = np.asarray(est.theta_e, dtype=np.float64), np.asarray(est.omega_m, dtype=np.float64)
    wall = time.perf_counter() - t0
    modulo_pi = injection and not args.polarity_known
    if modulo_pi:
        theta = 0.5 * wrap_angle(2.0 * theta)  # the d axis modulo pi, [-pi/2, pi/2)
    bad_rows = ~(np.isfinite(theta) & np.isfinite(omega))
    if bad_rows.any():
        row = int(np.argmax(bad_rows))
        raise ParameterError(
            f"observer {args.observer!r} diverged (not finite from row {row}, t = {log.time[row]:.6g} s); "
            "nothing written: check the motor parameters (--motor), the log's units (--units) and the "
            "observer options."
        )

    summary = {
        "observer": args.observer,
        "motor": str(args.motor),
        "drive_file": spec.summary(),
        "log": str(args.log),
        "samples": int(log.n),
        "Ts_s": log.Ts,
        "options": options,
        "notes": list(log.notes),
        "wall_time_s": wall,
        "angle_modulo_pi": bool(modulo_pi),
    }
    if truth:
        summary["errors"] = _errors(log, theta, omega, args.settle_s, error_statistics, modulo_pi)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / "estimate.csv", {"time": log.time, "theta_e": theta, "omega_m": omega})
    atomic_write(out / "observe.json", lambda f: f.write(json.dumps(summary, indent=2).encode()))
    written = ["estimate.csv", "observe.json"]
    if not args.no_figures:
        from pmsmjax.plotting.observers import observer_log_figure
        from pmsmjax.plotting.traces import save_figure

        save_figure(
            observer_log_figure(
                log.time, theta, omega, log.truth, title=f"{args.observer} on {args.log}", modulo_pi=modulo_pi
            ),
            out / "observe.png",
        )
        written.append("observe.png")
    if truth:
        e = summary["errors"]
        parts = []
        if "angle_rms_deg" in e:
            parts.append(f"angle error {e['angle_rms_deg']:.3g} deg RMS (max {e['angle_max_deg']:.3g})")
        if "speed_rms_rpm" in e:
            parts.append(f"speed error {e['speed_rms_rpm']:.3g} r/min RMS")
        print(f"after {args.settle_s:g} s: " + ", ".join(parts))
    print(
        f"{args.observer}: {log.n} samples in {wall:.2f} s; wrote {', '.join(f'{out}/{w}' for w in written)}"
    )
    return 0


def _errors(log, theta, omega, settle_s, error_statistics, modulo_pi=False) -> dict:
    """Error figures against the truth columns present (angle: electrical deg; speed: mechanical r/min)."""
    import numpy as np

    if log.time[-1] - log.time[0] <= settle_s:
        raise ParameterError(
            f"--settle-s {settle_s} s is not shorter than the log ({log.time[-1] - log.time[0]:.4g} s): "
            "lower it so some samples are scored."
        )
    th_true = log.truth.get("theta_e", theta)
    w_true = log.truth.get("omega_m", omega)
    stats = error_statistics(log.time, theta, omega, th_true, w_true, settle_s, modulo_pi=modulo_pi)
    keys = {"samples"}
    if "theta_e" in log.truth:
        keys |= {"angle_rms_deg", "angle_mean_deg", "angle_max_deg"}
    if "omega_m" in log.truth:
        keys |= {"speed_rms_rpm", "speed_max_rpm"}
    out = {k: v for k, v in stats.items() if k in keys}
    out["settle_s"] = float(settle_s)
    out["finite"] = bool(np.all(np.isfinite(list(out.values()))))
    return out
