"""Where a drive is built: [`assemble`][pmsmjax.assemble.assemble] turns a drive spec and a choice of control,
estimator and machine into a [`Drive`][pmsmjax.drive.Drive], in one pass, for three, five and six phases; and
[`with_parts`][pmsmjax.assemble.with_parts], the one place where a built drive's blocks or leaves are replaced
(a bridge swapped for a comparison, gains written by tuning).

The steps of [`assemble`][pmsmjax.assemble.assemble], in order (each a function of this module):

1. the control method's preset (`pmsmjax.spec.registry.REGISTRY`) at the drive file's DC link,
   control rate, current limit and bandwidths ([`drive_options`][pmsmjax.assemble.drive_options]), the user's
   options over them;
2. a three-phase drive file's ``[inverter]`` dead time and device drop in the averaged bridge, and their
   compensation in a FOC controller ([`inverter_error_parts`][pmsmjax.assemble.inverter_error_parts]);
3. a ``[motor] flux_map``: the map's plant, current loop and d-axis references
   ([`flux_map_parts`][pmsmjax.assemble.flux_map_parts]);
4. the position estimator: the file's encoder (``[sensor]``, with its mounting offset), or a sensorless
   observer with its I/f start ([`observer`][pmsmjax.assemble.observer]), reading the flux map where the
   file has one ([`map_aware`][pmsmjax.assemble.map_aware]);
5. the ``[sensor]`` phase-current sensors' offsets, gains and ADC step
   ([`current_sensor_parts`][pmsmjax.assemble.current_sensor_parts]), which the controller and the
   estimator then read;
6. a ``[thermal]`` table: the winding's thermal network and the motor's temperature coefficients
   ([`thermal_part`][pmsmjax.assemble.thermal_part]), a warm motor;
7. a ``[mechanics]`` table: the compliant shaft in the plant
   ([`shaft_parts`][pmsmjax.spec_blocks.shaft_parts]; the presets design for the total inertia), and the
   ``[control]`` speed-loop filters in the speed PI
   ([`speed_filter_parts`][pmsmjax.spec_blocks.speed_filter_parts]).
8. a ``[harmonics]`` table: the plant's magnet flux harmonics and cogging torque
   ([`harmonics_part`][pmsmjax.assemble.harmonics_part]), put into the machine the steps before chose.

The parts of steps 2-6 are collected and put into the preset's drive by one
[`with_parts`][pmsmjax.assemble.with_parts] call. The presets' own builders
([`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive], ...) remain the per-method factories;
on the book drive file (``--motor book``) [`assemble`][pmsmjax.assemble.assemble] gives their drives bit for
bit.
"""

from collections.abc import Mapping

import equinox as eqx

from pmsmjax.drive import Drive
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.spec import registry
from pmsmjax.spec.validation import ParameterError
from pmsmjax.spec_blocks import (
    design_motor,
    shaft_parts,
    spec_flux_map,
    spec_motor,
    spec_scenario,
    speed_filter_parts,
    startup_options,
)

__all__ = [
    "assemble",
    "with_parts",
    "part",
    "drive_options",
    "inverter_error_parts",
    "flux_map_parts",
    "current_sensor_parts",
    "observer",
    "map_aware",
    "map_injection_design",
    "thermal_part",
    "shaft_parts",
    "speed_filter_parts",
    "harmonics_part",
    "spec_motor",
    "spec_flux_map",
    "spec_scenario",
    "startup_options",
    "spec_drive",
    "with_inverter_error",
    "with_flux_map_control",
    "with_map_aware_estimator",
    "with_observer",
    "sensorless_drive",
    "STARTUP_DEFAULTS",
    "SMC_LOAD_RISE_S",
]

#: I/f start-up of the book drive ([`observer`][pmsmjax.assemble.observer] with ``startup=True``): current
#: amplitude (A; 1.1 N m/A torque constant, J = 0.003 kg m^2), ramp acceleration (mechanical rad/s^2),
#: hand-over speed and blend span (mechanical rad/s: 150 r/min, then 100 r/min of blend).
STARTUP_DEFAULTS = dict(i_start=8.0, accel=1000.0, handover_speed=15.7, blend_speed=10.5)

#: The sliding-mode speed law's design load: the rated torque rising in this time, s (the book's 10 N m in
#: 10 ms, [`pmsmjax.presets.smc_drive`][pmsmjax.presets.three_phase.smc_drive]). Its sliding surface's time
#: constant is the speed loop's, ``1 / beta`` (the book's 20 ms at 50 rad/s).
SMC_LOAD_RISE_S = 0.01


