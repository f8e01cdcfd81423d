"""``pmsmjax demo`` (alias ``simulate``): the drive's scenario (``--motor``: the book drive by default, or a
drive file, [`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]) under a chosen control method, written as a
trace, summary.json and figures; ``--machine six-phase`` runs the dual three-phase drive (book ch. 7-9),
``--machine five-phase`` the five-phase drive (book ch. 10).

Before any work: the flags (`pmsmjax.cli.checks`), ``--out``, the drive file (its units,
[`pmsmjax.spec.plausibility`][pmsmjax.spec.plausibility], and its ratings; `pmsmjax.cli.drive_flags`), the
gains file, the load step inside the run, and a speed the drive could reach at all. After the run,
``summary.json`` says whether the speed reached its reference and how much of the run sat at the voltage or
current limit ([`pmsmjax.analysis.operating_point.run_flags`][pmsmjax.analysis.operating_point.run_flags]),
and the console repeats every such flag with its cause and remedy.

The run itself is [`pmsmjax.jobs.demo`][pmsmjax.jobs.demo]: this module parses the flags into its
[`DemoSpec`][pmsmjax.jobs.demo.DemoSpec] and writes its [`DemoResult`][pmsmjax.jobs.demo.DemoResult].
"""

import json

from pmsmjax.cli import checks, drive_flags, memory
from pmsmjax.cli.figure_worker import FigureWorker
from pmsmjax.cli.gains import add_gains_flag, apply_gains_flag, read_gains_flag
from pmsmjax.jobs import demo as demo_job
from pmsmjax.spec import registry
from pmsmjax.spec.validation import ParameterError, plain

CONTROL_NAMES = registry.names("control", "three-phase")
SIX_PHASE_CONTROL_NAMES = registry.names("control", "six-phase")
SIX_PHASE_PWM_NAMES = registry.names("modulator", "six-phase")
THREE_PHASE_FRAMES = registry.names("frame", "three-phase")
SIX_PHASE_FRAME_NAMES = registry.names("frame", "six-phase")
FIVE_PHASE_CONTROL_NAMES = registry.names("control", "five-phase")
FIVE_PHASE_PWM_NAMES = registry.names("modulator", "five-phase")
FIVE_PHASE_FRAME_NAMES = registry.names("frame", "five-phase")
#: Per multi-phase machine: (controls, modulators, frames, default modulator).
MULTIPHASE_NAMES = {
    machine: (
        registry.names("control", machine),
        registry.names("modulator", machine),
        registry.names("frame", machine),
        registry.default("modulator", machine),
    )
    for machine in ("six-phase", "five-phase")
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

#: ``--estimator``: the chapter 5 observers, and the controls that can run on one (FOC cascades: they hold
#: the I/f start-up current).
ESTIMATOR_NAMES = registry.names("estimator", group="observer")
SENSORLESS_CONTROLS = registry.names("control", group="foc")

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


def options_from_flags(args, spec) -> dict:
    """The preset options the user set by flag for ``args.control`` on ``args.machine`` (flags left unset
    keep the drive file's values and the preset's defaults). A flag that does not apply to the chosen
    control is refused (``--band-a`` with ``--control pi``, say) instead of silently ignored.

    Args:
        args: the parsed flags.
        spec: the drive file (its current-loop bandwidth sets field weakening's), or None for the book
            drive's defaults.

    Returns:
        ``{option: value}`` for [`pmsmjax.assemble.assemble`][pmsmjax.assemble.assemble], without ``d_axis``:
        the field weakening of ``--field-weakening`` is built by the job
        ([`pmsmjax.jobs.demo.DemoSpec.field_weakening`][pmsmjax.jobs.demo.DemoSpec]).
    """
    if args.machine in MULTIPHASE_NAMES:
        options = {}
        for flag, option in SIX_PHASE_FLAG_OPTIONS.items():
            value = getattr(args, flag, None)
            if value is not None and value is not False:
                options[option] = False if flag == "no_delay" else value
        return options
    allowed = registry.method("control", args.control, what="control").options
    options = {}
    for flag, option in FLAG_OPTIONS.items():
        value = getattr(args, flag, None)
        if value is None or value is False or (flag == "frame" and value == "dq"):
            continue
        if flag == "current_limit" and spec is not None:
            continue  # already in the spec (drive_spec's max_current_a override)
        if option not in allowed:
            fits = [c for c in CONTROL_NAMES if option in registry.method("control", c).options]
            raise ParameterError(
                f"--{flag.replace('_', '-')} does not apply to --control {args.control}: drop it, or choose "
                f"--control {' or '.join(fits)}."
            )
        if flag == "field_weakening":
            continue  # the job adds the block (DemoSpec.field_weakening)
        if flag == "no_delay":
            value = False
        elif flag == "sample_period_us":
            value = value * 1e-6
        options[option] = value
    return options


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
    drive_flags.add_drive_flags(p, "demo_out")
    drive_flags.add_scenario_flags(p)
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
        "--anticogging",
        metavar="FILE",
        default=None,
        help="the FOC's anticogging table learnt by pmsmjax tune --anticogging (DIR/anticogging.csv: "
        "theta_e_rad, iq_a over one electrical revolution), fed forward on the q current (default: none)",
    )
    drive_flags.add_trust_units_flag(
        p,
        "accept motor values outside the plausible ranges of pmsmjax.spec.plausibility (an inductance above "
        "1 H, say) instead of refusing them as a likely unit mistake (a drive file: trust_units = true in "
        "[motor])",
    )
    p.add_argument(
        "--decimate",
        type=checks.count(),
        default=1,
        help="record every N-th period (default 1); a run whose estimated memory exceeds the budget is "
        "refused with the decimation that fits",
    )
    p.add_argument(
        "--margins",
        action="store_true",
        help="also report the current and speed loops' bandwidth, phase and gain margins and sensitivity "
        "peak, linearised at the final speed and load (three-phase FOC on the exact sensor; about 15 s more)",
    )
    memory.add_memory_flag(p)
    p.add_argument("--format", choices=["csv", "npz"], default="csv", help="trace file format (default csv)")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def precheck(args):
    """Every check that needs no model (pure Python, before JAX starts); returns the drive
    ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]) with the scenario flags left unset filled from it."""
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
    name = lambda key: drive_flags.scenario_name(args, key)  # noqa: E731
    if not args.load_time_s < args.duration_s:
        raise ParameterError(
            f"{name('load_time_s')} {plain(args.load_time_s)} s is not inside the run ({name('duration_s')} "
            f"{plain(args.duration_s)} s): the summary's load-step window would lie outside the run; give "
            f"a time below {plain(args.duration_s)} s (also with --load-nm 0)."
        )
    read_gains_flag(args.gains)
    if args.machine in MULTIPHASE_NAMES:
        return spec
    demo_job.check_reference_speed(
        spec, args.speed_rpm, args.field_weakening, drive_flags.U_DC_KNOB, name("speed_rpm")
    )
    demo_job.check_load(spec, args.load_nm, name("load_nm"))
    return spec


