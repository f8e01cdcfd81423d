"""The SimpleFOC target of ``pmsmjax export`` (``--target simplefoc``): the drive's gains as the
SimpleFOC library's ``PIDController`` and ``LowPassFilter`` fields, written as C++ lines for an Arduino
sketch (``simplefoc_gains.h``) and as JSON.

Names, units and discretisation, from the library's source (simplefoc/Arduino-FOC) and documentation:

- ``src/common/base_classes/FOCMotor.h`` (commit 0542fb7): ``PID_current_q``, ``PID_current_d``,
  ``PID_velocity``, ``LPF_current_q``, ``LPF_current_d``, ``LPF_velocity``, ``voltage_limit``,
  ``current_limit``, ``motion_downsample``; ``shaftVelocity()`` in rad/s (mechanical).
- https://docs.simplefoc.com/velocity_loop: with a current torque mode the velocity PID sets the target
  current ``iq`` (A), ``current_limit`` in A, ``voltage_limit`` in V; https://docs.simplefoc.com/
  foc_current_torque_mode: ``TorqueControlType::foc_current``, ``U_q = PID_q(I_d - i_q)``,
  ``U_d = PID_d(0 - i_d)`` (V from A: ``P`` in V/A, ``I`` in V/(A s)).
- ``src/common/pid.cpp`` (commit a09f828): ``integral = integral_prev + I*Ts*0.5f*(error + error_prev)``
  (Tustin), the integral and the output clamped to ``+-limit``, the output ramp applied only when
  ``output_ramp > 0``; ``Ts`` from ``micros()`` (or the fixed sampling time, https://docs.simplefoc.com/
  pid_implementation).
- ``src/common/lowpass_filter.cpp`` (commit 135c9d4): ``alpha = Tf/(Tf + dt)``: ``Tf = 0`` passes the
  signal through, as the simulator's controller takes the sensor's speed and currents unfiltered.

Discretisation: the simulator's PI is forward Euler, ``u_k = kp e_k + ki Ts sum_{j<k} e_j``; SimpleFOC's
Tustin PI gives ``u_k = (P + I Ts/2) e_k + I Ts sum_{j<k} e_j``. They are the same difference equation for
``I = ki``, ``P = kp - ki Ts/2`` (exact in the linear range when the library's loop runs every ``Ts``:
``loopFOC()`` and ``move()`` once per period, ``motion_downsample = 0``); the inverse is ``kp = P + I Ts/2``.
The velocity PI takes ``kp + B_a`` (active damping folded in,
[`pmsmjax.export.vendor_gains`][pmsmjax.export.vendor_gains]) at the speed loop's period. Anti-windup:
SimpleFOC clamps the integral to ``+-limit`` (the simulator: back-calculation); its current PIs clamp
``U_d`` and ``U_q`` each to ``voltage_limit`` (the simulator limits the vector). Refused in one line: MTPA
or field weakening (SimpleFOC's ``foc_current`` sets ``i_d* = 0``), and a tuned gain pair whose ``P``
would not be positive.
"""

import math

from pmsmjax.export.description import ControllerDescription
from pmsmjax.export.vendor_gains import (
    VendorParameter,
    check_finite_positive,
    gains_json,
    refuse_d_axis,
    speed_kp_without_damping,
)

__all__ = ["SIMPLEFOC_FILES", "simplefoc_parameters", "simplefoc_files", "kp_from_tustin"]

#: The files the SimpleFOC target writes.
SIMPLEFOC_FILES = ("simplefoc_gains.h", "simplefoc_gains.json")


def kp_from_tustin(p_gain: float, i_gain: float, Ts: float) -> float:
    """The forward-Euler proportional gain of SimpleFOC's Tustin PI (``P`` = ``p_gain``, ``I`` =
    ``i_gain``) run every ``Ts`` seconds: ``kp = P + I Ts/2`` (module docstring)."""
    return p_gain + 0.5 * i_gain * Ts


def _pid(name: str, kp: float, ki: float, Ts: float, limit: float, units: tuple[str, str, str]):
    p_unit, i_unit, out_unit = units
    return [
        VendorParameter(f"{name}.P", kp - 0.5 * ki * Ts, p_unit, f"kp - ki Ts/2, Ts = {Ts:.6g} s (Tustin)"),
        VendorParameter(f"{name}.I", ki, i_unit, "ki"),
        VendorParameter(f"{name}.D", 0.0, "", "no derivative"),
        VendorParameter(f"{name}.output_ramp", 0.0, f"{out_unit}/s", "0: no ramp"),
        VendorParameter(f"{name}.limit", limit, out_unit, "output and integral clamp"),
    ]


