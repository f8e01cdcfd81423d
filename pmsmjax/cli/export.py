"""``pmsmjax export``: the drive's controller, with its design-rule gains or the gains ``pmsmjax tune`` wrote,
written for firmware ([`pmsmjax.export`][pmsmjax.export]): ``--target c``, a self-contained float32 C99
controller that runs the simulator's field-oriented control step operation by operation.

Checked before anything is built or written, each refusal one line (exit 2): ``--out``, the drive file, a
control method or drive part export does not write (another ``--control``, a ``[motor] flux_map``), the
gains file. The drive is built as ``pmsmjax demo`` builds it (same flags, same gains path).
"""

from pmsmjax.cli import checks, drive_flags
from pmsmjax.cli.gains import add_gains_flag, apply_gains_flag, read_gains_flag
from pmsmjax.spec import registry
from pmsmjax.spec.validation import ParameterError

#: The targets and what each writes.
TARGETS = {
    "c": "pmsm_controller.h and pmsm_controller.c: a float32 C99 controller",
    "odrive": "odrive_config.txt (odrivetool lines) and odrive_config.json: ODrive 0.5.x parameters",
    "simplefoc": "simplefoc_gains.h (C++ for the sketch) and simplefoc_gains.json: SimpleFOC parameters",
    "vesc": "vesc_mcconf.txt (name = value) and vesc_mcconf.json: VESC mcconf parameters",
    "ti": "ti_user_mtr1.h (user_mtr1.h defines, PI gains) and ti_user_mtr1.json: TI MotorControl SDK "
    "universal-lab parameters",
}
#: The control methods export writes.
EXPORTED_CONTROLS = ("pi",)