def demo_spec(args, spec) -> demo_job.DemoSpec:
    """The job's [`DemoSpec`][pmsmjax.jobs.demo.DemoSpec] of the checked flags ``args`` on the drive ``spec``
    (from `precheck`); a flag that does not apply to the control is refused
    (`options_from_flags`)."""
    multiphase = args.machine in MULTIPHASE_NAMES
    return demo_job.DemoSpec(
        drive=spec,
        motor=args.motor,
        name=drive_flags.drive_name(spec) + (f" {args.machine}" if multiphase else ""),
        machine=args.machine,
        control=args.control,
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        load_time_s=args.load_time_s,
        duration_s=args.duration_s,
        options=options_from_flags(args, spec),
        flags={
            k: v
            for k, v in vars(args).items()
            if k in FLAG_OPTIONS.keys() | SIX_PHASE_FLAG_OPTIONS.keys() and v not in (None, False)
        },
        operating_flags=OPERATING_FLAGS,
        estimator=args.estimator,
        observer_model=args.observer_model,
        field_weakening=args.field_weakening,
        current_bandwidth=args.current_bandwidth,
        frame=args.frame,
        pwm=args.pwm,
        bridge=args.bridge,
        gains=args.gains,
        decimate=args.decimate,
        margins=args.margins,
    )


def run(args) -> int:
    """Simulate the drive's scenario under the chosen control method; writes the trace, summary.json
    and figures to ``--out``. Returns the exit status."""
    # Two figure workers load matplotlib now, while this process loads JAX and simulates; then they draw the
    # overview and the panels at the same time.
    workers = [] if args.no_figures else FigureWorker.start_several(2, preload=_load_plotting)
    try:
        spec = precheck(args)
        out = checks.output_folder(args.out)
        gains = read_gains_flag(args.gains)
        table = _read_anticogging(getattr(args, "anticogging", None))
        adjust = None if gains is None else (lambda drive, control: apply_gains_flag(drive, gains, control))
        if table is not None:
            from pmsmjax.jobs.anticogging_table import with_anticogging

            adjust = with_anticogging(adjust, table)
        try:
            request = demo_spec(args, spec)
            drive, scenario = demo_job.build(request, adjust)
        except ParameterError as err:
            raise checks.user_terms(err, USER_TERMS) from None
        check_memory(args, drive.Ts)
        result = demo_job.run(request, drive, scenario)
        write(args, request, result, out, workers)
    finally:
        for worker in workers:
            worker.close()
    return 0


