"""``pmsmjax pwm-compare``: the PWM methods of a three-, six- or five-phase drive compared at one steady
operating point (:mod:`pmsmjax.studies.pwm_comparison`)."""

import json
import time

from pmsmjax.checks.validation import ParameterError, plain
from pmsmjax.cli import checks
from pmsmjax.cli.gains import add_gains_flag, apply_gains_flag, read_gains_flag
from pmsmjax.presets.book_constants import (
    BOOK_CURRENT_LIMIT,
    BOOK_DC_LINK,
    BOOK_LOAD_NM,
    BOOK_POLE_PAIRS,
    BOOK_SPEED_STEP_RPM,
    BOOK_TS,
)

MODULATOR_NAMES = ("sinusoidal", "third_harmonic", "min_max", "svpwm")
#: ``--phases 6``: the dual three-phase modulators (pmsmjax.presets.six_phase.SIX_PHASE_PWMS).
SIX_PHASE_MODULATOR_NAMES = ("four-vector", "two-vector", "decoupled", "double-zs")
#: ``--phases 5``: the five-phase modulators (pmsmjax.presets.five_phase.FIVE_PHASE_PWMS).
FIVE_PHASE_MODULATOR_NAMES = ("near-four-vector", "carrier", "sinusoidal", "large-vector")


def add_parser(sub):
    p = sub.add_parser(
        "pwm-compare",
        help="compare the PWM methods (spectra, THD, DC-bus utilisation) at one steady operating point",
        description=(
            "Book chapter 2: sinusoidal PWM, third-harmonic and min-max injection and SVPWM at one steady "
            "operating point of the book drive (reached through the book scenario), each with the averaged "
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
    p.add_argument("--out", default="pwm_out", help="output folder (created), default: pwm_out")
    p.add_argument(
        "--speed-rpm",
        type=checks.positive("r/min"),
        default=BOOK_SPEED_STEP_RPM,
        help=f"speed, r/min; f_sw / f_1 must be whole: {plain(BOOK_SPEED_STEP_RPM)} r/min (default) gives "
        f"{plain(60.0 / (BOOK_SPEED_STEP_RPM * BOOK_POLE_PAIRS * BOOK_TS))}",
    )
    p.add_argument(
        "--load-nm",
        type=checks.real("N m"),
        default=BOOK_LOAD_NM,
        help=f"load torque, N m (default {plain(BOOK_LOAD_NM)})",
    )
    p.add_argument(
        "--dead-time-us",
        type=checks.nonnegative("us", maximum=50.0),
        default=2.0,
        help="dead time of the _deadtime variants, us (default 2)",
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
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def precheck(args) -> None:
    """Checks that need no model (before JAX starts)."""
    from pmsmjax.analysis.operating_point import refuse_unreachable
    from pmsmjax.io.motor_files import PRESET_VALUES

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
    if args.phases in (5, 6) and args.dead_time_us == 0.0 and args.dead_time_variants:
        raise ParameterError("--dead-time-variants with --dead-time-us 0 compares nothing: give a dead time.")
    motor = PRESET_VALUES["book"]  # the six- and five-phase rewinds have the same pole pairs
    f1 = args.speed_rpm / 60.0 * motor["pole_pairs"]
    per_cycle = 1.0 / (f1 * BOOK_TS)
    if abs(per_cycle - round(per_cycle)) > 1e-9 * per_cycle:
        good = [n for n in (250, 300, 375, 500, 600, 750, 1000, 1250, 1500) if n <= 2 * args.speed_rpm]
        raise ParameterError(
            f"--speed-rpm {plain(args.speed_rpm)}: a fundamental period ({1e3 / f1:.4g} ms) is not a whole "
            f"number of {plain(BOOK_TS * 1e6)} us PWM periods, so the spectra would leak: pick a speed "
            f"with f_sw / f_1 whole, e.g. {', '.join(str(n) for n in good[-4:])} r/min."
        )
    if args.phases in (5, 6):
        # The six- and five-phase rewinds have the book motor's torque constant and 1/2 or 3/5 of its
        # back-EMF per phase, against linear limits of 0.577 or 0.526 U_dc (not less than the book drive's
        # 0.577 U_dc in proportion): a point the three-phase check accepts they hold too.
        return
    refuse_unreachable(
        motor,
        args.speed_rpm,
        args.load_nm,
        BOOK_DC_LINK,
        BOOK_DC_LINK / 3**0.5,
        BOOK_CURRENT_LIMIT,
        what="the PWM comparison",
    )


def run(args) -> int:
    precheck(args)

    import numpy as np

    from pmsmjax.io.logs import atomic_write
    from pmsmjax.studies.pwm_comparison import PHASE_COUNTS, CompareSettings, compare

    settings = CompareSettings(
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
    )
    gains_block = "pi" if args.phases == 3 else "conventional"
    base = apply_gains_flag(PHASE_COUNTS[args.phases].base_drive(), read_gains_flag(args.gains), gains_block)
    out = checks.output_folder(args.out)
    t0 = time.perf_counter()
    result = compare(settings, base=base, progress=print)
    out.mkdir(parents=True, exist_ok=True)
    report = {"settings": result["settings"], "entries": result["entries"]}
    report["settings"]["gains"] = args.gains
    report["wall_time_s"] = time.perf_counter() - t0
    atomic_write(out / "pwm.json", lambda f: f.write(json.dumps(report, indent=2).encode()))
    arrays = {f"{name}/{key}": v for name, w in result["waves"].items() for key, v in w.items()}
    atomic_write(out / "waveforms.npz", lambda f: np.savez(f, **arrays))
    written = ["pwm.json", "waveforms.npz"]
    if not args.no_figures:
        from pmsmjax.plotting.pwm import comparison_figures
        from pmsmjax.plotting.traces import save_figure

        for name, fig in comparison_figures(result):
            save_figure(fig, out / name)
            written.append(name)
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {report['wall_time_s']:.1f} s")
    return 0
