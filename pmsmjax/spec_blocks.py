"""A drive file's values as the blocks the engine takes: its motor, flux map, scenario, I/f start, compliant
shaft and speed-loop filters (the parts [`assemble`][pmsmjax.assemble.assemble] builds a drive from;
re-exported there)."""

from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "spec_motor",
    "spec_flux_map",
    "spec_scenario",
    "startup_options",
    "design_motor",
    "shaft_parts",
    "speed_filter_parts",
]


def spec_motor(spec):
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


_MOTOR_KEYS = ("R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B")


def spec_flux_map(spec):
    """The drive file's flux map as the plant's interpolant
    ([`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap]), or None when the file has none."""
    if spec.flux_map is None:
        return None
    from pmsmjax.machines.pmsm_flux_map import FluxMap

    return FluxMap.from_grid(spec.flux_map)


def spec_scenario(spec, speed_rpm=None, load_nm=None, load_time_s=None, duration_s=None):
    """The drive file's scenario (``[scenario]``, derived where absent), each value overridable: a speed
    step from rest to ``speed_rpm`` (r/min) at t = 0, a load step 0 -> ``load_nm`` (N m) at
    ``load_time_s`` (s), ``duration_s`` (s) in all."""
    from pmsmjax.presets.three_phase import book_scenario

    s = spec.scenario
    pick = lambda value, key: s[key] if value is None else value
    return book_scenario(
        pick(speed_rpm, "speed_rpm"),
        pick(load_nm, "load_nm"),
        pick(load_time_s, "load_time_s"),
        pick(duration_s, "duration_s"),
    )


def startup_options(spec) -> dict:
    """The I/f start of a sensorless drive on ``spec``
    ([`StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator] keywords; ``[control]`` startup
    values)."""
    c = spec.control
    return {
        "i_start": c["startup_current_a"],
        "accel": c["startup_acceleration_rad_s2"],
        "handover_speed": c["handover_speed_rad_s"],
        "blend_speed": c["blend_speed_rad_s"],
    }


def design_motor(spec):
    """The motor the control presets design for: [`spec_motor`][pmsmjax.spec_blocks.spec_motor], with a
    ``[mechanics]`` shaft its ``J`` the total inertia of motor and load (a rigid body: the design rules' and
    the controller model's view of the drive)."""
    motor = spec_motor(spec)
    if not spec.mechanics:
        return motor
    import dataclasses

    return dataclasses.replace(motor, J=spec.motor["J"] + spec.mechanics["load_inertia"])


def shaft_parts(spec) -> dict:
    """The parts that put the file's ``[mechanics]`` shaft into the plant: the motor's own ``J`` and the load
    inertia, stiffness and damping ([`pmsmjax.machines.shaft`][pmsmjax.machines.shaft]); none for a rigid
    shaft. The controller's model keeps the total inertia."""
    if not spec.mechanics:
        return {}
    from pmsmjax.machines.motor import as_float

    m = spec.mechanics
    values = {
        "J": spec.motor["J"],
        "load_inertia": m["load_inertia"],
        "shaft_stiffness": m["shaft_stiffness_nm_per_rad"],
        "shaft_damping": m["shaft_damping_nm_s_per_rad"],
    }
    return {f"machine.motor.{k}": as_float(v) for k, v in values.items()}


def speed_filter_parts(spec, drive) -> dict:
    """The part that puts the file's ``[control]`` speed-loop filters into the speed PI of ``drive``
    ([`SpeedLoopFilters`][pmsmjax.controllers.speed_filters.SpeedLoopFilters]); none without them. Refused in
    one line on a drive whose speed loop is not the PI, or whose speed loop runs slower than the file's
    checks assumed (a notch at or above its Nyquist frequency)."""
    c = spec.control
    keys = ("speed_filter_hz", "notch_hz", "notch_width_hz", "notch_depth_db")
    if not any(k in c for k in keys):
        return {}
    from pmsmjax.controllers.speed_filters import SpeedLoopFilters
    from pmsmjax.controllers.speed_pi import SpeedLoopGains

    speed = getattr(drive.controller, "speed", None)
    if not isinstance(speed, SpeedLoopGains) or getattr(drive.controller, "mode", "speed") != "speed":
        raise ParameterError(
            f"{spec.source}: [control] {', '.join(k for k in keys if k in c)} filter a speed PI; this "
            f"drive's controller ({type(drive.controller).__name__}) runs none: choose control pi (or "
            "another with the speed PI), or drop the filters."
        )
    filters = SpeedLoopFilters(*(c.get(k) for k in keys))
    filters.check_rate(drive.Ts * drive.controller.speed_divider, f"{spec.source}: [control]")
    return {"controller.speed.filters": filters}