def with_parts(drive: Drive, parts: Mapping[str, object]) -> Drive:
    """``drive`` with the parts named by dotted paths replaced: whole blocks (``"bridge"``,
    ``"estimator"``, ``"controller.current"``) or leaves (``"controller.speed.kp"``,
    ``"machine.motor.R"``).

    Args:
        drive: the drive to change (unchanged itself: equinox modules are immutable).
        parts: ``{path: new value}``; a path may lead to a part that is None (an absent estimator or
            d-axis reference).

    Returns:
        The new drive. A replaced bridge is checked at the drive's period as a new drive's would be.
    """
    if not parts:
        return drive
    paths = list(parts)
    new = eqx.tree_at(lambda d: [part(d, p) for p in paths], drive, list(parts.values()), is_leaf=_is_none)
    if "bridge" in parts:
        new.bridge.check_period(new.Ts)
    return new


def _is_none(x) -> bool:
    return x is None


def part(tree, path: str):
    """The part of ``tree`` (a drive, or one of its blocks) at the dotted ``path``
    (``"controller.speed.kp"``)."""
    for name in path.split("."):
        tree = getattr(tree, name)
    return tree


def drive_options(spec, control: str = "pi", machine: str = "three-phase") -> dict:
    """The preset options that put the drive file ``spec`` into control ``control``'s drive: DC link,
    control period, current limit, bandwidths (and the sliding-mode law's design load).

    Args:
        spec: the drive file ([`pmsmjax.spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]).
        control: a control method of the registry on ``machine``.
        machine: ``"three-phase"``, ``"six-phase"`` or ``"five-phase"``.

    Returns:
        ``{option: value}`` for the method's preset (options it does not take are left out).
    """
    common = {
        "u_dc": spec.u_dc_v,
        "current_limit": spec.current_limit_a,
        "speed_bandwidth": spec.control["speed_bandwidth_rad_s"],
    }
    if machine != "three-phase":
        return {**common, "Ts": spec.Ts, "current_bandwidth": spec.control["current_bandwidth_rad_s"]}
    allowed = set(registry.method("control", control, machine, what="control").options)
    options = dict(common)
    if "Ts" in allowed:
        options["Ts"] = spec.Ts
    if "current_bandwidth" in allowed:
        options["current_bandwidth"] = spec.control["current_bandwidth_rad_s"]
    if "speed_period_s" in allowed:  # comparator drives: the speed loop at the control rate
        options["speed_period_s"] = spec.Ts
    if "load_torque_rate_nm_s" in allowed:  # the sliding-mode speed law: surface as fast as the PI's loop
        options["load_torque_rate_nm_s"] = spec.ratings["rated_torque_nm"] / SMC_LOAD_RISE_S
        options["time_constant_s"] = 1.0 / spec.control["speed_bandwidth_rad_s"]
    return options


