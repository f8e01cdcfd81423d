"""The ODrive target of ``pmsmjax export`` (``--target odrive``): the drive's gains as the ODrive firmware
(0.5.x, the torque-and-turns units) names them, written as the ``odrv0.axis0.*`` assignments one pastes
into ``odrivetool`` and as JSON.

Units and formulas, from the firmware's interface definition and source (odriverobotics/ODrive):

- ``Firmware/odrive-interface.yaml`` (commit 029ab55): ``controller.config.vel_gain`` in
  ``Nm/(turn/s)``, ``vel_integrator_gain`` in ``Nm/(turn/s * s)``, ``vel_limit`` in ``turn/s``;
  ``motor.config.phase_resistance``, ``phase_inductance``, ``torque_constant``,
  ``current_control_bandwidth``, ``current_lim``, ``pole_pairs``. (Firmware 0.4 and older used
  ``A/(counts/s)``: ``Firmware/MotorControl/controller.hpp``, commit 0193097; not written here.)
- ``Firmware/MotorControl/motor.cpp`` (commit bddae0e), ``update_current_controller_gains``: the current PI
  is ``p_gain = current_control_bandwidth * phase_inductance``, ``i_gain = (phase_resistance /
  phase_inductance) * p_gain``, one pair for both axes; ``max_available_torque = current_lim *
  torque_constant``: torque per ampere of ``Iq``, which ODrive takes with the amplitude-invariant Clarke
  (``Ialpha = -phB - phC``, ``Ibeta = (phB - phC)/sqrt(3)``, motor.cpp commit 0489edf): peak amperes, as
  here, so ``torque_constant = 1.5 p psi_f``.
- ``Firmware/MotorControl/controller.cpp`` (commit b968a67): ``torque = vel_gain * v_err +
  vel_integrator_torque``, then ``vel_integrator_torque += (vel_integrator_gain * current_meas_period) *
  v_err`` (forward Euler, the simulator's discretisation: the same difference equation when ODrive's
  period is the drive's ``Ts``); anti-windup: the integrator decays by 0.99 per period while the torque is
  limited (the simulator uses back-calculation).

So ``vel_gain = 2 pi k_t (kp + B_a)`` (active damping folded in,
[`pmsmjax.export.vendor_gains`][pmsmjax.export.vendor_gains]), ``vel_integrator_gain = 2 pi k_t ki``,
``current_control_bandwidth = kp / L``. Refused in one line: MTPA or field weakening, d and q current gains
that differ, and current gains whose ``ki / kp`` is not ``R / L`` (ODrive derives ``i_gain`` from the
bandwidth and the motor's R and L, so it cannot hold such a tuned pair).
"""

import math

from pmsmjax.export.description import ControllerDescription
from pmsmjax.export.vendor_gains import (
    VendorParameter,
    check_finite_positive,
    gains_json,
    refuse_d_axis,
    speed_kp_without_damping,
    torque_constant_nm_per_a,
)
from pmsmjax.spec.validation import ParameterError

__all__ = ["ODRIVE_FILES", "odrive_parameters", "odrive_files", "si_gains_from_odrive"]

#: The files the ODrive target writes.
ODRIVE_FILES = ("odrive_config.txt", "odrive_config.json")
#: Relative mismatch of two float32 gains that export still takes as equal.
MATCH = 1e-5
TURN = 2.0 * math.pi  # rad per turn


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= MATCH * max(abs(a), abs(b))


