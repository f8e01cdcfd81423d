"""``pmsmjax pwm-compare``: the PWM methods of a three-, six- or five-phase drive (``--motor``: the book
drive by default, or a drive file: its motor, DC link, switching frequency and dead time) compared at one
steady operating point. The comparison itself is [`pmsmjax.jobs.pwm_compare`][pmsmjax.jobs.pwm_compare]: this
module parses the flags into its [`PwmCompareSpec`][pmsmjax.jobs.pwm_compare.PwmCompareSpec] and writes its
[`PwmCompareResult`][pmsmjax.jobs.pwm_compare.PwmCompareResult]."""

import json

from pmsmjax.cli import checks, drive_flags
from pmsmjax.cli.gains import add_gains_flag, apply_gains_flag, read_gains_flag
from pmsmjax.jobs import pwm_compare as pwm_job
from pmsmjax.spec.validation import ParameterError, plain

MODULATOR_NAMES = ("sinusoidal", "third_harmonic", "min_max", "svpwm")
#: ``--phases 6``: the dual three-phase modulators (pmsmjax.presets.six_phase.SIX_PHASE_PWMS).
SIX_PHASE_MODULATOR_NAMES = ("four-vector", "two-vector", "decoupled", "double-zs")
#: ``--phases 5``: the five-phase modulators (pmsmjax.presets.five_phase.FIVE_PHASE_PWMS).
FIVE_PHASE_MODULATOR_NAMES = ("near-four-vector", "carrier", "sinusoidal", "large-vector")
#: Dead time of the _deadtime variants when the drive file gives none (ideal switches), us.
DEFAULT_DEAD_TIME_US = 2.0