def assemble(
    spec,
    control: str | None = None,
    *,
    machine: str = "three-phase",
    options: Mapping[str, object] | None = None,
    estimator: str | None = None,
    observer_model: str = "map",
    observer_options: Mapping[str, object] | None = None,
) -> Drive:
    """The drive of ``control`` on the drive file ``spec`` (module docstring: the steps).

    Args:
        spec: the drive file ([`pmsmjax.spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]).
        control: a control method of the registry on ``machine`` (default: the machine's default, ``pi``
            for three phases, ``vsd`` for six and five).
        machine: ``"three-phase"``, ``"six-phase"`` or ``"five-phase"``; the file's ``n_phases`` must match.
        options: the preset options the user set; they override the file's
            ([`drive_options`][pmsmjax.assemble.drive_options]). Refused in one line when the method does not
            take them.
        estimator: a sensorless observer of the registry (three-phase FOC controls), started by the file's
            I/f start; None: the file's ``[sensor]`` (the exact sensor or its encoder).
        observer_model: with a flux map, ``"map"`` (the observer reads the map at the operating current)
            or ``"constant"`` (the file's constant ``L_d``, ``L_q``, ``psi_f``).
        observer_options: the observer's design-rule options over its defaults.

    Returns:
        The drive.
    """
    control = control or registry.default("control", machine)
    entry = registry.method("control", control, machine, what="control")
    user = dict(options or {})
    registry.check_options(entry, set(user) - {"control"})
    merged = {**drive_options(spec, control, machine), **user}
    motor = design_motor(spec)
    if machine == "three-phase":
        drive = registry.load_factory(entry)(motor, **merged)
    else:
        if merged.get("bridge") == "switching" and spec.inverter["dead_time_s"] > 0:
            merged.setdefault("dead_time", spec.inverter["dead_time_s"])
        drive = registry.load_factory(entry)(motor, control=control, **merged)
    parts = {}
    if machine == "three-phase":
        parts.update(inverter_error_parts(spec, drive))
        if spec.flux_map is not None:
            parts.update(flux_map_parts(drive, spec.flux_map, spec.source))
    if estimator is not None:
        if entry.group != "foc":
            raise ParameterError(
                f"estimator {estimator!r} needs a three-phase FOC cascade (it holds the I/f start-up "
                f"current); control {control!r} is not one: choose "
                f"{' or '.join(registry.names('control', group='foc'))}."
            )
        model, found_options = motor, observer_options
        if spec.flux_map is not None and observer_model != "constant":
            model, found_options = map_injection_design(spec, estimator, motor, observer_options)
        found = observer(drive, estimator, model, found_options, True, startup_options(spec))
        if spec.flux_map is not None and observer_model != "constant":
            found = map_aware(found, spec)
        parts["estimator"] = found
    elif spec.sensor["kind"] == "encoder":
        from pmsmjax.estimators.position_sensors import Encoder

        offset = spec.sensor.get("encoder_offset_rad")
        parts["estimator"] = Encoder(
            spec.sensor["lines"], spec.motor["pole_pairs"], spec.sensor["delay_s"], offset_rad=offset
        )
    parts.update(current_sensor_parts(spec, machine))
    if spec.thermal:
        parts["thermal"] = thermal_part(spec)
    drive = with_parts(drive, parts)
    drive = with_parts(drive, {**shaft_parts(spec), **speed_filter_parts(spec, drive)})
    if spec.harmonics:  # into the machine as built above (the flux map's plant replaces the dq one)
        drive = with_parts(drive, {"machine.harmonics": harmonics_part(spec, drive.machine)})
    return drive


def harmonics_part(spec, machine):
    """The drive file's magnet flux harmonics and cogging torque
    ([`MagnetHarmonics`][pmsmjax.machines.harmonics.MagnetHarmonics], ``[harmonics]``) for ``machine``;
    refused in one line for a plant that has no model of them (the saturated dq, multi-phase plants)."""
    from pmsmjax.machines.harmonics import MagnetHarmonics

    if not hasattr(machine, "harmonics"):
        raise ParameterError(
            f"{spec.source}: [harmonics] are modelled in the three-phase dq, alpha-beta, abc and flux-map "
            f"plants; this drive simulates a {type(machine).__name__}: choose one of those or drop "
            "[harmonics]."
        )
    h = spec.harmonics
    return MagnetHarmonics.from_rows(h.get("flux", ()), h.get("cogging", ()))


def current_sensor_parts(spec, machine: str = "three-phase") -> dict:
    """The part that puts the file's ``[sensor]`` current-sensor errors into the drive
    ([`CurrentSensors`][pmsmjax.estimators.current_sensors.CurrentSensors]: offsets A, gains, ADC step A);
    none when the file gives none. Refused in one line on a five- or six-phase machine."""
    s = spec.sensor
    if "current_offset_a" not in s:
        return {}
    if machine != "three-phase":
        raise ParameterError(
            f"{spec.source}: [sensor] current_offset_a, current_gain, current_lsb_a are modelled for "
            f"three-phase drives; this is a {machine} drive: drop them from the drive file."
        )
    from pmsmjax.estimators.current_sensors import CurrentSensors

    return {
        "current_sensor": CurrentSensors(s["current_offset_a"], s["current_gain"], s.get("current_lsb_a"))
    }


def thermal_part(spec):
    """The drive file's winding thermal network and temperature coefficients
    ([`WindingThermal`][pmsmjax.machines.thermal.WindingThermal]: ``[thermal]`` and ``[motor]``'s
    ``reference_temperature_c``, ``r_temp_coeff_per_k``, ``psi_f_temp_coeff_per_k``, temperatures in
    kelvin), or None for a file without ``[thermal]``."""
    if not spec.thermal:
        return None
    from pmsmjax.machines.thermal import WindingThermal
    from pmsmjax.units import celsius_to_kelvin

    t, m = spec.thermal, spec.motor
    return WindingThermal(
        r_th=t["r_th_k_per_w"],
        c_th=t["c_th_j_per_k"],
        ambient_k=celsius_to_kelvin(t["ambient_c"]),
        initial_k=celsius_to_kelvin(t["initial_c"]),
        reference_k=celsius_to_kelvin(m["reference_temperature_c"]),
        r_temp_coeff=m["r_temp_coeff_per_k"],
        psi_f_temp_coeff=m["psi_f_temp_coeff_per_k"],
    )


