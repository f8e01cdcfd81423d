"""``pmsmjax identify``: motor parameters with error bars from a logged run
([`tuning.identify`][tuning.identify]), and the identified motor as a drive file
([`tuning.identify.motor_file`][tuning.identify.motor_file])."""

import math
import sys
from pathlib import Path

from pmsmjax.cli import checks, memory
from pmsmjax.spec.validation import ParameterError


def add_parser(sub):
    """Add the ``identify`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "identify",
        help="identify R, L_d, L_q, psi_f, J, B with error bars from a logged drive run",
        description=(
            "Fit the PMSM model to a log (CSV/NPZ/MAT; default columns time,u_d,u_q,i_d,i_q,omega_m and "
            "optionally theta_e, T_L; alpha-beta/abc/duty voltages and alpha-beta/abc currents with "
            "theta_e) by output-error Levenberg-Marquardt over shooting windows. Writes DIR/params.json "
            "(value, stderr, ci95, identifiable per parameter; residuals; wall time), DIR/fit.png and "
            "DIR/motor.toml, a drive file every command reads (--motor DIR/motor.toml): [motor] the "
            "identified values, [tolerances] the relative half-widths of their 95 % intervals. A "
            "parameter the log does not determine (L_d when i_d is held at zero, psi_f at standstill, J "
            "at constant speed, ...) is reported NOT IDENTIFIABLE, without an interval; motor.toml then "
            "takes its value (and tolerance) from the prior drive of --motor, which also gives its "
            "[ratings], [inverter] and [sensor]. Without --motor such a parameter has no value: "
            "params.json is written, motor.toml is not, and the command exits with status 1 naming it and "
            'the fix (--motor PRIOR or --fix NAME=VALUE). To try it, make a log with: python -c "from '
            "tuning.identify import identification_scenario; from pmsmjax.recorded.synthetic_logs import "
            "ID_LOG_NOISE, add_measurement_noise, identification_log; from pmsmjax.io.logs import "
            "write_csv_atomic; write_csv_atomic('log.csv', "
            'add_measurement_noise(identification_log(identification_scenario()), ID_LOG_NOISE))" then '
            "pmsmjax identify log.csv --pole-pairs 4 --out id_out."
        ),
    )
    p.add_argument("log", help="log file (.csv, .npz or .mat)")
    checks.add_out_flag(p)
    p.add_argument(
        "--pole-pairs",
        type=checks.count(),
        default=None,
        help="number of pole pairs (known; default: the --motor prior's, required without it)",
    )
    p.add_argument(
        "--motor",
        metavar="PRIOR",
        default=None,
        help="prior drive: a preset name (book, servo-400w, ...) or a drive file; gives the pole pairs, "
        "the values the log does not determine and motor.toml's [ratings], [inverter], [sensor] "
        "(default: none)",
    )
    checks.add_log_column_flags(
        p,
        "u_d=Ud",
        "e.g. omega_m=rpm time=ms (omega_m=erpm: electrical r/min; default: SI: s, V, A, rad/s, rad, or the "
        "unit in a column's name)",
        tables="[columns], [units], [log], [identify]",
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
        "--encoder-lines",
        type=checks.count(),
        default=None,
        help="lines per revolution of the encoder whose quadrature count (column encoder_counts, 4 per line, "
        "zero at its index) the log gives instead of theta_e (default: [sensor] lines of --motor)",
    )
    checks.add_key_values_flag(
        p, "--fix", "NAME=VALUE", "hold parameters fixed, SI units, e.g. L_d=0.0041 (default: none)"
    )
    p.add_argument(
        "--load",
        choices=["constant", "none"],
        default=None,
        help="load model: constant (default: estimate a constant load torque T_c besides a logged T_L) or "
        "none (only the logged T_L)",
    )
    p.add_argument("--dead-time", action="store_true", help="estimate an inverter dead-time voltage V_dt")
    p.add_argument(
        "--sensor-errors",
        action="store_true",
        help="first identify the current sensors' offsets (A), their gains relative to sensor a and the "
        "encoder's angle offset (electrical rad), with 95 %% intervals, from a log of the phase currents as "
        "read (i_a, i_b, and i_c with a third sensor), the measured theta_e and stator-frame voltages held "
        "by a real inverter; the motor is then identified on the corrected log and motor.toml's [sensor] "
        "gets them. The absolute current gain is not identifiable (R and L absorb it): R, L_d, L_q are per "
        "ampere as sensor a reads it (default: off, the sensors taken as exact)",
    )
    p.add_argument(
        "--ambient-c",
        type=float,
        default=None,
        metavar="DEGC",
        help="the ambient (coolant) temperature of a heat-run log, degC, when known; a log with a "
        "temperature_c column (winding temperature, degC) gives R and psi_f at the --motor prior's "
        "reference_temperature_c (default 20 degC), their temperature coefficients and the winding's thermal "
        "network, whose ambient is fitted unless given here (default: fitted)",
    )
    p.add_argument(
        "--flux-harmonics",
        metavar="ORDERS",
        default=None,
        help="fit magnet flux harmonics of these orders per electrical revolution (e.g. 5,7; not 1, not "
        "triplen) with the sensor errors in the stator-frame voltage equation, from a log at speed (both "
        "directions separate them best); motor.toml gets [harmonics] flux (default: none)",
    )
    p.add_argument(
        "--cogging-orders",
        metavar="ORDERS",
        default=None,
        help="fit the cogging torque of these orders per electrical revolution (e.g. 6,12) from the logged "
        "shaft torque T_L of a slow held-speed run (a dynamometer holds the speed, a torque sensor logs "
        "T_L); motor.toml gets [harmonics] cogging (default: none)",
    )
    p.add_argument(
        "--two-mass",
        action="store_true",
        help="fit a compliant shaft to a run with speed steps: the motor's and the load's inertia, the "
        "shaft's stiffness and damping and the resonance, with 95 %% intervals, from the motor speed and "
        "the identified machine's torque; motor.toml gets [mechanics] and the motor's own J, B (default: "
        "rigid)",
    )
    p.add_argument("--no-figures", action="store_true", help="do not write fit.png")
    p.add_argument(
        "--flux-map",
        action="store_true",
        help="identify a saturated machine's flux map psi_d(i_d, i_q), psi_q(i_d, i_q) and R from a log at "
        "speed that walks current operating points (both directions of rotation separate R; else --fix "
        "R=...): writes DIR/flux_map.csv (points the log did not reach marked measured = 0), "
        "DIR/flux_map.json and DIR/motor.toml (J, B from --fix or --motor)",
    )
    p.add_argument(
        "--flux-map-step",
        type=checks.positive("A"),
        default=None,
        help="flux map grid step, A (default: about 8 intervals over the visited currents)",
    )
    p.add_argument(
        "--inverter-error",
        action="store_true",
        help="with --flux-map: fit the inverter voltage error (dead time and device drop, V per phase)",
    )
    p.add_argument(
        "--no-q-symmetry",
        action="store_true",
        help="with --flux-map: do not assume the rotor symmetric about its d axis (default: psi_d even and "
        "psi_q odd in i_q, the map fitted for i_q >= 0 and mirrored; give this for a rotor whose barriers "
        "or magnets are asymmetric, and record both torque signs)",
    )
    p.add_argument(
        "--flux-model",
        choices=["grid", "power-law"],
        default=None,
        help="with --flux-map: grid (default: node fluxes on a grid, any machine) or power-law (the "
        "saturation model of synchronous reluctance machines of Hinkkanen et al., IEEE TIA 2017, "
        "doi:10.1109/TIA.2016.2644624: five coefficients and the magnet fitted with 95 %% intervals, written "
        "to flux_map.json, the map sampled from it on the grid; for a reluctance machine and logs that visit "
        "few points, not for an interior-magnet machine)",
    )
    p.add_argument(
        "--fit-exponents",
        action="store_true",
        help="with --flux-model power-law: fit the exponents S, T, U too (default: the paper's S=5, T=1, "
        "U=1, V=0)",
    )
    memory.add_memory_flag(p)
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


def prior_and_pole_pairs(args):
    """``(prior DriveSpec or None, pole pairs)`` from ``--motor`` and ``--pole-pairs`` (checked, no JAX)."""
    prior = None
    if args.motor is not None:
        from pmsmjax.io.drive_files import drive_spec

        prior = drive_spec(args.motor)
    if args.pole_pairs is None:
        if prior is None:
            raise ParameterError(
                "give --pole-pairs N (the motor's pole pairs, poles / 2) or --motor PRIOR (a drive file or "
                "preset that states them)."
            )
        return prior, prior.motor["pole_pairs"]
    if prior is not None and prior.motor["pole_pairs"] != args.pole_pairs:
        raise ParameterError(
            f"--pole-pairs {args.pole_pairs} contradicts --motor {args.motor} (pole_pairs = "
            f"{prior.motor['pole_pairs']}): drop --pole-pairs or correct one of them."
        )
    return prior, args.pole_pairs


def run(args) -> int:
    """Identify the motor parameters with error bars from the log; writes params.json, fit.png and
    the identified drive file motor.toml to ``--out``. Returns the exit status."""
    checks.existing_file(args.log, "log", "log file")
    checks.output_folder(args.out)
    if args.config is not None:
        checks.existing_file(args.config, "--config", "config file")
    prior, pole_pairs = prior_and_pole_pairs(args)
    fixed = _pairs(args.fix, "--fix", _finite)
    columns = checks.key_values(args.columns, "--columns")
    units = checks.key_values(args.units, "--units", "time=ms")
    memory.check_log("identify", args.log, args.max_memory_gb)
    ripple = _ripple_orders(args)
    if args.flux_map:
        if args.sensor_errors:
            raise ParameterError("--sensor-errors belongs to the linear fit: drop it or --flux-map.")
        if args.two_mass:
            raise ParameterError("--two-mass belongs to the linear fit: drop it or --flux-map.")
        for flag, given in (
            ("--flux-harmonics", ripple["flux_orders"]),
            ("--cogging-orders", ripple["cogging_orders"]),
        ):
            if given:
                raise ParameterError(f"{flag} belongs to the linear fit: drop it or --flux-map.")
        return _run_flux_map(args, prior, pole_pairs, fixed, columns, units)
    flux_map_only = (
        ("--inverter-error", args.inverter_error),
        ("--flux-map-step", args.flux_map_step is not None),
        ("--no-q-symmetry", args.no_q_symmetry),
        ("--flux-model", args.flux_model is not None),
        ("--fit-exponents", args.fit_exponents),
    )
    given = [flag for flag, on in flux_map_only if on]
    if given:
        flag = given[0]
        linear = " (or use --dead-time for the linear fit)" if flag == "--inverter-error" else ""
        raise ParameterError(f"{flag} belongs to --flux-map: add --flux-map{linear}.")
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
        pole_pairs,
        config=args.config,
        columns=columns,
        units=units,
        hold=args.hold,
        u_dc=args.u_dc,
        resample=args.resample,
        figures=not args.no_figures,
        sensor_errors=args.sensor_errors,
        reference_c=_reference_temperature_c(prior),
        ambient_c=args.ambient_c,
        encoder_lines=_encoder_lines(args, prior),
        **ripple,
        two_mass=args.two_mass,
        **options,
    )
    s = result.summary
    for note in s["log"]["notes"]:
        print(note)
    if "sensor_errors" in s:
        _print_sensor_errors(s["sensor_errors"])
    if "temperature" in s:
        _print_temperature(s["temperature"])
    if "harmonics" in s:
        _print_harmonics(s["harmonics"])
    if "two_mass" in s:
        _print_two_mass(s["two_mass"])
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
    return _write_motor_file(args, s, pole_pairs, prior)


def _ripple_orders(args) -> dict:
    """``{"flux_orders", "cogging_orders"}`` from ``--flux-harmonics`` and ``--cogging-orders`` (comma
    lists of whole numbers per electrical revolution; flux orders not 1 and not triplen, as
    [`pmsmjax.machines.harmonics`][pmsmjax.machines.harmonics] has them; checked in plain Python)."""
    out = {}
    for flag, key, attr in (
        ("--flux-harmonics", "flux_orders", "flux_harmonics"),
        ("--cogging-orders", "cogging_orders", "cogging_orders"),
    ):
        text = getattr(args, attr)
        if text is None:
            out[key] = ()
            continue
        example = "5,7" if key == "flux_orders" else "6,12"
        try:
            orders = [int(v) for v in text.split(",")]
        except ValueError:
            orders = []
        if not orders or min(orders) < 1:
            raise ParameterError(
                f"{flag} {text}: give whole orders >= 1 per electrical revolution separated by commas, e.g. "
                f"{flag} {example}."
            )
        if len(set(orders)) != len(orders):
            raise ParameterError(f"{flag} {text}: an order is given twice; give each once.")
        if key == "flux_orders":
            for k in orders:
                if k == 1:
                    raise ParameterError(
                        f"{flag} order 1 is the fundamental, which the fit gives as psi_f: drop it."
                    )
                if k % 3 == 0:
                    raise ParameterError(
                        f"{flag} order {k} is triplen: zero-sequence, it drives no current and makes no "
                        "torque in a star winding without neutral (phase EMF only, not line): drop it."
                    )
        out[key] = tuple(orders)
    return out


def _print_harmonics(harmonics: dict) -> None:
    """One line per identified harmonic: amplitude and phase with their 95 % intervals."""
    for key, unit, f in (("flux", "mWb", 1e3), ("cogging", "N m", 1.0)):
        for row in harmonics.get(key, {}).get("rows", []):
            a, ph = row["amplitude"], row["phase_rad"]
            if a["identifiable"]:
                lo, hi = a["ci95"]
                plo, phi = ph["ci95"]
                print(f"{key} order {row['order']:<3d} {f * a['value']:.5g} {unit} 95 % [{f * lo:.5g}, "
                      f"{f * hi:.5g}], phase {math.degrees(ph['value']):.4g} deg 95 % "
                      f"[{math.degrees(plo):.4g}, {math.degrees(phi):.4g}]")  # fmt: skip
            else:
                print(f"{key} order {row['order']:<3d} {f * a['value']:.3g} {unit}  NOT IDENTIFIABLE")
    scale = harmonics.get("cogging", {}).get("torque_scale")
    if scale and "stderr" in scale:
        print(f"torque scale (logged / model) {scale['value']:.5g} +- {1.96 * scale['stderr']:.2g} (95 %)")


def _print_two_mass(shaft: dict) -> None:
    """One line per two-mass parameter and frequency, with its 95 % interval."""
    names = {
        "J_m": "motor inertia",
        "J_L": "load inertia",
        "K": "shaft stiffness",
        "D": "shaft damping",
        "B": "friction B",
        "resonance_hz": "resonance",
        "anti_resonance_hz": "anti-resonance",
    }
    for key, name in names.items():
        e = shaft[key]
        lo, hi = e["ci95"]
        interval = f"[{lo:.5g}, {hi:.5g}]" if lo is not None else "[not determined]"
        flag = "" if e["identifiable"] else "  NOT IDENTIFIABLE"
        print(f"{name:18s} {e['value']:.6g} {e['unit']:9s} 95 % {interval}{flag}")


def _encoder_lines(args, prior):
    """``--encoder-lines``, else the prior drive file's ``[sensor] lines``, else None."""
    if args.encoder_lines is not None:
        return args.encoder_lines
    return (prior.sensor or {}).get("lines") if prior is not None else None