def simplefoc_parameters(d: ControllerDescription, u_dc_v: float, where: str = "--motor") -> list:
    """The SimpleFOC parameters of the drive ``d`` (members of the ``BLDCMotor``), a list of
    [`VendorParameter`][pmsmjax.export.vendor_gains.VendorParameter].

    Args:
        d: the exported controller.
        u_dc_v: the DC-link voltage, V (``voltage_limit = u_dc/sqrt(3)``, SVPWM's linear range).
        where: how a refusal names the drive.

    Raises:
        ParameterError: one line, for what SimpleFOC's parameters cannot hold (module docstring).
    """
    refuse_d_axis(d, "simplefoc", where)
    u_max = u_dc_v / math.sqrt(3.0)
    volts = ("V/A", "V/(A s)", "V")
    parameters = [
        VendorParameter("controller", "MotionControlType::velocity", "", "speed mode"),
        VendorParameter("torque_controller", "TorqueControlType::foc_current", "", "dq current PIs"),
        VendorParameter("motion_downsample", 0, "", "no downsampling of move(): the speed PI every Ts"),
        VendorParameter("voltage_limit", u_max, "V", "u_dc/sqrt(3)"),
        VendorParameter("current_limit", d.current_limit_a, "A", "I_max, peak"),
        *_pid("PID_current_q", d.current_kp_q, d.current_ki_q, d.Ts_s, u_max, volts),
        *_pid("PID_current_d", d.current_kp_d, d.current_ki_d, d.Ts_s, u_max, volts),
        *_pid(
            "PID_velocity",
            speed_kp_without_damping(d),
            d.speed_ki,
            d.speed_period_s,
            d.current_limit_a,
            ("A/(rad/s)", "A/rad", "A"),
        ),
        VendorParameter("LPF_velocity.Tf", 0.0, "s", "no filter (the sensor's speed as the simulator)"),
        VendorParameter("LPF_current_q.Tf", 0.0, "s", "no filter"),
        VendorParameter("LPF_current_d.Tf", 0.0, "s", "no filter"),
    ]
    check_finite_positive("simplefoc", [p for p in parameters if p.name.endswith((".P", ".I"))])
    return parameters


def _notes(d: ControllerDescription) -> list[str]:
    return [
        "SimpleFOC PIDController: Tustin integral, P = kp - ki Ts/2 makes it the simulator's forward-Euler "
        f"PI when loopFOC() and move() run every Ts = {d.Ts_s:.6g} s (speed loop every "
        f"{d.speed_period_s:.6g} s).",
        f"PID_velocity folds the simulator's active damping B_a = {d.speed_active_damping:.6g} A/(rad/s) "
        "into the proportional gain: same feedback loop (poles, load rejection), the reference path sees "
        "the PI zero ki/(kp + B_a).",
        "Anti-windup: SimpleFOC clamps the integral to the limit (the simulator: back-calculation); U_d, U_q "
        "are clamped each to voltage_limit (the simulator limits the vector).",
        "Not carried: decoupling, delay compensation, angle advance, dead-time compensation (SimpleFOC's "
        "own loop runs instead).",
    ]


def _cpp_value(p: VendorParameter) -> str:
    if isinstance(p.value, str):
        return p.value
    if isinstance(p.value, int):
        return str(p.value)
    text = f"{p.value:.9g}"
    return text + ("" if any(c in text for c in ".e") else ".0") + "f"


def simplefoc_files(d: ControllerDescription, u_dc_v: float, where: str = "--motor") -> dict[str, str]:
    """``{file name: text}`` of the SimpleFOC target (`SIMPLEFOC_FILES`): ``simplefoc_gains.h`` with
    ``pmsmjax_apply_gains(FOCMotor &motor)`` (call it in ``setup()`` before ``motor.init()``) and the JSON."""
    parameters = simplefoc_parameters(d, u_dc_v, where)
    gains = "design rules of the drive file" if d.gains_source is None else f"gains file {d.gains_source}"
    lines = [
        f"// SimpleFOC parameters of the drive {d.source}, {gains}; written by pmsmjax export.",
        *(f"// {note}" for note in _notes(d)),
        "#pragma once",
        "#include <SimpleFOC.h>",
        "",
        "// call in setup(), after linking the sensor, driver and current sense, before motor.init()",
        "inline void pmsmjax_apply_gains(FOCMotor &motor)",
        "{",
    ]
    for p in parameters:
        unit = f"{p.unit}: " if p.unit else ""
        lines.append(f"    motor.{p.name} = {_cpp_value(p)};  // {unit}{p.meaning}")
    lines.append("}")
    return {
        SIMPLEFOC_FILES[0]: "\n".join(lines) + "\n",
        SIMPLEFOC_FILES[1]: gains_json("simplefoc", d, parameters, _notes(d)),
    }
