"""``pmsmjax compare``: control methods side by side on the book scenario
(:mod:`pmsmjax.controller_compare`)."""

import json
import time

from ..validation import ParameterError


def add_parser(sub):
    p = sub.add_parser(
        "compare",
        help="run the book scenario with several control methods and compare them (compare.json, figures)",
        description=(
            "Each control method (pi, smc, pr, hysteresis, dtc, smc-dtc) drives the book motor through the "
            "book scenario (speed step from rest, then a load step). Writes DIR/compare.json (per "
            "controller: rise_time_s, overshoot_pct, dip_rpm, recovery_time_s, itae, peak_current_a, "
            "current_thd_pct, switching_frequency_hz, torque_ripple_nm, flux_ripple_wb) and side-by-side "
            "figures. Ripple, THD, torque and flux ripple come from the last electrical periods, sampled "
            "inside each control period, with the switching-resolved bridge for voltage-commanding "
            "controllers."
        ),
    )
    p.add_argument(
        "--control",
        default="pi,smc,pr,hysteresis",
        help="comma-separated methods: pi, smc, pr, hysteresis, dtc, smc-dtc (default: the chapter 3 four)",
    )
    p.add_argument("--out", default="compare_out", help="output folder (created), default: compare_out")
    p.add_argument("--motor", default="book", help="preset name (book, book_salient) or motor TOML file")
    p.add_argument("--speed-rpm", type=float, default=1000.0, help="speed step, r/min (default 1000)")
    p.add_argument("--load-nm", type=float, default=10.0, help="load step, N m (default 10)")
    p.add_argument("--load-time-s", type=float, default=0.2, help="time of the load step, s (default 0.2)")
    p.add_argument("--duration-s", type=float, default=0.4, help="simulated time, s (default 0.4)")
    p.add_argument(
        "--bridge",
        choices=("switching", "averaged"),
        default="switching",
        help="bridge of the voltage-commanding controllers (default switching: the PWM ripple is modelled)",
    )
    p.add_argument(
        "--equal-switching",
        nargs="?",
        type=float,
        const=0.0,
        metavar="HZ",
        help="also run each banded controller (dtc, hysteresis) with its bands scaled to this mean switching "
        "frequency, Hz (no value: the PWM frequency of the voltage-commanding controls), as NAME@F kHz",
    )
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def run(args) -> int:
    from .. import presets
    from ..controller_compare import ControllerCompareSettings, compare_controllers
    from ..controls import CONTROLS
    from ..logs import atomic_write, check_output_folder

    names = [n.strip() for n in args.control.split(",") if n.strip()]
    unknown = [n for n in names if n not in CONTROLS]
    if not names or unknown:
        raise ParameterError(
            f"--control {args.control!r}: unknown {unknown or 'empty list'}; "
            f"choose from {', '.join(CONTROLS)}."
        )
    settings = ControllerCompareSettings(
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        load_time_s=args.load_time_s,
        duration_s=args.duration_s,
        bridge=args.bridge,
        equal_switching_hz=args.equal_switching,
    )
    settings.check()
    motor = presets.load_motor(args.motor)
    out = check_output_folder(args.out)
    t0 = time.perf_counter()
    result = compare_controllers(names, motor, settings, progress=print)
    report = {"settings": result["settings"], "controllers": result["controllers"]}
    report["wall_time_s"] = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "compare.json", lambda f: f.write(json.dumps(report, indent=2).encode()))
    written = ["compare.json"]
    if not args.no_figures:
        from ..plotting import save_figure
        from ..plotting_compare import flux_figure, ripple_figure, speed_figure

        for name, fig in (
            ("compare_speed.png", speed_figure(result)),
            ("compare_ripple.png", ripple_figure(result)),
            ("compare_flux.png", flux_figure(result)),
        ):
            save_figure(fig, out / name)
            written.append(name)
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {report['wall_time_s']:.1f} s")
    return 0
