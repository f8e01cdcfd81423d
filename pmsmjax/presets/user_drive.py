"""The user's drive as a simulation: the motor, inverter, ratings and design-rule gains of a drive file
([`pmsmjax.io.drive_files.DriveSpec`][pmsmjax.io.drive_files.DriveSpec]) put into the presets of every control
method.

[`spec_drive`][pmsmjax.presets.user_drive.spec_drive] builds the drive of a control method
([`pmsmjax.presets.control_methods.CONTROLS`][pmsmjax.presets.control_methods.CONTROLS], or a six- or
five-phase scheme) at the file's DC link, control rate, current limit and bandwidths; the file's sensor (an
encoder) becomes the drive's estimator, and a three-phase drive's averaged bridge gets the file's dead time
and device drop ([`pmsmjax.inverters.voltage_error`][pmsmjax.inverters.voltage_error]) with, unless the file
turns it off, the FOC controller's dead-time compensation
([`with_inverter_error`][pmsmjax.presets.user_drive.with_inverter_error]).
[`spec_scenario`][pmsmjax.presets.user_drive.spec_scenario] is the file's scenario,
[`startup_options`][pmsmjax.presets.user_drive.startup_options] its I/f start for sensorless runs. On the book
drive file (``--motor book``) all three are bit for bit the book presets (tests/presets/test_user_drive.py).

A drive file with a flux map (``[motor] flux_map``) gets the map's plant
([`PMSMFluxMapdq`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq]) in place of the linear dq machine, and
control on the map
([`pmsmjax.presets.flux_map_control.with_flux_map_control`][pmsmjax.presets.flux_map_control.with_flux_map_control]:
the current loop scheduled on its inductances, MTPA and field weakening from its tables); the controller's
linear model (the file's or the map's derived ``L_d``, ``L_q``, ``psi_f``) remains for the speed loop's
design.
"""

import inspect

import equinox as eqx

from pmsmjax.drive import Drive
from pmsmjax.io.drive_files import DriveSpec
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.scenarios import Scenario

__all__ = [
    "spec_motor",
    "spec_flux_map",
    "drive_options",
    "spec_drive",
    "spec_scenario",
    "startup_options",
    "with_inverter_error",
    "with_map_aware_estimator",
    "SMC_LOAD_RISE_S",
]

#: The sliding-mode speed law's design load: the rated torque rising in this time, s (the book's 10 N m in
#: 10 ms, [`pmsmjax.presets.smc_drive`][pmsmjax.presets.three_phase.smc_drive]). Its sliding surface's time
#: constant is the speed loop's, ``1 / beta`` (the book's 20 ms at 50 rad/s).
SMC_LOAD_RISE_S = 0.01

_MOTOR_KEYS = ("R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B")


def spec_motor(spec: DriveSpec):
    """The drive file's motor: [`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters], or a six- or
    five-phase [`MultiPhaseParameters`][pmsmjax.machines.multiphase_motor.MultiPhaseParameters]."""
    if spec.n_phases == 3:
        return PMSMParameters(**{k: spec.motor[k] for k in _MOTOR_KEYS})
    from pmsmjax.presets.five_phase import five_phase_motor
    from pmsmjax.presets.six_phase import six_phase_motor

    if spec.source in ("book", "book_salient"):  # the rewind presets compute their values: keep them exact
        rewind = six_phase_motor if spec.n_phases == 6 else five_phase_motor
        return rewind(spec.source == "book_salient")
    from pmsmjax.machines.multiphase_motor import MultiPhaseParameters

    extra = {"psi_f3": spec.motor["psi_f3"]} if "psi_f3" in spec.motor else {}
    values = {k: spec.motor[k] for k in _MOTOR_KEYS + ("L_ls",)}
    return MultiPhaseParameters(**values, n_phases=spec.n_phases, **extra)


def spec_flux_map(spec: DriveSpec):
    """The drive file's flux map as the plant's interpolant
    ([`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap]), or None when the file has none."""
    if "flux_map" not in spec.motor:
        return None
    from pmsmjax.io.flux_map_files import read_flux_map
    from pmsmjax.machines.pmsm_flux_map import FluxMap

    return FluxMap.from_grid(read_flux_map(spec.motor["flux_map"]))


