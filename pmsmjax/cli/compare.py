"""``pmsmjax compare``: control methods side by side on a drive's scenario (``--motor``: the book drive by
default, or a drive file), or observers (``--estimator``). The comparison itself is
[`pmsmjax.jobs.compare`][pmsmjax.jobs.compare]: this module parses the flags into its
[`CompareSpec`][pmsmjax.jobs.compare.CompareSpec] and writes its
[`CompareResult`][pmsmjax.jobs.compare.CompareResult]."""

import json

from pmsmjax.cli import checks, drive_flags
from pmsmjax.cli.gains import add_gains_flag, apply_gains_flag, read_gains_flag
from pmsmjax.jobs import compare as compare_job
from pmsmjax.spec import registry
from pmsmjax.spec.validation import ParameterError, plain


def add_parser(sub):
    """Add the ``compare`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "compare",
        help="run a drive's scenario with several control methods and compare them (compare.json, figures)",
        description=(
            "Each control method (pi, smc, pr, hysteresis, dtc, smc-dtc) drives the motor of --motor (the "
            "book drive by default, or a drive file: its DC link, control rate, current limit and "
            "bandwidths) through its scenario (speed step from rest, then a load step; the drive file's "
            "[scenario], book: 1000 r/min, 10 N m at 0.2 s, 0.4 s). Writes DIR/compare.json (per "
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
        "downwards, also with the plant's R 30 %% above the observer's); or the chapter 6 estimators "
        "(hfi-rotating, hfi-pulsating: angle scored modulo pi; hybrid) on the salient book motor with "
        "d-axis saturation, the rotor --initial-angle-deg off their initial estimate (see --scenario); "
        "writes compare.json, compare_estimators.md and figures (default: the control methods are "
        "compared). On a drive file with a flux map (saturated-ipm, pm-syrm) the chapter 5 observers and "
        "flux-observer run the file's own drive on its map, its I/f start and scenario, each observer "
        "reading the map (see --observer-model), the low-speed sweep scaled to the file's rated speed and "
        "scenario; the chapter 6 estimators are refused there",
    )
    p.add_argument(
        "--observer-model",
        choices=("map", "constant"),
        default=None,
        help="with --estimator on a drive file with a flux map: the observers read the map at the operating "
        "current (map, the default there) or keep the file's constant L_d, L_q, psi_f (constant)",
    )
    p.add_argument(
        "--scenario",
        choices=("book", "standstill", "slow-reversal", "reversal"),
        default=None,
        help="with --estimator: book (speed step, load step; default for the chapter 5 observers and the "
        "hybrid), standstill (speed 0, --load-nm stepped on at 0.1 s, 0.8 s; default for hfi-*), "
        "slow-reversal (0 -> 60 -> -60 r/min, --load-nm at 0.1 s, 0.8 s), reversal (hybrid: -1000 -> "
        "1000 r/min at 0.3 s under 5 N m from 0.15 s, 0.7 s)",
    )
    p.add_argument(
        "--initial-angle-deg",
        type=checks.real("el. deg"),
        default=None,
        help="with chapter 6 estimators: initial rotor angle, electrical degrees off their initial estimate "
        "(default 30; the injection methods without polarity lock to the wrong pole beyond 90)",
    )
    p.add_argument(
        "--machine",
        choices=("three-phase", "six-phase", "five-phase"),
        default="three-phase",
        help="with --control: three-phase (default), six-phase (controls vsd, double-dq, conventional, pr) "
        "or five-phase (vsd, conventional, pr), book ch. 7-10 (--motor book: the book motor's rewinds)",
    )
    drive_flags.add_drive_flags(p, "compare_out", None, "book; book_salient for the chapter 6 estimators")
    # The load step inside a run with a ripple window at speed: a speed and a load time above 0.
    drive_flags.add_scenario_flags(
        p, types={"speed_rpm": checks.positive("r/min"), "load_time_s": checks.positive("s")}
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
    drive_flags.add_trust_units_flag(p)
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def precheck(args):
    """Checks that need no model (before JAX starts); returns the control (or observer) names and the
    drive ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]), the scenario flags left unset filled from it."""
    multiphase = args.machine != "three-phase"
    if multiphase:
        for flag, value in (("--estimator", args.estimator), ("--equal-switching", args.equal_switching)):
            if value is not None:
                raise ParameterError(
                    f"{flag} applies to the three-phase drive; with --machine {args.machine} compare its "
                    "control schemes (--control), or drop --machine."
                )
    chapter6 = False
    if args.estimator is not None:
        observers = registry.names("estimator", group="observer")
        names = _estimator_names(args, (*observers, *CHAPTER6_NAMES), observers)
        chapter6 = any(n in CHAPTER6_NAMES for n in names)
        _chapter6_flags(args, names, chapter6)
        if chapter6:
            from pmsmjax.jobs.estimator_comparison import check_estimator_scenario

            check_estimator_scenario(names, args.scenario)
        control = "pi"
    else:
        names = control = None
        for flag, value in (("--scenario", args.scenario), ("--initial-angle-deg", args.initial_angle_deg)):
            if value is not None:
                raise ParameterError(f"{flag} belongs to --estimator: give --estimator NAMES or drop it.")
    if args.motor is None:
        args.motor = "book_salient" if chapter6 else "book"
    spec = drive_flags.resolve_drive(args, drive_flags.MACHINE_PHASES[args.machine])
    fixed = args.scenario not in (None, "book")
    for flag, key in (
        ("--speed-rpm", "speed_rpm"),
        ("--load-time-s", "load_time_s"),
        ("--duration-s", "duration_s"),
    ):
        if getattr(args, key) is not None and fixed:
            raise ParameterError(
                f"{flag} sets the book scenario; --scenario {args.scenario} is a fixed run (only --load-nm "
                "applies): drop it or give --scenario book."
            )
    speed_given = args.speed_rpm is not None
    drive_flags.fill_scenario(args, spec)
    if not fixed:
        args.speed_rpm, note = compare_job.fitting_speed(args.speed_rpm, spec, speed_given)
        if note:
            print(note)
    known = registry.names("control", args.machine)
    default = ",".join(known) if multiphase else (control or "pi,smc,pr,hysteresis")
    control_list = args.control if args.control is not None else default
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
    motor = spec.motor
    on_map = args.estimator is not None and "flux_map" in motor
    if args.observer_model is not None and not on_map:
        raise ParameterError(
            "--observer-model applies to --estimator on a drive file with a flux map ([motor] flux_map), "
            "where the observers may read the map or its constants: drop it."
        )
    if on_map and chapter6:
        _check_injection_region(args, spec, names)
    if chapter6 and not on_map and not motor["L_q"] > motor["L_d"]:
        raise ParameterError(
            f"--motor {args.motor}: L_q = {plain(motor['L_q'])} H is not above L_d = "
            f"{plain(motor['L_d'])} H; HF injection needs a salient machine: give --motor book_salient or "
            "a salient drive file."
        )
    if not fixed:
        compare_job.check_operating_point(spec, args.speed_rpm, args.load_nm, drive_flags.U_DC_KNOB)
    return names, spec


def _check_injection_region(args, spec, names) -> None:
    """On a drive file with a flux map: the injection region's refusals
    ([`pmsmjax.jobs.estimator_comparison.check_injection_region`][pmsmjax.jobs.estimator_comparison.check_injection_region]),
    the load named by where it came from (``--load-nm`` or the file's ``[scenario] load_nm``)."""
    from pmsmjax.jobs.estimator_comparison import check_injection_region

    check_injection_region(spec, names, args.load_nm, drive_flags.scenario_name(args, "load_nm"))


#: The chapter 6 estimators ``compare --estimator`` takes (the keys of
#: [`pmsmjax.estimators.INJECTION_OBSERVERS`][pmsmjax.estimators.catalogue.INJECTION_OBSERVERS] and
#: ``HYBRID_OBSERVERS``; spelled here so that the checks run before JAX starts,
#: tests/studies/test_hfi_compare.py checks they agree).
CHAPTER6_NAMES = registry.names("estimator", group="injection") + registry.names("estimator", group="hybrid")


def _chapter6_flags(args, names: list[str], chapter6: bool) -> None:
    """Fill in --scenario (book; standstill when an injection method is compared) and refuse what does
    not fit before JAX starts (the scenario-estimator pairs themselves:
    [`pmsmjax.jobs.estimator_comparison.check_estimator_scenario`][pmsmjax.jobs.estimator_comparison.check_estimator_scenario])."""
    if args.scenario is None:
        injection = any(n.startswith("hfi-") for n in names)
        args.scenario = "standstill" if injection else "book"
    if not chapter6:
        if args.scenario != "book":
            raise ParameterError(
                f"--scenario {args.scenario} is for the chapter 6 estimators ({', '.join(CHAPTER6_NAMES)}); "
                "the chapter 5 observers are compared on the book scenario: drop --scenario."
            )
        if args.initial_angle_deg is not None:
            raise ParameterError(
                "--initial-angle-deg is for the chapter 6 estimators (the chapter 5 observers start with "
                "I/f from angle 0): drop it."
            )


def _estimator_names(args, known, everything) -> list[str]:
    """``--estimator`` as a list of observer names, refused with the fix when malformed or combined with
    flags that belong to the control comparison."""
    text = args.estimator
    names = list(everything) if text.strip() == "all" else [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if not names or unknown:
        raise ParameterError(
            f"--estimator {text!r}: unknown {', '.join(unknown) if unknown else 'empty list'}; choose from "
            f"{', '.join(known)} (comma separated) or 'all' (the six chapter 5 observers)."
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


def chapter6_run(names) -> bool:
    """Whether the compared estimators are chapter 6's."""
    return any(n in CHAPTER6_NAMES for n in names)


def run(args) -> int:
    """Run the drive's scenario under each chosen control method (or observer, ``--estimator``);
    writes compare.json and figures to ``--out``. Returns the exit status."""
    names, spec = precheck(args)
    request = compare_job.CompareSpec(
        drive=spec,
        names=tuple(names),
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        load_time_s=args.load_time_s,
        duration_s=args.duration_s,
        machine=args.machine,
        bridge=args.bridge,
        equal_switching_hz=args.equal_switching,
        gains=args.gains,
        estimators=args.estimator is not None,
        scenario=args.scenario,
        initial_angle_deg=args.initial_angle_deg,
        observer_model=args.observer_model,
    )
    out = checks.output_folder(args.out)
    if request.estimators:
        result = compare_job.compare_observers(request, progress=print)
    else:
        gains = read_gains_flag(args.gains)
        tune = None if gains is None else (lambda drive, name: apply_gains_flag(drive, gains, name))
        result = compare_job.compare_controls(request, adjust=tune, progress=print)
    write(args, request, result, out)
    return 0


def write(args, request: compare_job.CompareSpec, result: compare_job.CompareResult, out) -> None:
    """Write compare.json, compare_estimators.md (observers) and, unless ``--no-figures``, the figures into
    the folder ``out``; then print the warnings and what was written."""
    from pmsmjax.io.logs import atomic_write

    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "compare.json", lambda f: f.write(json.dumps(result.report, indent=2).encode()))
    written = ["compare.json"]
    if result.table is not None:
        atomic_write(out / "compare_estimators.md", lambda f: f.write(result.table.encode()))
        written.append("compare_estimators.md")
    if not args.no_figures:
        from pmsmjax.plotting.traces import save_figure

        figures = observer_figures(request, result) if request.estimators else control_figures(result)
        for name, fig in figures:
            save_figure(fig, out / name)
            written.append(name)
    for line in result.warnings:
        print(line)
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {result.report['wall_time_s']:.1f} s")


def control_figures(result: compare_job.CompareResult) -> list:
    """``[(file name, figure)]`` of the control methods: speed, ripple and flux side by side."""
    from pmsmjax.plotting.compare import flux_figure, ripple_figure, speed_figure

    comparison = result.comparison
    return [
        ("compare_speed.png", speed_figure(comparison)),
        ("compare_ripple.png", ripple_figure(comparison)),
        ("compare_flux.png", flux_figure(comparison)),
    ]


def observer_figures(request: compare_job.CompareSpec, result: compare_job.CompareResult) -> list:
    """``[(file name, figure)]`` of the observers: the speeds and the angle errors."""
    from pmsmjax.plotting.compare import speed_figure
    from pmsmjax.plotting.observers import angle_error_figure

    chapter6 = chapter6_run(request.names)
    angle0 = result.comparison["settings"]["initial_angle_deg"]
    start = f"rotor {angle0:g} el. deg off" if chapter6 else "I/f"
    angles = result.angle_errors
    where = f"{request.scenario} scenario"
    if request.drive.flux_map is not None:  # the file's own drive and scenario, on its map
        model = request.observer_model or "map"
        where = f"{drive_flags.drive_name(request.drive)} on its flux map, observers on the {model}"
    angle = angle_error_figure(
        angles["t"],
        angles["errors"],
        speed_rpm=angles["speed_rpm"],
        title=f"Angle error, sensorless from standstill ({start}), {where}",
        ylim=20.0 if chapter6 else 5.0,
    )
    speed = (
        speed_figure(result.comparison)
        if request.scenario == "book"
        else speed_figure(
            result.comparison,
            title=f"Speed, {request.scenario} scenario",
            load_time_s=result.load_time_s,
        )
    )
    return [("compare_speed.png", speed), ("compare_angle_error.png", angle)]
