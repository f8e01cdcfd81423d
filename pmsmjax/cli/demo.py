"""``pmsmjax demo`` (alias ``simulate``): the book scenario under a chosen control method, written as a
trace, summary.json and figures."""

import json
import time

from ..validation import ParameterError

CONTROL_NAMES = ("pi", "smc", "pr", "hysteresis", "dtc", "smc-dtc")

#: Command-line flag (argparse dest) -> preset option; flags left unset keep each preset's own default.
FLAG_OPTIONS = {
    "frame": "frame",
    "substeps": "n_substeps",
    "no_delay": "computation_delay",
    "current_bandwidth": "current_bandwidth",
    "speed_bandwidth": "speed_bandwidth",
    "field_weakening": "d_axis",
    "band_a": "band_a",
    "switching": "switching",
    "torque_band_nm": "torque_band_nm",
    "flux_band_wb": "flux_band_wb",
    "sample_period_us": "sample_period_s",
}


def control_drive_from_flags(args, motor):
    """The drive of ``args.control`` with the options the user set; a flag that does not apply to the
    chosen control is refused (``--band-a`` with ``--control pi``, say) instead of silently ignored."""
    from .. import presets
    from ..controls import control_drive, control_options

    allowed = control_options(args.control)
    options = {}
    for flag, option in FLAG_OPTIONS.items():
        value = getattr(args, flag, None)
        if value is None or value is False or (flag == "frame" and value == "dq"):
            continue
        if option not in allowed:
            raise ParameterError(f"--{flag.replace('_', '-')} does not apply to --control {args.control}.")
        if flag == "no_delay":
            value = False
        elif flag == "sample_period_us":
            value = value * 1e-6
        elif flag == "field_weakening":
            value = presets.field_weakening_block(args.current_bandwidth or presets.BOOK_CURRENT_BANDWIDTH)
        options[option] = value
    return control_drive(args.control, motor, **options)