def _with_flux_map(drive: Drive, spec: DriveSpec) -> Drive:
    """``drive`` with its linear dq plant replaced by the file's flux-map plant (same motor, mechanics)."""
    from pmsmjax.checks.validation import ParameterError
    from pmsmjax.machines.pmsm3 import PMSMdq
    from pmsmjax.machines.pmsm_flux_map import PMSMFluxMapdq

    if type(drive.machine) is not PMSMdq:
        raise ParameterError(
            f"{spec.source}: [motor] flux_map runs in the rotor-frame (dq) machine, this drive simulates a "
            f"{type(drive.machine).__name__}: use the dq frame or drop the map."
        )
    plant = PMSMFluxMapdq(drive.machine.motor, spec_flux_map(spec), drive.machine.mechanics)
    return eqx.tree_at(lambda d: d.machine, drive, plant)


def with_map_aware_estimator(spec: DriveSpec, drive: Drive) -> Drive:
    """``drive`` with its sensorless estimator reading the file's flux map: HF injection corrected by the
    map's cross-saturation angle
    ([`pmsmjax.estimators.hfi_cross_saturation`][pmsmjax.estimators.hfi_cross_saturation]), a back-EMF
    observer or the EKF keeping its constant model with its angle corrected by the map at the operating
    current ([`pmsmjax.estimators.map_angle_corrected`][pmsmjax.estimators.map_angle_corrected]: the scheduled
    model of [`pmsmjax.estimators.map_scheduled`][pmsmjax.estimators.map_scheduled] oscillates in the closed
    loop); an I/f start keeps wrapping it."""
    from pmsmjax.checks.validation import ParameterError
    from pmsmjax.estimators.hfi_cross_saturation import cross_saturation_compensated
    from pmsmjax.estimators.hfi_pulsating import HFIPulsating
    from pmsmjax.estimators.hfi_rotating import HFIRotating
    from pmsmjax.estimators.map_angle_corrected import map_angle_corrected
    from pmsmjax.estimators.startup import StartupEstimator

    if "flux_map" not in spec.motor:
        raise ParameterError(
            f"{spec.source}: a map-aware estimator needs [motor] flux_map (a measured flux map CSV); this "
            "drive file has none: drop the map-aware option or add the map."
        )
    flux_map = spec_flux_map(spec)

    def aware(estimator):
        if isinstance(estimator, StartupEstimator):
            return eqx.tree_at(lambda s: s.observer, estimator, aware(estimator.observer))
        if isinstance(estimator, (HFIRotating, HFIPulsating)):
            return cross_saturation_compensated(estimator, flux_map)
        return map_angle_corrected(estimator, flux_map)

    return eqx.tree_at(lambda d: d.estimator, drive, aware(drive.estimator))


def _accepts(preset) -> set:
    params = inspect.signature(preset).parameters
    return {p for p, v in params.items() if v.kind == v.KEYWORD_ONLY}


def drive_options(spec: DriveSpec, control: str = "pi") -> dict:
    """The preset options
    ([`pmsmjax.presets.control_methods.control_drive`][pmsmjax.presets.control_methods.control_drive], or the
    six- and five-phase drives) that put the drive file into control ``control``'s drive: DC link, control
    period, current limit, bandwidths (and the SMC's design load)."""
    common = {
        "u_dc": spec.u_dc_v,
        "current_limit": spec.current_limit_a,
        "speed_bandwidth": spec.control["speed_bandwidth_rad_s"],
    }
    if spec.n_phases != 3:
        return {**common, "Ts": spec.Ts, "current_bandwidth": spec.control["current_bandwidth_rad_s"]}
    from pmsmjax.presets.control_methods import control_options

    allowed = set(control_options(control))
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