def inverter_error_parts(spec, drive: Drive) -> dict:
    """The parts that put the file's ``[inverter]`` dead time and device drop into ``drive`` (three-phase,
    averaged bridge): the bridge's voltage error and, with ``dead_time_compensation`` (default true) and a
    FOC controller, the same estimates compensated in the controller (the other controllers have none).
    None when the file has neither a dead time nor a drop.

    The engine runs one PWM period per control period ``Ts``; a file whose control rate differs from its
    switching rate loses ``U_dc t_d`` per PWM period, so the dead time is scaled by ``f_sw / f_c`` to keep
    that share of the voltage. The current sign is smoothed over
    [`CURRENT_LIMIT_SHARE`][pmsmjax.inverters.voltage_error.CURRENT_LIMIT_SHARE] of the controller's current
    limit.
    """
    from pmsmjax.controllers.dead_time_compensation import DeadTimeCompensation
    from pmsmjax.controllers.foc import FOC
    from pmsmjax.inverters.averaged import AveragedBridge
    from pmsmjax.inverters.voltage_error import CURRENT_LIMIT_SHARE, VoltageError

    inv = spec.inverter
    t_d, drop = inv["dead_time_s"], inv["device_drop_v"]
    if (t_d == 0.0 and drop == 0.0) or not isinstance(drive.bridge, AveragedBridge):
        return {}
    t_d_period = t_d * inv["switching_frequency_hz"] / inv["control_frequency_hz"]
    scale = CURRENT_LIMIT_SHARE * float(drive.controller.current_limit)
    parts = {
        "bridge": AveragedBridge(
            drive.bridge.u_dc,
            drive.bridge.unroll_substeps,
            dead_time=t_d_period,
            device_drop=drop,
            sign_smoothing=scale,
        )
    }
    if inv["dead_time_compensation"] and isinstance(drive.controller, FOC):
        parts["controller.dead_time_compensation"] = DeadTimeCompensation(
            VoltageError(t_d_period, drop, scale)
        )
    return parts


def flux_map_parts(drive: Drive, grid, source: str = "flux map", plant: bool = True) -> dict:
    """The parts that run ``drive`` on the flux map ``grid``
    ([`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid], of the drive file ``source``): the map's plant
    ([`PMSMFluxMapdq`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq]) in place of the linear dq machine and,
    for a dq PI current loop, the map's current loop
    ([`FluxMapCurrentLoop`][pmsmjax.controllers.flux_map_current_loop.FluxMapCurrentLoop], same bandwidth:
    ``a_c = kp_d / L_d`` read back from the internal-model gains) and, in speed mode of a FOC cascade (``pi``,
    ``smc``), field weakening on the map's MTPA and MTPV tables
    ([`flux_map_field_weakening`][pmsmjax.controllers.flux_map_references.flux_map_field_weakening]) at
    [`field_weakening_block`][pmsmjax.presets.three_phase.field_weakening_block]'s bandwidth and margin. In
    current mode the scenario's ``i_d*`` stands. The other controls keep their linear-model design on the
    map's plant. ``plant=False``: the control parts only (``drive`` already runs on the map).
    """
    from pmsmjax.controllers.current_pi import CurrentLoopGains
    from pmsmjax.controllers.flux_map_current_loop import FluxMapCurrentLoop
    from pmsmjax.controllers.flux_map_references import flux_map_field_weakening
    from pmsmjax.controllers.foc import FOC
    from pmsmjax.machines.pmsm3 import PMSMdq
    from pmsmjax.machines.pmsm_flux_map import FluxMap, PMSMFluxMapdq
    from pmsmjax.presets.three_phase import field_weakening_block

    if plant and type(drive.machine) is not PMSMdq:
        raise ParameterError(
            f"{source}: [motor] flux_map runs in the rotor-frame (dq) machine, this drive simulates a "
            f"{type(drive.machine).__name__}: use the dq frame or drop the map."
        )
    flux_map = FluxMap.from_grid(grid)
    parts = (
        {"machine": PMSMFluxMapdq(drive.machine.motor, flux_map, drive.machine.mechanics)} if plant else {}
    )
    c = drive.controller
    if not (isinstance(c, FOC) and isinstance(c.current, CurrentLoopGains)):
        return parts
    a_c = float(c.current.kp_d / c.model.L_d)
    parts["controller.current"] = FluxMapCurrentLoop.imc(flux_map, c.model, a_c)
    if c.mode == "speed":
        rule = field_weakening_block(a_c)
        parts["controller.d_axis"] = flux_map_field_weakening(
            grid, int(c.model.pole_pairs), float(c.current_limit), float(rule.bandwidth),
            float(rule.voltage_margin),
        )  # fmt: skip
    return parts


