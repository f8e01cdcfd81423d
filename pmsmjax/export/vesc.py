"""The VESC target of ``pmsmjax export`` (``--target vesc``): the drive's gains under the names of VESC's
motor configuration (``mcconf``), written as ``name = value`` lines (``vesc_mcconf.txt``) and as JSON.
VESC Tool's mcconf XML is not written: its layout could not be checked against VESC Tool's source here.

Names, units and formulas, from the firmware (vedderb/bldc) and VESC Tool (vedderb/vesc_tool):

- ``widgets/detectfoc.cpp`` (vesc_tool, commit 03fba5c): ``foc_motor_r`` in ohm, ``foc_motor_l`` and
  ``foc_motor_ld_lq_diff`` in H (the dialog's uH divided by 1e6), ``foc_motor_flux_linkage`` in Wb (mWb
  divided by 1e3); the current PI ``kp = l * bw``, ``ki = r * bw`` (V/A and V/(A s), ``bw = 1/tc``);
  ``foc_observer_gain = 1.0e-3 / lambda^2 * 1e6``.
- ``motor/foc_math.c`` (bldc, commit 04f13d6): ``foc_precalc_values`` sets ``L_q = foc_motor_l +
  ld_lq_diff/2``, ``L_d = foc_motor_l - ld_lq_diff/2``; ``foc_run_pid_control_speed``: the speed error in
  ERPM (``RADPS2RPM_f`` of the electrical speed), ``p_term = error * s_pid_kp / 20``, the integral
  ``+= error * s_pid_ki * dt / 20`` (forward Euler, the output formed before the update, as the
  simulator's), output and integral clamped to +-1, ``m_iq_set = output * lo_current_max``.
- ``motor/mcpwm_foc.c`` (bldc, commit 013ef7a): the amplitude-invariant Clarke transform
  (``(2/3) ia - (1/3) ib - (1/3) ic``): peak amperes and a peak flux linkage, as here.

So ``s_pid_kp = 20 (kp + B_a) 2 pi / (60 p I_max)`` and ``s_pid_ki = 20 ki 2 pi / (60 p I_max)`` (per ERPM,
``I_max = l_current_max``; active damping folded in,
[`pmsmjax.export.vendor_gains`][pmsmjax.export.vendor_gains]). Refused in one line: MTPA or field
weakening, and d and q current gains that differ (VESC runs one current PI on both axes).
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
from pmsmjax.spec.validation import ParameterError

__all__ = ["VESC_FILES", "vesc_parameters", "vesc_files", "erpm_per_rad_s"]

#: The files the VESC target writes.
VESC_FILES = ("vesc_mcconf.txt", "vesc_mcconf.json")
MATCH = 1e-5


def erpm_per_rad_s(pole_pairs: int) -> float:
    """ERPM (electrical revolutions per minute, VESC's speed unit) per mechanical rad/s."""
    return pole_pairs * 60.0 / (2.0 * math.pi)


def vesc_parameters(d: ControllerDescription, where: str = "--motor") -> list:
    """The VESC mcconf parameters of the drive ``d``, a list of
    [`VendorParameter`][pmsmjax.export.vendor_gains.VendorParameter].

    Raises:
        ParameterError: one line, for what VESC's parameters cannot hold (module docstring).
    """
    refuse_d_axis(d, "vesc", where)
    same = lambda a, b: abs(a - b) <= MATCH * max(abs(a), abs(b))  # noqa: E731
    if not (same(d.current_kp_d, d.current_kp_q) and same(d.current_ki_d, d.current_ki_q)):
        raise ParameterError(
            f"--target vesc: {where} has d and q current gains that differ (kp {d.current_kp_d:.6g} / "
            f"{d.current_kp_q:.6g} V/A, ki {d.current_ki_d:.6g} / {d.current_ki_q:.6g} V/(A s)); VESC runs "
            "one current PI (foc_current_kp, foc_current_ki) on both axes: give --gains with equal "
            "controller.current kp_d, kp_q and ki_d, ki_q, or use --target c."
        )
    per_erpm = 20.0 / (erpm_per_rad_s(d.pole_pairs) * d.current_limit_a)
    return_ = [
        VendorParameter("foc_motor_r", d.R_ohm, "Ohm", "R"),
        VendorParameter("foc_motor_l", 0.5 * (d.L_d_h + d.L_q_h), "H", "(L_d + L_q)/2"),
        VendorParameter("foc_motor_ld_lq_diff", d.L_q_h - d.L_d_h, "H", "L_q - L_d"),
        VendorParameter("foc_motor_flux_linkage", d.psi_f_wb, "Wb", "psi_f, peak"),
        VendorParameter("foc_current_kp", d.current_kp_q, "V/A", "kp"),
        VendorParameter("foc_current_ki", d.current_ki_q, "V/(A s)", "ki"),
        VendorParameter(
            "foc_observer_gain",
            1.0e3 / d.psi_f_wb**2,
            "",
            "VESC Tool's rule 1e-3/lambda^2 * 1e6 (sensorless)",
        ),
        VendorParameter("l_current_max", d.current_limit_a, "A", "I_max, peak (the speed PID's full scale)"),
        VendorParameter(
            "s_pid_kp",
            speed_kp_without_damping(d) * per_erpm,
            "1/ERPM (x20)",
            "20 (kp + B_a) / (ERPM/(rad/s) I_max)",
        ),
        VendorParameter(
            "s_pid_ki", d.speed_ki * per_erpm, "1/(ERPM s) (x20)", "20 ki / (ERPM/(rad/s) I_max)"
        ),
    ]
    check_finite_positive("vesc", [p for p in return_ if p.name not in ("foc_motor_ld_lq_diff",)])
    return return_


def _notes(d: ControllerDescription) -> list[str]:
    return [
        f"VESC's speeds are ERPM: {erpm_per_rad_s(d.pole_pairs):.6g} ERPM per mechanical rad/s "
        f"({d.pole_pairs} pole pairs); set the motor's poles in VESC Tool to match.",
        "s_pid_kp and s_pid_ki fold the simulator's active damping into the proportional gain (same feedback "
        "loop); VESC clamps the speed integral to +-1 (the simulator: back-calculation).",
        "foc_observer_gain is VESC Tool's rule for the sensorless observer (the simulator's drive uses a "
        "position sensor); not carried: the simulator's delay compensation, angle advance and dead-time "
        "compensation (VESC's own current loop runs instead).",
        "VESC Tool's mcconf XML is not written; enter the values in VESC Tool or through its scripting.",
    ]


def vesc_files(d: ControllerDescription, where: str = "--motor") -> dict[str, str]:
    """``{file name: text}`` of the VESC target (`VESC_FILES`): ``name = value`` lines and the JSON."""
    parameters = vesc_parameters(d, where)
    gains = "design rules of the drive file" if d.gains_source is None else f"gains file {d.gains_source}"
    lines = [f"# VESC mcconf parameters of the drive {d.source}, {gains}; written by pmsmjax export."]
    lines += [f"# {note}" for note in _notes(d)]
    lines += [f"{p.name} = {p.value:.9g}  # {p.unit + ': ' if p.unit else ''}{p.meaning}" for p in parameters]
    return {
        VESC_FILES[0]: "\n".join(lines) + "\n",
        VESC_FILES[1]: gains_json("vesc", d, parameters, _notes(d)),
    }
