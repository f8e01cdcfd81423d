"""``pmsmjax compare``: control methods side by side on the book scenario
(:mod:`pmsmjax.controller_compare`)."""

import json
import time

from ..validation import ParameterError, plain
from . import checks
from .gains import add_gains_flag, apply_gains_flag, read_gains_flag


def add_parser(sub):
    p = sub.add_parser(
        "compare",
        help="run the book scenario with several control methods and compare them (compare.json, figures)",
        description=(
            "Each control method (pi, smc, pr, hysteresis, dtc, smc-dtc) drives the book motor through the "
            "book scenario (speed step from rest, then a load step). Writes DIR/compare.json (per "
            "controller: rise_time_s, overshoot_pct, dip_rpm, recovery_time_s, itae, peak_current_a, "
            "current_thd_pct, switching_frequency_hz, torque_ripple_nm, flux_ripple_wb, operating_point) and "
            "side-by-side figures. Ripple, THD, torque and flux ripple come from the last electrical "
            "periods, sampled inside each control period, with the switching-resolved bridge for "
            "voltage-commanding controllers; an operating point the drive cannot hold (above its top "
            "speed, or a load beyond its current limit) is refused, since its ripple figures would describe "
            "saturation."
        ),
    )
    p.add_argument(
        "--control",
        default=None,
        help="comma-separated methods: pi, smc, pr, hysteresis, dtc, smc-dtc (default: the chapter 3 four)",
    )
    p.add_argument(
        "--estimator",
        default=None,
        help="instead of control methods, compare chapter 5 observers (comma-separated: smo, smo-pll, "
        "adaptive-smo, dq-smo, mras, ekf; 'all' for the six) on the book PI drive, sensorless from "
        "standstill (I/f start): angle error RMS/max after convergence (el. deg), speed estimation error, "
        "ITAE, loss of lock, and the lowest speed held under the load step (a sweep of speed references "
        "downwards, also with the plant's R 30 %% above the observer's); writes compare.json, "
        "compare_estimators.md and figures",
    )
    p.add_argument("--out", default="compare_out", help="output folder (created), default: compare_out")
    p.add_argument(
        "--motor", default="book", help="preset name (book, book_salient) or motor TOML file (default book)"
    )
    p.add_argument(
        "--speed-rpm", type=checks.positive("r/min"), default=1000.0, help="speed step, r/min (default 1000)"
    )
    p.add_argument("--load-nm", type=checks.real("N m"), default=10.0, help="load step, N m (default 10)")
    p.add_argument(
        "--load-time-s", type=checks.positive("s"), default=0.2, help="time of the load step, s (default 0.2)"
    )
    p.add_argument(
        "--duration-s", type=checks.positive("s"), default=0.4, help="simulated time, s (default 0.4)"
    )
    p.add_argument(
        "--bridge",
        choices=("switching", "averaged"),
        default="switching",
        help="bridge of the voltage-commanding controllers (default switching: the PWM ripple is modelled)",
    )
    p.add_argument(
        "--equal-switching",
        nargs="?",
        type=checks.nonnegative("Hz"),
        const=0.0,
        metavar="HZ",
        help="also run each banded controller (dtc, hysteresis) with its bands scaled to this mean switching "
        "frequency, Hz (no value: the PWM frequency of the voltage-commanding controls), as NAME@F kHz "
        "(default: not run)",
    )
    add_gains_flag(p)
    p.add_argument(
        "--trust-units", action="store_true", help="accept motor values outside the plausible ranges"
    )
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def precheck(args) -> list[str]:
    """Checks that need no model (before JAX starts); returns the control (or observer) names."""
    from ..motor_files import motor_values
    from ..operating_point import refuse_unreachable
    from .demo import BOOK_CURRENT_LIMIT_A, BOOK_TS_S, BOOK_U_DC_V, CONTROL_NAMES, ESTIMATOR_NAMES

    if args.estimator is not None:
        names = _estimator_names(args, ESTIMATOR_NAMES)
        control = "pi"
    else:
        names = control = None
    known = CONTROL_NAMES
    control_list = args.control if args.control is not None else (control or "pi,smc,pr,hysteresis")
    controls = [n.strip() for n in control_list.split(",") if n.strip()]
    names = names if names is not None else controls
    unknown = [n for n in controls if n not in known]
    if not controls or unknown:
        raise ParameterError(
            f"--control {control_list!r}: unknown {', '.join(unknown) if unknown else 'empty list'}; "
            f"choose from {', '.join(known)} (comma separated)."
        )
    checks.output_folder(args.out)
    if not args.load_time_s < args.duration_s:
        raise ParameterError(
            f"--load-time-s {plain(args.load_time_s)} s is not inside the run (--duration-s "
            f"{plain(args.duration_s)} s): give a time below {plain(args.duration_s)} s."
        )
    gains = read_gains_flag(args.gains)
    if gains is not None and len(names) != 1:
        raise ParameterError(
            f"--gains {args.gains}: tuned gains belong to one control method; compare it alone with the "
            "design-rule version of another by running pmsmjax demo, or pass a single --control."
        )
    motor = motor_values(args.motor, check_units=not args.trust_units, Ts=BOOK_TS_S)
    if motor is not None:
        refuse_unreachable(
            motor,
            args.speed_rpm,
            args.load_nm,
            BOOK_U_DC_V,
            BOOK_U_DC_V / 3**0.5,
            BOOK_CURRENT_LIMIT_A,
            what="the comparison of ripple and THD",
        )
    return names