def add_parser(sub):
    p = sub.add_parser(
        "demo",
        aliases=["simulate"],
        help="run the book scenario (FOC by default) and write figures, a trace and summary.json",
        description=(
            "Simulate the book drive (design-rule PI gains, SVPWM, averaged bridge, 10 kHz; or another "
            "control method with --control): a speed step from rest, then a load step. Writes "
            "DIR/trace.csv (or .npz), DIR/summary.json and PNG figures."
        ),
    )
    p.add_argument(
        "--control",
        choices=list(CONTROL_NAMES),
        default="pi",
        help="control method: pi (cascaded PI FOC, default), smc (sliding-mode speed loop), pr "
        "(proportional-resonant current loops in alpha-beta), hysteresis (current comparators at 100 kHz), "
        "dtc (switching-table direct torque control, 40 kHz samples), smc-dtc (sliding-mode DTC with SVPWM)",
    )
    p.add_argument("--out", default="demo_out", help="output folder (created), default: demo_out")
    p.add_argument("--motor", default="book", help="preset name (book, book_salient) or motor TOML file")
    p.add_argument("--speed-rpm", type=float, default=1000.0, help="speed step, r/min (default 1000)")
    p.add_argument("--load-nm", type=float, default=10.0, help="load step, N m (default 10)")
    p.add_argument("--load-time-s", type=float, default=0.2, help="time of the load step, s (default 0.2)")
    p.add_argument("--duration-s", type=float, default=0.4, help="simulated time, s (default 0.4)")
    p.add_argument("--frame", choices=["dq", "alpha_beta", "abc"], default="dq", help="machine model frame")
    p.add_argument("--substeps", type=int, help="RK4 sub-steps per control period (default 10; hysteresis 1)")
    p.add_argument("--no-delay", action="store_true", help="no one-period computational delay")
    p.add_argument("--current-bandwidth", type=float, help="current loop a_c, rad/s (default 1100)")
    p.add_argument("--speed-bandwidth", type=float, help="speed loop beta, rad/s (default 50)")
    p.add_argument("--field-weakening", action="store_true", help="MTPA and voltage-feedback field weakening")
    p.add_argument("--band-a", type=float, help="hysteresis band, A (full width; default 0.5)")
    p.add_argument(
        "--switching",
        choices=("sign", "saturation", "tanh"),
        help="switching function of smc (default sign, the book's) or smc-dtc (default saturation)",
    )
    p.add_argument("--torque-band-nm", type=float, help="dtc: full torque hysteresis band, N m (default 1)")
    p.add_argument("--flux-band-wb", type=float, help="dtc: full flux hysteresis band, Wb (default 0.01)")
    p.add_argument("--sample-period-us", type=float, help="dtc: comparator sample period, us (default 25)")
    p.add_argument("--decimate", type=int, default=1, help="record every N-th period (default 1)")
    p.add_argument("--format", choices=["csv", "npz"], default="csv", help="trace file format")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def run(args) -> int:
    import jax

    from .. import presets
    from ..logs import atomic_write, check_output_folder, write_csv_atomic
    from ..plotting import save_demo_figures
    from ..simulate import check_simulation, simulate
    from ..summary import speed_step_summary

    out = check_output_folder(args.out)
    motor = presets.load_motor(args.motor)
    drive = control_drive_from_flags(args, motor)
    scenario = presets.book_scenario(args.speed_rpm, args.load_nm, args.load_time_s, args.duration_s)
    check_simulation(drive, scenario, args.decimate)

    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=args.decimate))
    first_call_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=args.decimate))
    run_s = time.perf_counter() - t0

    load_time = args.load_time_s if 0 < args.load_time_s < args.duration_s else None
    summary = {
        "scenario": {
            "speed_rpm": args.speed_rpm,
            "load_nm": args.load_nm,
            "load_time_s": args.load_time_s,
            "duration_s": args.duration_s,
        },
        "drive": {
            "motor": args.motor,
            "control": args.control,
            "frame": args.frame,
            "Ts_s": drive.Ts,
            "n_substeps": drive.n_substeps,
            "computation_delay": drive.computation_delay,
            "options": {k: v for k, v in vars(args).items() if k in FLAG_OPTIONS and v not in (None, False)},
            "current_limit_a": float(drive.controller.current_limit),
            "u_dc_v": float(drive.bridge.u_dc),
        },
        "metrics": speed_step_summary(
            trace, load_time_s=load_time, current_limit_a=float(drive.controller.current_limit)
        ),
        "timing": {"compile_s": max(first_call_s - run_s, 0.0), "run_s": run_s},
    }

    out.mkdir(parents=True, exist_ok=True)
    columns = trace.columns()
    if args.format == "csv":
        write_csv_atomic(out / "trace.csv", columns)
    else:
        atomic_write(out / "trace.npz", lambda f: __import__("numpy").savez(f, **columns))
    atomic_write(out / "summary.json", lambda f: f.write(json.dumps(summary, indent=2).encode()))
    figures = (
        []
        if args.no_figures
        else save_demo_figures(trace, out, f"pmsmjax demo: book drive, {args.control} control")
    )
    m = summary["metrics"]
    print(
        f"final speed {m['final_speed_rpm']:.1f} r/min (ref {m['reference_speed_rpm']:.0f}), "
        f"rise {_fmt(m['rise_time_s'], 1e3)} ms, overshoot {m['overshoot_pct']:.2f} %, "
        f"settling {_fmt(m['settling_time_s'], 1e3)} ms"
    )
    if "speed_dip_rpm" in m:
        print(
            f"load step: dip {m['speed_dip_rpm']:.1f} r/min, recovery {_fmt(m['recovery_time_s'], 1e3)} ms; "
            f"peak current {m['peak_phase_current_a']:.2f} A (limit {m['current_limit_a']:.1f} A)"
        )
    print(f"compile {summary['timing']['compile_s']:.2f} s, run {summary['timing']['run_s'] * 1e3:.1f} ms")
    print(
        f"wrote {out}/trace.{args.format}, {out}/summary.json"
        + (f" and {len(figures)} figures" if figures else "")
    )
    return 0


def _fmt(x, scale):
    return "n/a" if x is None else f"{x * scale:.1f}"
