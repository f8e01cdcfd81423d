"""``pmsmjax demo`` (alias ``simulate``): the drive's scenario (``--motor``: the book drive by default, or a
drive file, [`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]) under a chosen control method, written as a
trace, summary.json and figures; ``--machine six-phase`` runs the dual three-phase drive (book ch. 7-9),
``--machine five-phase`` the five-phase drive (book ch. 10).

Before any work: the flags (`pmsmjax.cli.checks`), ``--out``, the drive file (its units,
[`pmsmjax.checks.plausibility`][pmsmjax.checks.plausibility], and its ratings; `pmsmjax.cli.drive_flags`), the
gains file, the load step inside the run, and a speed the drive could reach at all. After the run,
``summary.json`` says whether the speed reached its reference and how much of the run sat at the voltage or
current limit ([`pmsmjax.analysis.operating_point.run_flags`][pmsmjax.analysis.operating_point.run_flags]),
and the console repeats every such flag with its cause and remedy.
"""

import json
import math
import time

from pmsmjax.checks.validation import ParameterError, plain
from pmsmjax.cli import checks, drive_flags
from pmsmjax.cli.gains import add_gains_flag, apply_gains_flag, read_gains_flag

CONTROL_NAMES = ("pi", "smc", "pr", "hysteresis", "dtc", "smc-dtc")
#: ``--machine six-phase``: the schemes of pmsmjax.presets.six_phase.SIX_PHASE_CONTROLS (listed here so
#: that ``--help`` needs no JAX import), its modulators and model frames.
SIX_PHASE_CONTROL_NAMES = ("vsd", "double-dq", "conventional", "pr")
SIX_PHASE_PWM_NAMES = ("four-vector", "two-vector", "decoupled", "double-zs")
THREE_PHASE_FRAMES = ("dq", "alpha_beta", "abc")
SIX_PHASE_FRAME_NAMES = ("dq", "vsd", "double-dq", "natural")
#: ``--machine five-phase``: pmsmjax.presets.five_phase.FIVE_PHASE_CONTROLS, _PWMS, _FRAMES.
FIVE_PHASE_CONTROL_NAMES = ("vsd", "conventional", "pr")
FIVE_PHASE_PWM_NAMES = ("near-four-vector", "carrier", "sinusoidal", "large-vector")
FIVE_PHASE_FRAME_NAMES = ("dq", "vsd", "natural")
#: Per multi-phase machine: (controls, modulators, frames, default modulator).
MULTIPHASE_NAMES = {
    "six-phase": (SIX_PHASE_CONTROL_NAMES, SIX_PHASE_PWM_NAMES, SIX_PHASE_FRAME_NAMES, "four-vector"),
    "five-phase": (
        FIVE_PHASE_CONTROL_NAMES,
        FIVE_PHASE_PWM_NAMES,
        FIVE_PHASE_FRAME_NAMES,
        "near-four-vector",
    ),
}
#: Flags the six- and five-phase drives take (argparse dest -> six_phase_drive / five_phase_drive option).
SIX_PHASE_FLAG_OPTIONS = {
    "frame": "frame",
    "substeps": "n_substeps",
    "no_delay": "computation_delay",
    "current_bandwidth": "current_bandwidth",
    "speed_bandwidth": "speed_bandwidth",
    "current_limit": "current_limit",
    "pwm": "pwm",
    "bridge": "bridge",
}

#: ``--estimator``: the chapter 5 observers
#: ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]; listed here so the flags are
#: checked before JAX starts) and the controls that can run on one (FOC cascades: they hold the I/f start-up
#: current).
ESTIMATOR_NAMES = ("smo", "smo-pll", "adaptive-smo", "dq-smo", "mras", "ekf")
SENSORLESS_CONTROLS = ("pi", "smc", "pr")

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
    "current_limit": "current_limit",
}

#: The library's names in messages -> this command's flags.
USER_TERMS = {
    "Drive.n_substeps": "--substeps",
    "Scenario.duration_s": "--duration-s",
    "current_limit": "--current-limit",
}