def observer(
    drive: Drive,
    name: str,
    model: PMSMParameters,
    options: Mapping[str, object] | None = None,
    startup: bool = True,
    startup_options: Mapping[str, float] | None = None,
):
    """The chapter 5 or 6 estimator ``name`` for ``drive``: its design rule for ``model`` at the drive's
    period, overridden by ``options`` (unstable gains refused), wrapped in the I/f start from standstill
    if ``startup`` ([`STARTUP_DEFAULTS`][pmsmjax.assemble.STARTUP_DEFAULTS] overridden by
    ``startup_options``). The drive's controller must be a FOC cascade (it holds the start-up current)."""
    from pmsmjax.estimators.registry import HYBRID_OBSERVERS, INJECTION_OBSERVERS, make_observer

    options = dict(options or {})
    if name in INJECTION_OBSERVERS or name in HYBRID_OBSERVERS:
        # the carrier's phase at the sampling instant depends on when the drive applies the command
        options.setdefault("delay_periods", 1.5 if drive.computation_delay else 0.5)
    found = make_observer(name, model, drive.Ts, **options)
    if startup:
        from pmsmjax.estimators.startup import StartupEstimator

        found = StartupEstimator(found, model.pole_pairs, **{**STARTUP_DEFAULTS, **(startup_options or {})})
    return found


def map_injection_design(spec, name: str, motor: PMSMParameters, options=None):
    """``(model, options)`` that design the estimator ``name`` on the drive file ``spec``'s flux map: HF
    injection (``hfi-rotating``, ``hfi-pulsating``) on the map's incremental inductances at no load
    ([`injection_model`][pmsmjax.estimators.hfi_cross_saturation.injection_model]: the file's linear model
    is taken at the rated current, where the q path may have saturated below ``L_d``), the hybrid's
    injection likewise (its observer keeps ``motor``); other estimators unchanged. Refused in one line
    where the map has no injection region
    ([`spec_injection_region`][pmsmjax.estimators.injection_region.spec_injection_region])."""
    from pmsmjax.estimators.hfi_cross_saturation import injection_model
    from pmsmjax.estimators.injection_region import spec_injection_region
    from pmsmjax.estimators.registry import HYBRID_OBSERVERS, INJECTION_OBSERVERS

    options = dict(options or {})
    if name not in INJECTION_OBSERVERS and name not in HYBRID_OBSERVERS:
        return motor, options
    spec_injection_region(spec)
    no_load = injection_model(spec.flux_map, motor, (0.0, 0.0))
    if name in INJECTION_OBSERVERS:
        return no_load, options
    options.setdefault("injection_motor", no_load)
    return motor, options