def _estimator_names(args, known) -> list[str]:
    """``--estimator`` as a list of observer names, refused with the fix when malformed or combined with
    flags that belong to the control comparison."""
    text = args.estimator
    names = list(known) if text.strip() == "all" else [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if not names or unknown:
        raise ParameterError(
            f"--estimator {text!r}: unknown {', '.join(unknown) if unknown else 'empty list'}; choose from "
            f"{', '.join(known)} (comma separated) or 'all'."
        )
    if args.control not in (None, "pi"):
        raise ParameterError(
            f"--estimator with --control {args.control!r}: the observers are compared on the book PI drive "
            "(FOC, which holds the I/f start-up current); drop --control or give --control pi."
        )
    for flag, value in (("--gains", args.gains), ("--equal-switching", args.equal_switching)):
        if value is not None:
            raise ParameterError(
                f"{flag} does not apply to --estimator (it tunes or matches control methods): drop it."
            )
    return names


def run(args) -> int:
    names = precheck(args)
    if args.estimator is not None:
        return run_estimators(args, names)

    from .. import presets
    from ..controller_compare import ControllerCompareSettings, compare_controllers
    from ..logs import atomic_write

    settings = ControllerCompareSettings(
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        load_time_s=args.load_time_s,
        duration_s=args.duration_s,
        bridge=args.bridge,
        equal_switching_hz=args.equal_switching,
    )
    settings.check()
    motor = presets.load_motor(args.motor, check_units=not args.trust_units)
    out = checks.output_folder(args.out)
    gains = read_gains_flag(args.gains)
    tune = None if gains is None else (lambda drive, name: apply_gains_flag(drive, gains, name))
    t0 = time.perf_counter()
    result = compare_controllers(names, motor, settings, progress=print, adjust=tune)
    report = {"settings": result["settings"], "controllers": result["controllers"]}
    report["settings"]["gains"] = args.gains
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
    for name, entry in result["controllers"].items():
        for f in entry["operating_point"]["flags"]:
            print(f"WARNING {name}: {f['flag']}: {f['cause']}; remedy: {f['remedy']}.")
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {report['wall_time_s']:.1f} s")
    return 0


def run_estimators(args, names: list[str]) -> int:
    """``pmsmjax compare --estimator``: the observers side by side (:func:`pmsmjax.controller_compare.
    compare_estimators`); writes compare.json, compare_estimators.md and figures."""
    import numpy as np

    from .. import presets
    from ..controller_compare import (
        ESTIMATOR_COLUMNS,
        ControllerCompareSettings,
        LowSpeedSweep,
        compare_estimators,
        estimator_table,
    )
    from ..logs import atomic_write
    from ..observer_metrics import angle_error

    settings = ControllerCompareSettings(
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        load_time_s=args.load_time_s,
        duration_s=args.duration_s,
        bridge=args.bridge,
    )
    settings.check()
    motor = presets.load_motor(args.motor, check_units=not args.trust_units)
    out = checks.output_folder(args.out)
    t0 = time.perf_counter()
    print("  ".join(h for h, _, _ in ESTIMATOR_COLUMNS))
    result = compare_estimators(names, motor, settings, LowSpeedSweep(load_nm=args.load_nm), progress=print)
    report = {"settings": result["settings"], "estimators": result["controllers"]}
    report["wall_time_s"] = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "compare.json", lambda f: f.write(json.dumps(report, indent=2).encode()))
    table = estimator_table(result) + "\n"
    atomic_write(out / "compare_estimators.md", lambda f: f.write(table.encode()))
    written = ["compare.json", "compare_estimators.md"]
    if not args.no_figures:
        from ..plotting import save_figure
        from ..plotting_compare import speed_figure
        from ..plotting_observers import angle_error_figure

        first = next(iter(result["traces"].values()))
        errors = {
            n: np.degrees(angle_error(tr.theta_e_est, tr.theta_e)) for n, tr in result["traces"].items()
        }
        angle = angle_error_figure(
            np.asarray(first.t),
            errors,
            speed_rpm=np.asarray(first.omega_m) * 30.0 / np.pi,
            title="Angle error, sensorless from standstill (I/f start), book scenario",
        )
        for name, fig in (("compare_speed.png", speed_figure(result)), ("compare_angle_error.png", angle)):
            save_figure(fig, out / name)
            written.append(name)
    for name, entry in result["controllers"].items():
        for f in entry["operating_point"]["flags"]:
            print(f"WARNING {name}: {f['flag']}: {f['cause']}; remedy: {f['remedy']}.")
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {report['wall_time_s']:.1f} s")
    return 0