#: The names the operating-point flags use for this command's flags.
OPERATING_FLAGS = {
    "speed": "--speed-rpm",
    "load": "--load-nm",
    "duration": "--duration-s",
    "field_weakening": "--field-weakening",
    "current_limit": "--current-limit",
    "u_dc": drive_flags.U_DC_KNOB,
}

#: A reference beyond this many times the top speed the drive could reach at no load is refused: the run
#: would only show saturation (up to it, the run is made and its saturation reported).
MAX_SPEED_FACTOR = 3.0


def six_phase_drive_from_flags(args, spec):
    """``--machine six-phase`` (or ``five-phase``): the multi-phase drive of ``args.control`` on the drive
    file ``spec`` with the flags the user set (a switching bridge gets the file's dead time); flags of the
    three-phase controls are refused (`check_machine_flags`)."""
    from pmsmjax.presets.user_drive import spec_drive

    options = {}
    for flag in SIX_PHASE_FLAG_OPTIONS:
        value = getattr(args, flag, None)
        if value is None or value is False:
            continue
        options[SIX_PHASE_FLAG_OPTIONS[flag]] = False if flag == "no_delay" else value
    return spec_drive(spec, args.control, **options)


def check_machine_flags(args) -> None:
    """The flags that do not fit ``--machine`` are refused before any work (pure Python)."""
    if args.machine in MULTIPHASE_NAMES:
        machine = args.machine
        controls, pwms, frames, _ = MULTIPHASE_NAMES[machine]
        if args.control is None:
            args.control = "vsd"
        if args.control not in controls:
            kind = "a three-phase" if args.control in CONTROL_NAMES else "another machine's"
            raise ParameterError(
                f"--control {args.control} is {kind} control; with --machine {machine} choose from "
                f"{', '.join(controls)}."
            )
        for flag in FLAG_OPTIONS.keys() - SIX_PHASE_FLAG_OPTIONS.keys():
            if getattr(args, flag, None) not in (None, False):
                raise ParameterError(f"--{flag.replace('_', '-')} does not apply to --machine {machine}.")
        if getattr(args, "estimator", None):
            raise ParameterError(
                "--estimator applies to the three-phase drive only (the chapter 5 observers are "
                "three-phase); drop it or use --machine three-phase."
            )
        if args.frame is not None and args.frame not in frames:
            kind = "a three-phase" if args.frame in THREE_PHASE_FRAMES else "another machine's"
            raise ParameterError(
                f"--frame {args.frame} is {kind} frame; {machine} frames: {', '.join(frames)}."
            )
        if getattr(args, "pwm", None) is not None and args.pwm not in pwms:
            raise ParameterError(
                f"--pwm {args.pwm} does not drive the {machine} machine; choose from {', '.join(pwms)}."
            )
        return
    if args.control is None:
        args.control = "pi"
    for flag in ("pwm", "bridge"):
        if getattr(args, flag, None) is not None:
            raise ParameterError(
                f"--{flag} applies to --machine six-phase only (three phases: SVPWM, averaged)."
            )
    if args.frame is not None and args.frame not in THREE_PHASE_FRAMES:
        raise ParameterError(
            f"--frame {args.frame} is a six-phase frame; three-phase frames: {', '.join(THREE_PHASE_FRAMES)}."
        )
    if args.control not in CONTROL_NAMES:
        need = "five-phase" if args.control not in SIX_PHASE_CONTROL_NAMES else "six-phase"
        raise ParameterError(f"--control {args.control} needs --machine {need}.")