def odrive_parameters(d: ControllerDescription, rated_speed_rpm: float, where: str = "--motor") -> list:
    """The ODrive parameters of the drive ``d``, a list of
    [`VendorParameter`][pmsmjax.export.vendor_gains.VendorParameter] named from ``axis0``.

    Args:
        d: the exported controller.
        rated_speed_rpm: the drive file's rated speed, r/min (ODrive's ``vel_limit``; its overspeed error
            trips at ``vel_limit_tolerance`` = 1.2 times it by default).
        where: how a refusal names the drive.

    Raises:
        ParameterError: one line, for what ODrive's parameters cannot hold (module docstring).
    """
    refuse_d_axis(d, "odrive", where)
    if not (_same(d.current_kp_d, d.current_kp_q) and _same(d.current_ki_d, d.current_ki_q)):
        raise ParameterError(
            f"--target odrive: {where} has d and q current gains that differ (kp {d.current_kp_d:.6g} / "
            f"{d.current_kp_q:.6g} V/A, ki {d.current_ki_d:.6g} / {d.current_ki_q:.6g} V/(A s)); ODrive runs "
            "one current PI on both axes: give --gains with equal controller.current kp_d, kp_q and ki_d, "
            "ki_q, or use --target c."
        )
    L, R = d.L_q_h, d.R_ohm
    bandwidth = d.current_kp_q / L
    if not _same(d.current_ki_q, bandwidth * R):
        raise ParameterError(
            f"--target odrive: the current PI's ki/kp = {d.current_ki_q / d.current_kp_q:.6g} 1/s is not the "
            f"motor's R/L = {R / L:.6g} 1/s; ODrive sets i_gain = current_control_bandwidth * R from the "
            "motor's R: keep the design-rule current gains (drop them from --gains) or use --target c."
        )
    kt = torque_constant_nm_per_a(d)
    kp = speed_kp_without_damping(d)
    parameters = [
        VendorParameter("axis0.motor.config.pole_pairs", int(d.pole_pairs), "", "pole pairs"),
        VendorParameter("axis0.motor.config.phase_resistance", R, "Ohm", "R"),
        VendorParameter("axis0.motor.config.phase_inductance", L, "H", "L (L_q = L_d)"),
        VendorParameter("axis0.motor.config.torque_constant", kt, "Nm/A", "1.5 p psi_f, per peak A of Iq"),
        VendorParameter("axis0.motor.config.current_lim", d.current_limit_a, "A", "I_max, peak"),
        VendorParameter(
            "axis0.motor.config.current_control_bandwidth", bandwidth, "rad/s", "kp/L; ODrive: ki = bw R"
        ),
        VendorParameter(
            "axis0.controller.config.control_mode", "CONTROL_MODE_VELOCITY_CONTROL", "", "speed mode"
        ),
        VendorParameter(
            "axis0.controller.config.vel_gain", TURN * kt * kp, "Nm/(turn/s)", "2 pi k_t (kp + B_a)"
        ),
        VendorParameter(
            "axis0.controller.config.vel_integrator_gain",
            TURN * kt * d.speed_ki,
            "Nm/(turn/s * s)",
            "2 pi k_t ki",
        ),
        VendorParameter("axis0.controller.config.vel_limit", rated_speed_rpm / 60.0, "turn/s", "rated speed"),
    ]
    check_finite_positive("odrive", parameters)
    return parameters


def si_gains_from_odrive(values: dict) -> dict:
    """The inverse conversion, as the ODrive firmware computes its gains from the parameters: ``{name:
    value}`` (the names of [`odrive_parameters`][pmsmjax.export.odrive.odrive_parameters]) ->
    ``{"current_kp" (V/A), "current_ki" (V/(A s)), "speed_kp" (A/(rad/s), active damping folded in),
    "speed_ki" (A/rad)}``."""
    bw = values["axis0.motor.config.current_control_bandwidth"]
    kt = values["axis0.motor.config.torque_constant"]
    return {
        "current_kp": bw * values["axis0.motor.config.phase_inductance"],
        "current_ki": bw * values["axis0.motor.config.phase_resistance"],
        "speed_kp": values["axis0.controller.config.vel_gain"] / (TURN * kt),
        "speed_ki": values["axis0.controller.config.vel_integrator_gain"] / (TURN * kt),
    }


def _notes(d: ControllerDescription) -> list[str]:
    return [
        "ODrive firmware 0.5.x units (torque and turns); paste the lines into odrivetool, then "
        "odrv0.save_configuration().",
        f"vel_gain folds the simulator's active damping B_a = {d.speed_active_damping:.6g} A/(rad/s) into "
        "the proportional gain: same feedback loop (poles, load rejection), the reference path sees the PI "
        "zero ki/(kp + B_a) (more overshoot on a step).",
        "Discretisation: ODrive's forward-Euler integrators at its current_meas_period, as the simulator's "
        f"at Ts = {d.Ts_s:.6g} s; anti-windup: ODrive decays the velocity integrator by 0.99 per period "
        "while the torque is limited (the simulator: back-calculation).",
        "Not carried (ODrive's own current loop runs instead): decoupling, delay compensation, angle "
        "advance, dead-time compensation; pos_gain is not written (speed mode).",
    ]


def odrive_files(d: ControllerDescription, rated_speed_rpm: float, where: str = "--motor") -> dict[str, str]:
    """``{file name: text}`` of the ODrive target (`ODRIVE_FILES`): the odrivetool lines and the JSON."""
    parameters = odrive_parameters(d, rated_speed_rpm, where)
    gains = "design rules of the drive file" if d.gains_source is None else f"gains file {d.gains_source}"
    lines = [
        f"# ODrive (firmware 0.5.x) parameters of the drive {d.source}, {gains}; written by pmsmjax export.",
        *(f"# {note}" for note in _notes(d)),
    ]
    for p in parameters:
        value = p.value if isinstance(p.value, str | int) else f"{p.value:.9g}"
        if isinstance(p.value, float) and not any(c in value for c in ".en"):
            value += ".0"
        unit = f"{p.unit}: " if p.unit else ""
        lines.append(f"odrv0.{p.name} = {value}  # {unit}{p.meaning}")
    return {
        ODRIVE_FILES[0]: "\n".join(lines) + "\n",
        ODRIVE_FILES[1]: gains_json("odrive", d, parameters, _notes(d)),
    }