def _read_anticogging(path):
    """The ``--anticogging`` table's ``(N,)`` q currents, A (read and checked before JAX), or None."""
    if path is None:
        return None
    from pmsmjax.io.anticogging_files import read_anticogging_csv

    return read_anticogging_csv(path)


def _load_plotting() -> None:
    """What a figure worker imports before its first figure."""
    import matplotlib.pyplot  # noqa: F401

    import pmsmjax.plotting.traces  # noqa: F401


def check_memory(args, Ts: float) -> None:
    """Refuse a run whose estimated peak memory ([`pmsmjax.cli.memory.demo_bytes`][pmsmjax.cli.memory])
    exceeds the budget, before it compiles, naming the ``--decimate`` that fits or a shorter run.

    Args:
        args: the checked flags (``--duration-s``, ``--decimate``, ``--machine``, ``--max-memory-gb``).
        Ts: the drive's control period, s.
    """
    n_columns = demo_job.trace_column_count(args.machine)
    n_periods = int(round(args.duration_s / Ts))
    need = memory.demo_bytes(n_periods, args.decimate, n_columns)
    budget, _ = memory.budget_bytes(args.max_memory_gb)
    if need <= budget:
        return
    d = memory.demo_decimate_to_fit(n_periods, n_columns, budget)
    per_period = memory.DEMO_PERIOD_BYTES + memory.DEMO_ROW_BYTES * n_columns / args.decimate
    longest = max((budget - memory.BASE_BYTES) / per_period, 0) * Ts
    shorter = f"a --duration-s of at most {plain(float(f'{longest:.2g}'))} s"
    fix = (
        f"pass --decimate {d} (about {memory.gb(memory.demo_bytes(n_periods, d, n_columns))}) or give "
        f"{shorter}"
        if d is not None
        else f"give {shorter}"
    )
    memory.check_fits(
        need,
        f"--duration-s {plain(args.duration_s)} s at {plain(1e-3 / Ts)} kHz is {n_periods:,} control "
        f"periods, {n_periods // args.decimate:,} trace rows of {n_columns} columns (--decimate "
        f"{args.decimate}); the run",
        fix,
        args.max_memory_gb,
        floor=memory.BASE_BYTES,
    )


def write(args, request: demo_job.DemoSpec, result: demo_job.DemoResult, out, workers=()) -> None:
    """Write the trace (``--format``), summary.json and, unless ``--no-figures``, the figures into the
    folder ``out``, then print the result's report and what was written."""
    import numpy as np

    from pmsmjax.io.logs import atomic_write, write_csv_atomic

    out.mkdir(parents=True, exist_ok=True)
    columns = result.trace.columns()
    if args.format == "csv":
        write_csv_atomic(out / "trace.csv", columns)
    else:
        atomic_write(out / "trace.npz", lambda f: np.savez(f, **columns))
    atomic_write(out / "summary.json", lambda f: f.write(json.dumps(result.summary, indent=2).encode()))
    console = list(result.console)
    if not args.no_figures:
        from pmsmjax.plotting.traces import save_demo_figures
    figures = (
        []
        if args.no_figures
        else save_demo_figures(
            result.trace,
            out,
            f"pmsmjax demo: {request.name} drive, {args.control} control"
            + (f", sensorless ({args.estimator}, I/f start)" if args.estimator else ""),
            current_limit_a=result.current_limit_a,
            voltage_limit_v=result.voltage_limit_v,
            workers=workers,
        )
    )
    if result.layout is not None and not args.no_figures:
        from pmsmjax.plotting.six_phase import z_currents_figure
        from pmsmjax.plotting.traces import save_figure

        fig = z_currents_figure(result.trace, f"{request.name} drive, {args.control}", result.layout)
        name = "currents_xy.png" if args.machine == "five-phase" else "currents_z.png"
        figures.append(save_figure(fig, out / name))
        # Kept as the command always printed it: the first line then names this figure's file where the
        # drive's name belongs (a slip, left for a change of its own since it changes the output).
        console[0] = name + console[0][len(request.name) :]
    for line in console:
        print(line)
    print(
        f"wrote {out}/trace.{args.format}, {out}/summary.json"
        + (f" and {len(figures)} figures" if figures else "")
    )