def control_drive_from_flags(args, drive):
    """The three-phase drive of ``args.control`` with the options the user set, on ``drive``: a
    [`DriveSpec`][pmsmjax.io.drive_files.DriveSpec] (its DC link, control rate, current limit and bandwidths;
    [`pmsmjax.presets.user_drive.spec_drive`][pmsmjax.presets.user_drive.spec_drive]) or a bare motor (the
    preset's defaults). A flag that does not apply to the chosen control is refused (``--band-a`` with
    ``--control pi``, say) instead of silently ignored."""
    from pmsmjax import presets
    from pmsmjax.io.drive_files import DriveSpec
    from pmsmjax.presets.control_methods import control_drive, control_options
    from pmsmjax.presets.user_drive import spec_drive

    spec = drive if isinstance(drive, DriveSpec) else None
    allowed = control_options(args.control)
    options = {}
    for flag, option in FLAG_OPTIONS.items():
        value = getattr(args, flag, None)
        if value is None or value is False or (flag == "frame" and value == "dq"):
            continue
        if flag == "current_limit" and spec is not None:
            continue  # already in the spec (drive_spec's max_current_a override)
        if option not in allowed:
            fits = [c for c in CONTROL_NAMES if option in control_options(c)]
            raise ParameterError(
                f"--{flag.replace('_', '-')} does not apply to --control {args.control}: drop it, or choose "
                f"--control {' or '.join(fits)}."
            )
        if flag == "no_delay":
            value = False
        elif flag == "sample_period_us":
            value = value * 1e-6
        elif flag == "field_weakening":
            bandwidth = getattr(args, "current_bandwidth", None) or (
                presets.BOOK_CURRENT_BANDWIDTH if spec is None else spec.control["current_bandwidth_rad_s"]
            )
            value = presets.field_weakening_block(bandwidth)
        options[option] = value
    if spec is None:
        return control_drive(args.control, drive, **options)
    return spec_drive(spec, args.control, **options)