def _print_sensor_errors(errors: dict) -> None:
    """One line per identified sensor error, with its 95 % interval."""
    rows = [(f"current offset {e['sensor']}", e, 1e3, "mA") for e in errors["current_offset_a"]]
    rows += [(f"current gain {e['sensor']}/a", e, 1.0, "") for e in errors["current_gain"][1:]]
    rows.append(("encoder offset", errors["encoder_offset_rad"], math.degrees(1.0), "deg el."))
    for name, e, f, unit in rows:
        lo, hi = e["ci95"]
        interval = f"[{f * lo:.5g}, {f * hi:.5g}]" if lo is not None else "[not determined]"
        flag = "" if e["identifiable"] else "  NOT IDENTIFIABLE"
        print(f"{name:18s} {f * e['value']:.6g} {unit:7s} 95 % {interval}{flag}")
    print(f"absolute current gain: not identifiable ({errors['not_identifiable']['absolute_current_gain']})")


def _reference_temperature_c(prior) -> float:
    """The temperature R and psi_f are identified at: the prior's ``[motor] reference_temperature_c``, else
    20 degC (what data sheets state R at)."""
    stated = prior.motor.get("reference_temperature_c") if prior is not None else None
    return float(stated) if stated is not None else 20.0


def _print_temperature(report: dict) -> None:
    """One line per temperature coefficient and thermal-network parameter, with its 95 % interval."""
    low, high = report["logged_range_c"]
    print(f"winding temperature logged {low:.1f} to {high:.1f} degC; R and psi_f at "
          f"{report['reference_temperature_c']:g} degC")  # fmt: skip
    rows = [("R temp. coeff.", report["r_temp_coeff_per_k"]),
            ("psi_f temp. coeff.", report["psi_f_temp_coeff_per_k"])]  # fmt: skip
    network = report["thermal_network"]
    if "r_th_k_per_w" in network:
        rows += [
            ("thermal resistance", network["r_th_k_per_w"]),
            ("thermal capacity", network["c_th_j_per_k"]),
            ("time constant", network["time_constant_s"]),
        ]
        if not network["ambient_c"].get("given"):
            rows.append(("ambient", network["ambient_c"]))
    else:
        print(f"thermal network: NOT IDENTIFIABLE ({network['note']})")
    for name, e in rows:
        lo, hi = e["ci95"]
        interval = f"[{lo:.5g}, {hi:.5g}]" if lo is not None else "[not determined]"
        flag = "" if e["identifiable"] else "  NOT IDENTIFIABLE"
        print(f"{name:18s} {e['value']:.6g} {e['unit']:7s} 95 % {interval}{flag}")