def add_parser(sub):
    """Add the ``pwm-compare`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "pwm-compare",
        help="compare the PWM methods (spectra, THD, DC-bus utilisation) at one steady operating point",
        description=(
            "Book chapter 2: sinusoidal PWM, third-harmonic and min-max injection and SVPWM at one steady "
            "operating point of the drive (--motor: the book drive by default, or a drive file; reached "
            "through a speed step and a load step), each with the averaged "
            "bridge, the switching-resolved bridge, and the switching bridge with dead time. Writes "
            "DIR/pwm.json (per variant: linear_limit_v, fundamental, voltage and current THD, DC-bus "
            "utilisation against sinusoidal PWM), DIR/waveforms.npz and PNG figures. An operating point the "
            "drive cannot hold (above its top speed at the load, or a load beyond its current limit) is "
            "refused: the spectra of a saturated drive compare nothing. Book chapter 8 (--phases 6): the "
            "dual three-phase PWMs with the averaged and switching six-leg bridges on the six-phase drive "
            "(conventional control); pwm.json per method: linear_limit_v, fundamental, z1-z2 average "
            "voltage, current THD, 5th/7th harmonic currents; figures of the 64 vectors, the alpha-beta "
            "and z1-z2 voltages and currents, the harmonics. Book chapter 10 (--phases 5): the five-phase "
            "PWMs (near-four-vector SVPWM, min-max carrier, sinusoidal, large-vector SVPWM) on the "
            "five-phase drive; pwm.json gives the x-y average voltage and the 3rd/7th harmonic currents."
        ),
    )
    p.add_argument(
        "--phases",
        type=int,
        choices=(3, 5, 6),
        default=3,
        help="3 (book chapter 2, default) or 6: the dual three-phase methods of chapter 8 (four-vector, "
        "two-vector, decoupled, double-zs) on the six-phase drive with conventional control; pwm.json "
        "then also gives the z1-z2 average voltage and the 5th/7th harmonic currents; or 5: the "
        "five-phase methods of chapter 10 (near-four-vector, carrier, sinusoidal, large-vector), x-y "
        "average voltage and 3rd/7th harmonic currents",
    )
    drive_flags.add_drive_flags(p, "pwm_out")
    # One steady operating point: a speed above 0 and a load.
    drive_flags.add_scenario_flags(
        p,
        ("speed_rpm", "load_nm"),
        types={"speed_rpm": checks.positive("r/min")},
        whats={
            "speed_rpm": "speed, r/min; f_sw / f_1 must be whole (book: 1000 r/min gives 150)",
            "load_nm": "load torque, N m",
        },
    )
    p.add_argument(
        "--dead-time-us",
        type=checks.nonnegative("us", maximum=50.0),
        default=None,
        help="dead time of the _deadtime variants, us (default: the drive file's [inverter] dead_time_s "
        f"when above 0, else {plain(DEFAULT_DEAD_TIME_US)}; book: {plain(DEFAULT_DEAD_TIME_US)})",
    )
    p.add_argument(
        "--settle-cycles", type=checks.count(), default=2, help="fundamental periods settled (default 2)"
    )
    p.add_argument(
        "--window-cycles", type=checks.count(), default=2, help="fundamental periods analysed (default 2)"
    )
    p.add_argument(
        "--modulators",
        nargs="+",
        choices=MODULATOR_NAMES + SIX_PHASE_MODULATOR_NAMES + FIVE_PHASE_MODULATOR_NAMES,
        default=None,
        help="modulators to compare (default: all four of the phase count: sinusoidal third_harmonic "
        "min_max svpwm; with --phases 6: four-vector two-vector decoupled double-zs; with --phases 5: "
        "near-four-vector carrier sinusoidal large-vector)",
    )
    p.add_argument(
        "--dead-time-variants",
        action="store_true",
        help="--phases 6 or 5: add the switching bridge with dead time (three phases always include it)",
    )
    add_gains_flag(p)
    drive_flags.add_trust_units_flag(p)
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def precheck(args):
    """Checks that need no model (before JAX starts); returns the drive
    ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]), the flags left unset filled from it."""
    checks.output_folder(args.out)
    read_gains_flag(args.gains)
    names = {3: MODULATOR_NAMES, 5: FIVE_PHASE_MODULATOR_NAMES, 6: SIX_PHASE_MODULATOR_NAMES}[args.phases]
    if args.modulators is None:
        args.modulators = list(names)
    wrong = [m for m in args.modulators if m not in names]
    if wrong:
        raise ParameterError(
            f"--modulators {' '.join(wrong)} do not drive {args.phases} phases: with --phases {args.phases} "
            f"choose from {', '.join(names)}."
        )
    spec = drive_flags.resolve_drive(args, args.phases)
    drive_flags.fill_scenario(args, spec, ("speed_rpm", "load_nm"))
    if args.dead_time_us is None:
        t_d = spec.inverter["dead_time_s"]
        args.dead_time_us = t_d * 1e6 if t_d > 0 else DEFAULT_DEAD_TIME_US
    if args.phases in (5, 6) and args.dead_time_us == 0.0 and args.dead_time_variants:
        raise ParameterError("--dead-time-variants with --dead-time-us 0 compares nothing: give a dead time.")
    f_sw, f_c = spec.inverter["switching_frequency_hz"], spec.inverter["control_frequency_hz"]
    if f_c != f_sw:
        raise ParameterError(
            f"{spec.source}: [inverter] control_frequency_hz = {plain(f_c)} Hz: the PWM comparison updates "
            f"the modulator once per switching period; give control_frequency_hz = {plain(f_sw)} (or leave "
            "it out)."
        )
    pwm_job.check_speed(spec, args.speed_rpm)
    pwm_job.check_operating_point(spec, args.speed_rpm, args.load_nm, drive_flags.U_DC_KNOB)
    return spec


def run(args) -> int:
    """Compare the PWM methods at the operating point; writes pwm.json, waveforms.npz and figures
    to ``--out``. Returns the exit status."""
    spec = precheck(args)
    request = pwm_job.PwmCompareSpec(
        drive=spec,
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        dead_time_s=args.dead_time_us * 1e-6,
        settle_cycles=args.settle_cycles,
        window_cycles=args.window_cycles,
        modulators=tuple(dict.fromkeys(args.modulators)),
        # Three phases always include the dead-time variants; more phases with --dead-time-variants.
        bridges=None
        if args.phases == 3
        else ("averaged", "switching") + (("deadtime",) if args.dead_time_variants else ()),
        phases=args.phases,
        gains=args.gains,
    )
    gains = read_gains_flag(args.gains)
    adjust = None if gains is None else (lambda drive, control: apply_gains_flag(drive, gains, control))
    out = checks.output_folder(args.out)
    result = pwm_job.compare_pwm(request, adjust, progress=print)
    write(args, result, out)
    return 0


def write(args, result: pwm_job.PwmCompareResult, out) -> None:
    """Write pwm.json, waveforms.npz and, unless ``--no-figures``, the figures into the folder ``out``;
    then print what was written."""
    import numpy as np

    from pmsmjax.io.logs import atomic_write

    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "pwm.json", lambda f: f.write(json.dumps(result.report, indent=2).encode()))
    atomic_write(out / "waveforms.npz", lambda f: np.savez(f, **result.arrays))
    written = ["pwm.json", "waveforms.npz"]
    if not args.no_figures:
        from pmsmjax.plotting.pwm import comparison_figures
        from pmsmjax.plotting.traces import save_figure

        for name, fig in comparison_figures(result.comparison):
            save_figure(fig, out / name)
            written.append(name)
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {result.report['wall_time_s']:.1f} s")
