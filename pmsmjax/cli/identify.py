"""``pmsmjax identify``: motor parameters with error bars from a logged run (:mod:`tuning.identify`)."""

from pmsmjax.checks.validation import ParameterError
from pmsmjax.cli import checks


def add_parser(sub):
    p = sub.add_parser(
        "identify",
        help="identify R, L_d, L_q, psi_f, J, B with error bars from a logged drive run",
        description=(
            "Fit the PMSM model to a log (CSV/NPZ/MAT; default columns time,u_d,u_q,i_d,i_q,omega_m and "
            "optionally theta_e, T_L; alpha-beta/abc/duty voltages and alpha-beta/abc currents with theta_e) "
            "by output-error Levenberg-Marquardt over shooting windows. Writes DIR/params.json (value, "
            "stderr, ci95, identifiable per parameter; residuals; wall time) and DIR/fit.png. A parameter "
            "the log does not determine (L_d when i_d is held at zero, say) is reported NOT IDENTIFIABLE, "
            'without an interval. To try it, make a log with: python -c "from tuning.identify import '
            "identification_scenario; from pmsmjax.studies.synthetic_logs import ID_LOG_NOISE, "
            "add_measurement_noise, identification_log; from pmsmjax.io.logs import write_csv_atomic; "
            "write_csv_atomic('log.csv', "
            'add_measurement_noise(identification_log(identification_scenario()), ID_LOG_NOISE))" '
            "then pmsmjax identify log.csv --pole-pairs 4 --out id_out."
        ),
    )
    p.add_argument("log", help="log file (.csv, .npz or .mat)")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--pole-pairs", type=checks.count(), required=True, help="number of pole pairs (known)")
    p.add_argument(
        "--config",
        default=None,
        help="TOML with [columns], [units], [log], [identify] tables (default: none)",
    )
    p.add_argument(
        "--columns",
        nargs="+",
        default=[],
        metavar="CANONICAL=NAME",
        help="column map, e.g. u_d=Ud (default: the canonical names)",
    )
    p.add_argument(
        "--units",
        nargs="+",
        default=[],
        metavar="COLUMN=UNIT",
        help="e.g. omega_m=rpm time=ms (default: SI: s, V, A, rad/s, rad)",
    )
    p.add_argument(
        "--hold",
        choices=["auto", "stator", "rotor"],
        default=None,
        help="how the logged voltage was held between rows: stator (real inverter), rotor (dq-model "
        "simulator) or auto (default, as pmsmjax replay: both are fitted and the better is used)",
    )
    p.add_argument(
        "--u-dc",
        type=checks.positive("V"),
        default=None,
        help="DC-link voltage, V, for duty logs without a U_dc column (default: none)",
    )
    p.add_argument("--resample", action="store_true", help="resample an irregular time grid (with a warning)")
    p.add_argument(
        "--fix",
        nargs="+",
        default=[],
        metavar="NAME=VALUE",
        help="hold parameters fixed, SI units, e.g. L_d=0.0041 (default: none)",
    )
    p.add_argument(
        "--load",
        choices=["constant", "none"],
        default=None,
        help="load model: constant (default: estimate a constant load torque T_c besides a logged T_L) or "
        "none (only the logged T_L)",
    )
    p.add_argument("--dead-time", action="store_true", help="estimate an inverter dead-time voltage V_dt")
    p.add_argument("--no-figures", action="store_true", help="do not write fit.png")
    p.set_defaults(func=run)


def _finite(text: str) -> float:
    value = float(text)
    if not value == value or value in (float("inf"), float("-inf")):
        raise ValueError("not a finite number")
    return value


def _pairs(items, what, convert=str):
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            example = {"--fix": "L_d=0.0041", "--units": "time=ms"}.get(what, "u_d=Ud")
            raise ParameterError(f"{what} {item}: not KEY=VALUE; write e.g. {what} {example}.")
        try:
            out[key.strip()] = convert(value.strip())
        except ValueError:
            raise ParameterError(
                f"{what} {item}: {value.strip()!r} is not a finite number: give NAME=VALUE in SI units, "
                "e.g. L_d=0.0041."
            ) from None
    return out


def run(args) -> int:
    checks.existing_file(args.log, "log", "log file")
    checks.output_folder(args.out)
    if args.config is not None:
        checks.existing_file(args.config, "--config", "config file")
    fixed = _pairs(args.fix, "--fix", _finite)
    columns, units = _pairs(args.columns, "--columns"), _pairs(args.units, "--units")
    # The command line is the one place where pmsmjax reaches up into the tuning workflows.
    from tuning.identify import identify_file

    options = {"fixed": fixed} if fixed else {}
    if args.load:
        options["load"] = args.load
    if args.dead_time:
        options["dead_time"] = True
    result = identify_file(
        args.log,
        args.out,
        args.pole_pairs,
        config=args.config,
        columns=columns,
        units=units,
        hold=args.hold,
        u_dc=args.u_dc,
        resample=args.resample,
        figures=not args.no_figures,
        **options,
    )
    s = result.summary
    for note in s["log"]["notes"]:
        print(note)
    for name, p in s["parameters"].items():
        ci = p["ci95"]
        interval = f"[{ci[0]:.5g}, {ci[1]:.5g}]" if ci[0] is not None else "[not determined]"
        flag = "" if p["identifiable"] is not False else "  NOT IDENTIFIABLE"
        print(f"{name:6s} {p['value']:.6g} {p['unit']:10s} 95 % {interval}{flag}")
    for name, advice in s["identifiability"]["advice"].items():
        print(f"to determine {name}: {advice}")
    print(
        f"wall time {s['wall_time_s']:.2f} s; wrote {args.out}/params.json"
        + ("" if args.no_figures else ", fit.png")
    )
    return 0