def _run_flux_map(args, prior, pole_pairs: int, fixed: dict, columns: dict, units: dict) -> int:
    """``--flux-map``: fit and write DIR/flux_map.csv, flux_map.json and motor.toml (read back as every
    command reads it). Returns the exit status."""
    from pmsmjax.io.drive_files import drive_spec

    bad = sorted(set(fixed) - {"R", "J", "B"})
    if bad:
        raise ParameterError(
            f"--fix {bad[0]}=...: with --flux-map only R (ohm), J (kg m^2) and B (N m s/rad) are values; "
            "the inductances and flux are the map."
        )
    for name, value in fixed.items():
        if value <= 0:
            raise ParameterError(f"--fix {name}={value:g}: must be > 0 (SI units).")
    if args.config is not None or args.load or args.dead_time:
        flag = "--config" if args.config is not None else "--load" if args.load else "--dead-time"
        raise ParameterError(
            f"{flag} is for the linear fit: with --flux-map use --inverter-error and --fix R=."
        )
    power_law = args.flux_model == "power-law"
    if args.fit_exponents and not power_law:
        raise ParameterError("--fit-exponents belongs to --flux-model power-law: add it or drop the flag.")
    if power_law and args.no_q_symmetry:
        raise ParameterError(
            "--no-q-symmetry: the power-law model is symmetric about the d axis (it depends on |psi_q|): "
            "drop one of them."
        )
    from tuning.identify.flux_map_files import (
        flux_map_motor_missing,
        identify_flux_map_file,
        write_flux_map_motor,
    )

    fit = identify_flux_map_file(
        args.log,
        args.out,
        pole_pairs,
        fixed=fixed,
        inverter_error=args.inverter_error,
        step_a=args.flux_map_step,
        q_symmetric=not args.no_q_symmetry,
        flux_model=args.flux_model or "grid",
        exponents="fitted" if args.fit_exponents else "paper",
        columns=columns,
        units=units,
        hold=args.hold or "stator",
        u_dc=args.u_dc,
        resample=args.resample,
    )
    R_note = "fixed" if fit.R_fixed else "identified"
    print(f"R {fit.R:.6g} ohm ({R_note})")
    if power_law:
        _print_flux_model(Path(args.out) / "flux_map.json")
    if fit.V_e is not None:
        print(f"inverter voltage error {fit.V_e:.4g} V per phase")
    symmetry = "symmetric about the d axis" if fit.q_symmetric else "not mirrored"
    print(
        f"flux map {fit.grid.i_d.size} x {fit.grid.i_q.size} points, {int(fit.measured.sum())} measured "
        f"(step {fit.grid.step[0]:g} A; {symmetry}); "
        f"window residual {fit.residual_rms_wb:.3g} Wb rms; "
        f"wrote {args.out}/flux_map.csv, flux_map.json"
    )
    if fit.constraints:
        print(
            f"{fit.constraints} energy-storing constraints active (incremental inductance positive definite, "
            "flux rising with its current): the log alone does not determine the map everywhere (the points "
            "marked measured = 0 follow the constraints and a smoothness prior)"
        )
    missing = flux_map_motor_missing(fixed, prior)
    if missing:
        print(
            f"pmsmjax identify: motor.toml not written: {', '.join(missing)} not determined by a "
            f"constant-speed "
            f"log: give --fix {missing[0]}=VALUE (SI units) or --motor PRIOR (a drive file or preset).",
            file=sys.stderr,
        )
        return 1
    path = Path(args.out) / "motor.toml"
    draft = write_flux_map_motor(path.with_name(".motor.toml.draft"), fit, pole_pairs, fixed, prior)
    try:
        drive_spec(draft)
    except ParameterError as err:
        draft.unlink()
        raise ParameterError(f"motor.toml not written: {str(err).replace(str(draft), str(path))}") from None
    draft.replace(path)
    print(f"wrote {path}: use it with --motor {path}")
    return 0