def spec_drive(spec: DriveSpec, control: str | None = None, **options) -> Drive:
    """The drive of ``control`` (default ``pi``, six- and five-phase ``vsd``) on the drive file ``spec``;
    ``options`` (preset options) override the file's. An encoder in ``[sensor]`` becomes the estimator."""
    if spec.n_phases == 3:
        from pmsmjax.presets.control_methods import control_drive

        control = control or "pi"
        merged = {**drive_options(spec, control), **options}
        drive = with_inverter_error(spec, control_drive(control, spec_motor(spec), **merged))
        if "flux_map" in spec.motor:
            from pmsmjax.io.flux_map_files import read_flux_map
            from pmsmjax.presets.flux_map_control import with_flux_map_control

            drive = _with_flux_map(drive, spec)
            drive = with_flux_map_control(drive, read_flux_map(spec.motor["flux_map"]))
    else:
        if spec.n_phases == 6:
            from pmsmjax.presets.six_phase import six_phase_drive as multiphase_drive
        else:
            from pmsmjax.presets.five_phase import five_phase_drive as multiphase_drive
        merged = {**drive_options(spec, control), **options}
        if merged.get("bridge") == "switching" and spec.inverter["dead_time_s"] > 0:
            merged.setdefault("dead_time", spec.inverter["dead_time_s"])
        drive = multiphase_drive(spec_motor(spec), control=control or "vsd", **merged)
    if spec.sensor["kind"] == "encoder":
        from pmsmjax.estimators.position_sensors import Encoder

        encoder = Encoder(spec.sensor["lines"], spec.motor["pole_pairs"], spec.sensor["delay_s"])
        drive = eqx.tree_at(lambda d: d.estimator, drive, encoder, is_leaf=lambda x: x is None)
    return drive


def with_inverter_error(spec: DriveSpec, drive: Drive) -> Drive:
    """``drive`` (three-phase, averaged bridge) with the file's ``[inverter]`` dead time and device drop
    in its bridge and, with ``dead_time_compensation`` (default true) and an FOC controller, the same
    estimates compensated in the controller (the other controllers have none). Unchanged when the file
    has neither a dead time nor a drop.

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
        return drive
    t_d_period = t_d * inv["switching_frequency_hz"] / inv["control_frequency_hz"]
    limit = float(drive.controller.current_limit) if hasattr(drive.controller, "current_limit") else None
    scale = CURRENT_LIMIT_SHARE * (spec.current_limit_a if limit is None else limit)
    bridge = AveragedBridge(
        drive.bridge.u_dc,
        drive.bridge.unroll_substeps,
        dead_time=t_d_period,
        device_drop=drop,
        sign_smoothing=scale,
    )
    drive = eqx.tree_at(lambda d: d.bridge, drive, bridge)
    if inv["dead_time_compensation"] and isinstance(drive.controller, FOC):
        compensation = DeadTimeCompensation(VoltageError(t_d_period, drop, scale))
        drive = eqx.tree_at(
            lambda d: d.controller.dead_time_compensation, drive, compensation, is_leaf=lambda x: x is None
        )
    return drive


def spec_scenario(
    spec: DriveSpec,
    speed_rpm: float | None = None,
    load_nm: float | None = None,
    load_time_s: float | None = None,
    duration_s: float | None = None,
) -> Scenario:
    """The drive file's scenario (``[scenario]``, derived where absent), each value overridable: a speed
    step from rest to ``speed_rpm`` at t = 0, a load step 0 -> ``load_nm`` at ``load_time_s``."""
    from pmsmjax.presets.three_phase import book_scenario

    s = spec.scenario
    pick = lambda value, key: s[key] if value is None else value
    return book_scenario(
        pick(speed_rpm, "speed_rpm"),
        pick(load_nm, "load_nm"),
        pick(load_time_s, "load_time_s"),
        pick(duration_s, "duration_s"),
    )


def startup_options(spec: DriveSpec) -> dict:
    """The I/f start of a sensorless drive on ``spec``
    ([`pmsmjax.estimators.startup.StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator] keywords;
    ``[control]`` startup values)."""
    c = spec.control
    return {
        "i_start": c["startup_current_a"],
        "accel": c["startup_acceleration_rad_s2"],
        "handover_speed": c["handover_speed_rad_s"],
        "blend_speed": c["blend_speed_rad_s"],
    }