def map_aware(estimator, spec):
    """``estimator`` reading the file's flux map: HF injection corrected by the map's cross-saturation
    angle ([`pmsmjax.estimators.hfi_cross_saturation`][pmsmjax.estimators.hfi_cross_saturation]), a back-EMF
    observer or the EKF keeping its constant model with its angle corrected by the map at the operating
    current ([`pmsmjax.estimators.map_angle_corrected`][pmsmjax.estimators.map_angle_corrected]); the
    hybrid each of its two so (its hand-over by current at the map's injection region is not set here:
    [`with_current_handover`][pmsmjax.estimators.hybrid.with_current_handover] with
    [`spec_injection_region`][pmsmjax.estimators.injection_region.spec_injection_region]'s
    ``max_current_a``); an I/f start or a polarity detector keeps wrapping it."""
    from pmsmjax.estimators.hfi_cross_saturation import cross_saturation_compensated
    from pmsmjax.estimators.hfi_pulsating import HFIPulsating
    from pmsmjax.estimators.hfi_rotating import HFIRotating
    from pmsmjax.estimators.hybrid import HybridEstimator
    from pmsmjax.estimators.map_angle_corrected import map_angle_corrected
    from pmsmjax.estimators.polarity import PolarityDetector
    from pmsmjax.estimators.startup import StartupEstimator
    from pmsmjax.machines.pmsm_flux_map import FluxMap

    if spec.flux_map is None:
        raise ParameterError(
            f"{spec.source}: a map-aware estimator needs [motor] flux_map (a measured flux map CSV); this "
            "drive file has none: drop the map-aware option or add the map."
        )
    flux_map = FluxMap.from_grid(spec.flux_map)

    def aware(found):
        if isinstance(found, (StartupEstimator, PolarityDetector)):
            return with_parts(found, {"observer": aware(found.observer)})
        if isinstance(found, HybridEstimator):
            # no hand-over by current here: at standstill it would hand the angle to an observer that sees
            # no back-EMF (docs, chapter 6); with_current_handover sets it where it is wanted
            return with_parts(found, {"injection": aware(found.injection), "observer": aware(found.observer)})
        if isinstance(found, (HFIRotating, HFIPulsating)):
            return cross_saturation_compensated(found, flux_map)
        if hasattr(found, "with_flux_map"):  # an observer written on the current-flux relation reads the map
            return found.with_flux_map(flux_map)
        return map_angle_corrected(found, flux_map)

    return aware(estimator)


# --- the steps applied to a built drive, and the book's sensorless drive ----------------------------
_MACHINE_OF_PHASES = {3: "three-phase", 6: "six-phase", 5: "five-phase"}


def spec_drive(spec, control: str | None = None, **options) -> Drive:
    """[`assemble`][pmsmjax.assemble.assemble] of ``control`` on the drive file ``spec`` with preset
    ``options``, on the file's machine (its ``n_phases``)."""
    return assemble(spec, control, machine=_MACHINE_OF_PHASES[spec.n_phases], options=options)


def with_inverter_error(spec, drive: Drive) -> Drive:
    """``drive`` with the file's dead time and device drop
    ([`inverter_error_parts`][pmsmjax.assemble.inverter_error_parts])."""
    return with_parts(drive, inverter_error_parts(spec, drive))


def with_flux_map_control(drive: Drive, grid) -> Drive:
    """``drive`` (its plant the map ``grid``'s) with the map's current loop and d-axis references
    ([`flux_map_parts`][pmsmjax.assemble.flux_map_parts], without the plant)."""
    return with_parts(drive, flux_map_parts(drive, grid, plant=False))


def with_map_aware_estimator(spec, drive: Drive) -> Drive:
    """``drive`` with its sensorless estimator reading the file's flux map
    ([`map_aware`][pmsmjax.assemble.map_aware])."""
    return with_parts(drive, {"estimator": map_aware(drive.estimator, spec)})


def with_observer(drive: Drive, observer_name: str, model: PMSMParameters, *args, **kwargs) -> Drive:
    """``drive`` with the estimator ``observer_name`` for the motor model ``model`` in place of its own;
    ``args``, ``kwargs``: the options, start-up and start-up options of
    [`observer`][pmsmjax.assemble.observer]."""
    return with_parts(drive, {"estimator": observer(drive, observer_name, model, *args, **kwargs)})


def sensorless_drive(
    observer_name: str,
    motor: PMSMParameters | None = None,
    *,
    observer_options: dict | None = None,
    observer_model: PMSMParameters | None = None,
    startup: bool = False,
    startup_options: dict | None = None,
    **kw,
) -> Drive:
    """[`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive] (``kw`` go there) with the
    chapter 5 or 6 estimator ``observer_name`` (the registry's estimators) in place of the exact sensor: the
    controller runs on the estimate, and the trace's ``theta_e_est``/``omega_m_est`` are the estimator's.

    The estimator gets its design-rule gains for ``observer_model`` (default ``motor``: no plant/model
    mismatch) at the drive's period, overridden by ``observer_options``; unstable gains are refused. It
    starts cold, so the drive suits runs that start at speed or take over from another estimator;
    ``startup=True`` wraps it in the I/f start from standstill
    ([`StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator],
    [`STARTUP_DEFAULTS`][pmsmjax.assemble.STARTUP_DEFAULTS] overridden by ``startup_options``).
    """
    from pmsmjax.presets.three_phase import book_drive, book_motor

    motor = book_motor() if motor is None else motor
    drive = book_drive(motor, **kw)
    model = motor if observer_model is None else observer_model
    return with_observer(drive, observer_name, model, observer_options, startup, startup_options)