def _print_flux_model(path) -> None:
    """One line per fitted parameter of the power-law model, with its 95 % interval, as written to
    ``flux_map.json``, and its window residual beside the grid's."""
    import json

    model = json.loads(Path(path).read_text())["flux_model"]
    magnet = {
        "flux": "a flux psi_f in series",
        "mmf": "an MMF i_f",
        "none": "none (a pure reluctance machine)",
    }
    print(f"power-law model (Hinkkanen et al. 2017), exponents {model['exponents']}, magnet "
          f"{magnet[model['magnet']]}:")  # fmt: skip
    for name, e in model["parameters"].items():
        if name in ("R", "V_e"):
            continue
        lo, hi = e["ci95"]
        interval = f"[{lo:.5g}, {hi:.5g}]" if lo is not None else "[not determined]"
        print(f"  {name:6s} {e['value']:.6g} {e['unit']:17s} 95 % {interval}")
    grid = model["grid_fit_residual_rms_wb"]
    print(f"  window residual {model['residual_rms_wb']:.3g} Wb rms (the grid's {grid:.3g})")


def _write_motor_file(args, summary: dict, pole_pairs: int, prior) -> int:
    """Write DIR/motor.toml and read it back as every command will; without a prior, a parameter the log
    does not determine leaves it unwritten (status 1, one line naming the parameter and the fix)."""
    from pathlib import Path

    from pmsmjax.io.drive_files import drive_spec
    from tuning.identify.motor_file import undetermined, write_motor_file

    missing = undetermined(summary)
    if missing and prior is None:
        name = missing[0]
        others = f" (also {', '.join(missing[1:])})" if missing[1:] else ""
        advice = summary["identifiability"]["advice"].get(name, "")
        print(
            f"pmsmjax identify: motor.toml not written: {name}{others} is not determined by this log "
            f"(it needs {advice}): give --motor PRIOR (a drive file or preset whose value is taken) or "
            f"--fix {name}=VALUE (SI units), or record a log with that excitation.",
            file=sys.stderr,
        )
        return 1
    path = Path(args.out) / "motor.toml"
    draft = write_motor_file(path.with_name(".motor.toml.draft"), summary, pole_pairs, prior)
    try:
        drive_spec(draft)  # what every command does with it: a value it refuses is reported, not written
    except ParameterError as err:
        draft.unlink()
        raise ParameterError(f"motor.toml not written: {str(err).replace(str(draft), str(path))}") from None
    draft.replace(path)
    taken = f" ({', '.join(missing)} from {prior.source})" if missing else ""
    print(f"wrote {path}{taken}: use it with --motor {path}")
    return 0