def add_parser(sub):
    """Add the ``demo`` subcommand (alias ``simulate``) and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "demo",
        aliases=["simulate"],
        help="run a drive's scenario (the book drive by default; FOC) and write figures, a trace and "
        "summary.json",
        description=(
            "Simulate a drive (--motor: the book drive by default, a preset or your drive file; design-rule "
            "PI gains, SVPWM, averaged bridge at the file's DC link and control rate; or another control "
            "method with --control): a speed step from rest, then a load step (the drive file's [scenario]; "
            "book: 1000 r/min, 10 N m at 0.2 s, 0.4 s). Writes "
            "DIR/trace.csv (or .npz; speeds in rad/s as omega_m, speed_ref and in r/min as speed_rpm, "
            "speed_ref_rpm; every column's unit is listed in summary.json trace_columns), DIR/summary.json "
            "(step and load metrics; operating_point: whether the speed reached its reference and how "
            "much of the run sat at the voltage or current limit, with cause and remedy; drive_file: the "
            "drive with every derived value and how) and PNG figures."
        ),
    )
    p.add_argument(
        "--machine",
        choices=("three-phase", "six-phase", "five-phase"),
        default="three-phase",
        help="three-phase (default), six-phase: a dual three-phase machine (book ch. 7-9; --motor book: the "
        "book motor rewound), or five-phase (book ch. 10); a drive file's n_phases must match",
    )
    p.add_argument(
        "--control",
        choices=list(dict.fromkeys(CONTROL_NAMES + SIX_PHASE_CONTROL_NAMES + FIVE_PHASE_CONTROL_NAMES)),
        default=None,
        help="control method. Three-phase: pi (cascaded PI FOC, default), smc (sliding-mode speed loop), pr "
        "(proportional-resonant current loops in alpha-beta), hysteresis (current comparators at 100 kHz), "
        "dtc (switching-table direct torque control, 40 kHz samples), smc-dtc (sliding-mode DTC with "
        "SVPWM). Six-phase: vsd (dq and z1-z2 PIs, default), double-dq (four PIs, cross-coupling "
        "compensation), conventional (dq PIs only), pr (stationary-frame PR on alpha-beta and z1-z2). "
        "Five-phase: vsd (i_d = 0, dq and x-y PIs, default), conventional (dq PIs only), pr "
        "(stationary-frame PR on alpha-beta and x-y)",
    )
    p.add_argument(
        "--pwm",
        choices=SIX_PHASE_PWM_NAMES + FIVE_PHASE_PWM_NAMES,
        help="six-phase modulator: four-vector SVPWM (default), two-vector SVPWM, decoupled (two SVPWMs), "
        "double-zs (carrier PWM, a zero sequence per set); five-phase: near-four-vector SVPWM (default), "
        "carrier (min-max zero sequence), sinusoidal, large-vector (x-y uncontrolled)",
    )
    p.add_argument(
        "--bridge",
        choices=("averaged", "switching"),
        help="six- or five-phase inverter model (default averaged)",
    )
    p.add_argument(
        "--estimator",
        choices=list(ESTIMATOR_NAMES),
        help="run sensorless from standstill on this chapter 5 observer, with the I/f start-up and hand-over "
        "(default: the exact position sensor); with --control pi, smc or pr",
    )
    p.add_argument(
        "--observer-model",
        choices=("map", "constant"),
        help="with --estimator on a drive file with a flux map: the observer reads the map's flux and "
        "incremental inductances at the operating current (map, the default there) or the file's constant "
        "L_d, L_q, psi_f (constant)",
    )
    p.add_argument("--out", default="demo_out", help="output folder (created), default: demo_out")
    drive_flags.add_motor_flag(p)
    drive_flags.add_override_flags(p)
    p.add_argument(
        "--speed-rpm",
        type=checks.real("r/min"),
        help=drive_flags.scenario_help("speed_rpm", "speed step, r/min"),
    )
    p.add_argument(
        "--load-nm", type=checks.real("N m"), help=drive_flags.scenario_help("load_nm", "load step, N m")
    )
    p.add_argument(
        "--load-time-s",
        type=checks.nonnegative("s"),
        help=drive_flags.scenario_help("load_time_s", "time of the load step, s"),
    )
    p.add_argument(
        "--duration-s",
        type=checks.positive("s"),
        help=drive_flags.scenario_help("duration_s", "simulated time, s"),
    )
    p.add_argument(
        "--frame",
        choices=list(dict.fromkeys(THREE_PHASE_FRAMES + SIX_PHASE_FRAME_NAMES + FIVE_PHASE_FRAME_NAMES)),
        default=None,
        help="machine model frame: dq (default), alpha_beta, abc; six-phase: dq, vsd, double-dq, natural; "
        "five-phase: dq, vsd, natural",
    )
    p.add_argument(
        "--substeps", type=checks.count(), help="RK4 sub-steps per control period (default 10; hysteresis 1)"
    )
    p.add_argument("--no-delay", action="store_true", help="no one-period computational delay")
    p.add_argument(
        "--current-bandwidth",
        type=checks.positive("rad/s"),
        help="current loop a_c, rad/s (default: the drive file's [control] current_bandwidth_rad_s or its "
        "design rule; book: 1100)",
    )
    p.add_argument(
        "--speed-bandwidth",
        type=checks.positive("rad/s"),
        help="speed loop beta, rad/s (default: the drive file's [control] speed_bandwidth_rad_s or its "
        "design rule; book: 50)",
    )
    p.add_argument("--field-weakening", action="store_true", help="MTPA and voltage-feedback field weakening")
    p.add_argument("--band-a", type=checks.positive("A"), help="hysteresis band, A (full width; default 0.5)")
    p.add_argument(
        "--switching",
        choices=("sign", "saturation", "tanh"),
        help="switching function of smc (default sign, the book's) or smc-dtc (default saturation)",
    )
    p.add_argument(
        "--torque-band-nm",
        type=checks.positive("N m"),
        help="dtc: full torque hysteresis band, N m (default 1)",
    )
    p.add_argument(
        "--flux-band-wb", type=checks.positive("Wb"), help="dtc: full flux hysteresis band, Wb (default 0.01)"
    )
    p.add_argument(
        "--sample-period-us",
        type=checks.positive("us"),
        help="dtc: comparator sample period, us (default 25)",
    )
    add_gains_flag(p)
    p.add_argument(
        "--trust-units",
        action="store_true",
        help="accept motor values outside the plausible ranges of pmsmjax.checks.plausibility (an inductance "
        "above 1 H, say) instead of refusing them as a likely unit mistake (a drive file: trust_units = "
        "true in [motor])",
    )
    p.add_argument("--decimate", type=checks.count(), default=1, help="record every N-th period (default 1)")
    p.add_argument("--format", choices=["csv", "npz"], default="csv", help="trace file format (default csv)")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def precheck(args):
    """Every check that needs no model (pure Python, before JAX starts); returns the drive
    ([`DriveSpec`][pmsmjax.io.drive_files.DriveSpec]) with the scenario flags left unset filled from it."""
    from pmsmjax.analysis.operating_point import top_speed_rpm

    checks.output_folder(args.out)
    check_machine_flags(args)
    if getattr(args, "estimator", None) and args.control not in SENSORLESS_CONTROLS:
        raise ParameterError(
            f"--estimator does not apply to --control {args.control}: the sensorless start-up needs a "
            f"three-phase FOC cascade; choose --control {' or '.join(SENSORLESS_CONTROLS)} (three-phase), "
            "or drop --estimator."
        )
    spec = drive_flags.resolve_drive(args, drive_flags.MACHINE_PHASES[args.machine])
    if getattr(args, "observer_model", None) and not (args.estimator and "flux_map" in spec.motor):
        raise ParameterError(
            "--observer-model applies to a sensorless run (--estimator) of a drive file with a flux map "
            "([motor] flux_map); drop it."
        )
    drive_flags.fill_scenario(args, spec)
    if not args.load_time_s < args.duration_s:
        raise ParameterError(
            f"--load-time-s {plain(args.load_time_s)} s is not inside the run (--duration-s "
            f"{plain(args.duration_s)} s): the summary's load-step window would lie outside the run; give "
            f"a time below {plain(args.duration_s)} s (also with --load-nm 0)."
        )
    read_gains_flag(args.gains)
    if args.machine in MULTIPHASE_NAMES:
        return spec
    motor, u_dc, u_limit, limit = spec.motor, spec.u_dc_v, spec.voltage_limit_v, spec.current_limit_a
    top = abs(top_speed_rpm(motor, u_limit, 0.0))
    if args.field_weakening:  # no-load top speed with i_d = -limit, resistance neglected
        excess = motor["psi_f"] - motor["L_d"] * limit
        top = math.inf if excess <= 0 else u_limit / (motor["pole_pairs"] * excess) * 30 / math.pi
    if abs(args.speed_rpm) > MAX_SPEED_FACTOR * top:
        raise ParameterError(
            f"--speed-rpm {plain(args.speed_rpm)}: this drive cannot turn faster than about {top:.0f} r/min "
            f"(no load, U_dc = {plain(u_dc)} V"
            + (", field weakening" if args.field_weakening else ", i_d = 0")
            + f"); a reference beyond {MAX_SPEED_FACTOR:g}x that would only show saturation: give at most "
            f"{MAX_SPEED_FACTOR * top:.0f} r/min"
            + ("" if args.field_weakening else ", add --field-weakening")
            + f", or raise the DC link ({drive_flags.U_DC_KNOB})."
        )
    return spec


def run(args) -> int:
    """Simulate the drive's scenario under the chosen control method; writes the trace, summary.json
    and figures to ``--out``. Returns the exit status."""
    spec = precheck(args)

    import jax
    import numpy as np

    from pmsmjax import presets
    from pmsmjax.analysis.operating_point import run_flags
    from pmsmjax.analysis.speed_step_summary import speed_step_summary
    from pmsmjax.io.logs import atomic_write, write_csv_atomic
    from pmsmjax.plotting.traces import save_demo_figures
    from pmsmjax.presets.user_drive import (
        spec_motor,
        spec_scenario,
        startup_options,
        with_map_aware_estimator,
    )
    from pmsmjax.simulate import check_simulation, simulate
    from pmsmjax.trace import COLUMN_UNITS

    out = checks.output_folder(args.out)
    six_phase = args.machine in MULTIPHASE_NAMES  # six- or five-phase
    try:
        if six_phase:
            drive = six_phase_drive_from_flags(args, spec)
        else:
            drive = control_drive_from_flags(args, spec)
        if args.estimator:  # three-phase only (check_machine_flags); the drive file's I/f start
            drive = presets.with_observer(
                drive, args.estimator, spec_motor(spec), startup_options=startup_options(spec)
            )
            if "flux_map" in spec.motor and args.observer_model != "constant":
                drive = with_map_aware_estimator(spec, drive)
        # after the observer is in: a gains.toml of pmsmjax tune --estimator names estimator.observer.*
        drive = apply_gains_flag(drive, read_gains_flag(args.gains), args.control)
        scenario = spec_scenario(spec, args.speed_rpm, args.load_nm, args.load_time_s, args.duration_s)
        n = args.duration_s / drive.Ts
        if abs(n - round(n)) > 1e-6 * max(n, 1.0):
            raise ParameterError(
                f"--duration-s {plain(args.duration_s)} is not a whole number of {plain(drive.Ts * 1e3)} ms "
                f"control periods: give e.g. {plain(round(n) * drive.Ts)} s."
            )
        if round(n) % args.decimate:
            raise ParameterError(
                f"--decimate {args.decimate} does not divide the {round(n)} control periods of the run: give "
                "a divisor of it (1, 2, 5, 10, ...)."
            )
        check_simulation(drive, scenario, args.decimate)
    except ParameterError as err:
        raise checks.user_terms(err, USER_TERMS) from None

    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=args.decimate))
    first_call_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=args.decimate))
    run_s = time.perf_counter() - t0
    trace = trace.to_numpy()

    load_time = args.load_time_s if 0 < args.load_time_s < args.duration_s else None
    current_limit = float(np.asarray(drive.controller.current_limit))
    operating = run_flags(
        trace, drive, load_time_s=load_time, field_weakening=args.field_weakening, flags=OPERATING_FLAGS
    )
    summary = {
        "scenario": {
            "speed_rpm": args.speed_rpm,
            "load_nm": args.load_nm,
            "load_time_s": args.load_time_s,
            "duration_s": args.duration_s,
        },
        "drive": {
            "machine": args.machine,
            "motor": args.motor,
            "control": args.control,
            "estimator": args.estimator or "exact sensor",
            "observer_model": (args.observer_model or "map")
            if args.estimator and "flux_map" in spec.motor
            else None,
            "frame": args.frame or "dq",
            "Ts_s": drive.Ts,
            "n_substeps": drive.n_substeps,
            "computation_delay": drive.computation_delay,
            "options": {
                k: v
                for k, v in vars(args).items()
                if k in FLAG_OPTIONS.keys() | SIX_PHASE_FLAG_OPTIONS.keys() and v not in (None, False)
            },
            "gains": args.gains,
            "current_limit_a": current_limit,
            "u_dc_v": float(np.asarray(drive.bridge.u_dc)),
            "bridge_dead_time": drive_flags.dead_time_entry(spec, drive),
        },
        "drive_file": spec.summary(),
        "metrics": speed_step_summary(trace, load_time_s=load_time, current_limit_a=current_limit),
        "operating_point": operating,
        **flux_map_entry(drive, trace),
        "definitions": DEFINITIONS,
        "trace_columns": COLUMN_UNITS,
        "timing": {"compile_s": max(first_call_s - run_s, 0.0), "run_s": run_s},
    }

    if six_phase:
        from pmsmjax.trace import FIVE_PHASE_COLUMN_UNITS, SIX_PHASE_COLUMN_UNITS

        five = args.machine == "five-phase"
        extra = FIVE_PHASE_COLUMN_UNITS if five else SIX_PHASE_COLUMN_UNITS
        summary["trace_columns"] = {**COLUMN_UNITS, **extra}
        summary["drive"]["pwm"] = args.pwm or MULTIPHASE_NAMES[args.machine][3]
        summary["drive"]["bridge"] = args.bridge or "averaged"
        summary["metrics"]["xy_current_peak_a" if five else "z_current_peak_a"] = z_current_peak(
            trace, drive.machine.layout
        )
    name = drive_flags.drive_name(spec) + (f" {args.machine}" if six_phase else "")
    out.mkdir(parents=True, exist_ok=True)
    columns = trace.columns()
    if args.format == "csv":
        write_csv_atomic(out / "trace.csv", columns)
    else:
        atomic_write(out / "trace.npz", lambda f: np.savez(f, **columns))
    atomic_write(out / "summary.json", lambda f: f.write(json.dumps(summary, indent=2).encode()))
    figures = (
        []
        if args.no_figures
        else save_demo_figures(
            trace,
            out,
            f"pmsmjax demo: {name} drive, {args.control} control"
            + (f", sensorless ({args.estimator}, I/f start)" if args.estimator else ""),
            current_limit_a=current_limit,
            voltage_limit_v=float(np.asarray(drive.voltage_limit())),
        )
    )
    if six_phase and not args.no_figures:
        from pmsmjax.plotting.six_phase import z_currents_figure
        from pmsmjax.plotting.traces import save_figure

        fig = z_currents_figure(trace, f"{name} drive, {args.control}", drive.machine.layout)
        name = "currents_xy.png" if args.machine == "five-phase" else "currents_z.png"
        figures.append(save_figure(fig, out / name))
    m = summary["metrics"]
    print(
        f"{name} drive ({args.machine}, U_dc {plain(summary['drive']['u_dc_v'])} V, current limit "
        f"{plain(current_limit)} A, {plain(1e-3 / drive.Ts)} kHz), {args.control} control"
    )
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
    print_flags(operating)
    if summary.get("flux_map", {}).get("warning"):
        print(f"WARNING flux_map: {summary['flux_map']['warning']}")
    print(f"compile {summary['timing']['compile_s']:.2f} s, run {summary['timing']['run_s'] * 1e3:.1f} ms")
    print(
        f"wrote {out}/trace.{args.format}, {out}/summary.json"
        + (f" and {len(figures)} figures" if figures else "")
    )
    return 0


#: What summary.json's less obvious figures mean.
DEFINITIONS = {
    "steady_state_error_rpm": "mean of reference - speed over the last 10 % of the samples before the load "
    "step, r/min",
    "final_error_rpm": "mean of reference - speed over the last n samples of the run, n = a tenth of the "
    "samples before the load step (the same window length as steady_state_error_rpm), r/min",
    "rise_time_s": "10 % to 90 % of the step, s (null: not reached)",
    "settling_time_s": "last entry into the 2 % band around the reference, s (null: not settled)",
    "speed_dip_rpm": "largest drop below the reference after the load step, r/min",
    "recovery_time_s": "time from the load step until the speed stays within recovery_band_rpm, s",
    "itae_rad_s": "integral of t |reference - speed| over the run, speed in rad/s (rad s)",
    "operating_point": "voltage_limited_share / current_limited_share: share of the control periods at the "
    "voltage or current limit; segments: whether the mean speed over the last 10 % before the load step and "
    "of the run is within the tolerance of the reference; flags: each shortfall with cause and remedy",
}


def flux_map_entry(drive, trace) -> dict:
    """``{"flux_map": ...}`` for summary.json when the plant is a flux map: how far the run's currents went
    outside the map's grid ([`pmsmjax.machines.flux_map.excursion`][pmsmjax.machines.flux_map.excursion]);
    ``{}`` otherwise."""
    flux_map = getattr(drive.machine, "flux_map", None)
    return {} if flux_map is None else {"flux_map": flux_map.excursion(trace.i_dq)}


def print_flags(operating: dict) -> None:
    """One console line per operating-point flag."""
    for f in operating["flags"]:
        print(f"WARNING {f['flag']}: {f['cause']}; remedy: {f['remedy']}.")


def z_current_peak(trace, layout=None) -> float:
    """Largest |z1-z2| current (A) of a six-phase trace (|x-y| of a five-phase one: ``layout``)."""
    import numpy as np

    from pmsmjax.frames.multiphase import SIX_PHASE, vsd

    i_z = np.asarray(vsd(trace.i_abc, SIX_PHASE if layout is None else layout))[:, 2:4]
    return float(np.max(np.hypot(i_z[:, 0], i_z[:, 1])))


def _fmt(x, scale):
    return "n/a" if x is None else f"{x * scale:.1f}"