def add_parser(sub):
    """Add the ``export`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "export",
        help="write the drive's controller (design-rule or tuned gains) for firmware: a float32 C99 "
        "controller",
        description=(
            "Write the drive's field-oriented controller (--motor: a preset or your drive file; its "
            "design-rule gains, or with --gains the gains.toml pmsmjax tune wrote) for firmware. --target c: "
            "DIR/pmsm_controller.h and DIR/pmsm_controller.c, self-contained C99 in float32 that runs the "
            "simulator's control step operation by operation (speed PI with active damping and its "
            "anti-windup, dq current PIs with decoupling, delay compensation and angle advance, MTPA and "
            "field weakening with --field-weakening, the drive file's dead-time compensation, SVPWM): "
            "call pmsm_controller_step once per control period with the sampled currents, angle, speed, "
            "speed reference and DC link, and load the duties it returns into the PWM compare registers."
        ),
    )
    checks.add_out_flag(p)
    drive_flags.add_motor_flag(p)
    drive_flags.add_override_flags(p)
    add_gains_flag(p)
    p.add_argument(
        "--target",
        choices=tuple(TARGETS),
        default="c",
        help="what to write: c (pmsm_controller.h and .c, float32 C99; default), odrive (the gains as "
        "ODrive 0.5.x parameters: odrive_config.txt for odrivetool, odrive_config.json), simplefoc (the "
        "gains as SimpleFOC PIDController fields: simplefoc_gains.h, simplefoc_gains.json), vesc (the "
        "gains as VESC mcconf parameters: vesc_mcconf.txt, vesc_mcconf.json), ti (the motor model and "
        "gains as TI MotorControl SDK universal-lab user_mtr1.h defines and series-PI gains: ti_user_mtr1.h, "
        "ti_user_mtr1.json)",
    )
    p.add_argument(
        "--fixed-point",
        choices=("q15", "q31"),
        default=None,
        help="with --target c: write the controller in integer arithmetic, per unit (pmsm_controller_q15.h "
        "and .c: int16 words, int32 intermediates; q31: int32 words, int64 intermediates), the bases, Q "
        "formats, saturation and rounding stated in the header; the i_d = 0 cascade without dead-time "
        "compensation (default: float32)",
    )
    p.add_argument(
        "--control",
        choices=registry.names("control", "three-phase"),
        default="pi",
        help="the drive's control method (default pi, the cascaded PI FOC: the one export writes)",
    )
    p.add_argument(
        "--field-weakening",
        action="store_true",
        help="MTPA and voltage-feedback field weakening, as in pmsmjax demo --field-weakening (default: "
        "i_d = 0)",
    )
    drive_flags.add_trust_units_flag(p)
    p.set_defaults(func=run)


def precheck(args):
    """Every check that needs no model (pure Python, before JAX starts); returns the drive
    ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec])."""
    checks.output_folder(args.out)
    spec = drive_flags.resolve_drive(args)
    if args.control not in EXPORTED_CONTROLS:
        raise ParameterError(
            f"--control {args.control}: pmsmjax export writes the cascaded PI FOC of --motor {args.motor} "
            f"(--control {' or '.join(EXPORTED_CONTROLS)}, with --field-weakening for MTPA and field "
            f"weakening), not {args.control}; drop --control or give --control pi."
        )
    if spec.flux_map is not None:
        raise ParameterError(
            f"--motor {args.motor}: [motor] flux_map drives run the map's current loop and field weakening, "
            "which pmsmjax export does not write (it writes the linear-model FOC): export a drive file "
            "without a flux map (L_d, L_q, psi_f in [motor])."
        )
    if args.target != "c" and args.field_weakening:
        raise ParameterError(
            f"--target {args.target} with --field-weakening: the {args.target} parameters written are the "
            "i_d = 0 cascade's gains, not MTPA or the voltage loop; drop --field-weakening, or use "
            "--target c."
        )
    if args.fixed_point is not None and args.target != "c":
        raise ParameterError(
            f"--fixed-point {args.fixed_point} with --target {args.target}: the fixed-point controller is a "
            f"C target; give --target c, or drop --fixed-point for the {args.target} parameters."
        )
    if args.fixed_point is not None and args.field_weakening:
        raise ParameterError(
            f"--fixed-point {args.fixed_point} with --field-weakening: the fixed-point controller writes the "
            "i_d = 0 cascade, not MTPA or the voltage loop; drop --field-weakening, or drop --fixed-point "
            "for the float32 controller."
        )
    read_gains_flag(args.gains)
    return spec


def run(args) -> int:
    """Build the drive, set the gains, write the target's files into ``--out``. Returns the exit status."""
    spec = precheck(args)
    out = checks.output_folder(args.out)
    gains = read_gains_flag(args.gains)
    from pmsmjax.export.build import export_drive
    from pmsmjax.export.description import describe
    from pmsmjax.export.vendor_gains import write_files

    drive = export_drive(
        spec,
        args.control,
        args.field_weakening,
        lambda drive, control: apply_gains_flag(drive, gains, control),
    )
    where = f"--motor {args.motor}"
    description = describe(drive, spec.source, args.gains, where=where)
    files = target_files(
        args.target, description, spec, where, args.fixed_point
    )  # refusals before anything is written
    out.mkdir(parents=True, exist_ok=True)
    written = write_files(files, out)
    gains_text = "design-rule gains" if args.gains is None else f"gains of {args.gains}"
    print(
        f"{drive_flags.drive_name(spec)} drive, {gains_text}: Ts {description.Ts_s:g} s, "
        f"d axis {description.d_axis.replace('_', ' ')}, dead-time compensation "
        f"{'on' if description.dead_time_compensation else 'off'}"
    )
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def target_files(
    target: str, description, spec, where: str, fixed_point: str | None = None
) -> dict[str, str]:
    """``{file name: text}`` of ``--target`` (``fixed_point``: ``"q15"``, ``"q31"`` or None for float32) for
    the described controller; a vendor's refusal is raised here, before anything is written."""
    if target == "odrive":
        from pmsmjax.export.odrive import odrive_files

        return odrive_files(description, spec.ratings.rated_speed_rpm, where)
    if target == "simplefoc":
        from pmsmjax.export.simplefoc import simplefoc_files

        return simplefoc_files(description, spec.inverter.u_dc_v, where)
    if target == "vesc":
        from pmsmjax.export.vesc import vesc_files

        return vesc_files(description, where)
    if target == "ti":
        from pmsmjax.export.ti import ti_files

        return ti_files(description, where)
    if fixed_point is not None:
        from pmsmjax.export.c_fixed_source import c_fixed_files
        from pmsmjax.export.fixed_point import fixed_scaling

        scaling = fixed_scaling(description, spec.inverter.u_dc_v, fixed_point, where)
        return c_fixed_files(description, scaling)
    from pmsmjax.export.c_source import c_files

    return c_files(description)
