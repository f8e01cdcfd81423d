"""The TI target of ``pmsmjax export`` (``--target ti``): the drive's motor model and gains under the names
and units of TI's MotorControl SDK universal motor control lab, written as a C header
(``ti_user_mtr1.h``: ``#define`` lines of ``user_mtr1.h``, plus the PI gains for ``PI_setGains``) and as
JSON.

Names, units and formulas, from the SDK's source: the C2000 MotorControl SDK v3.03 (its public mirror
anyway-blows/ti-c2000-motor-control-sdk, commit b0b88fb) and TI's own TexasInstruments/motor-control-sdk
(the same lab for AM26x):

- ``examples/tidm_02018_universal_motorcontrol/universal_motorcontrol/src_board/user_mtr1.h`` (TI, commit
  dfc3eed): ``USER_MOTOR1_NUM_POLE_PAIRS``, ``USER_MOTOR1_Rs_Ohm`` (ohm), ``USER_MOTOR1_Ls_d_H`` and
  ``USER_MOTOR1_Ls_q_H`` (H), ``USER_MOTOR1_RATED_FLUX_VpHz`` ("the rated flux value of the motor, in
  V/Hz"), ``USER_MOTOR1_MAX_CURRENT_A`` (A); ``USER_M1_PWM_FREQ_kHz``, ``USER_M1_NUM_PWM_TICKS_PER_ISR_TICK``,
  ``USER_M1_NUM_ISR_TICKS_PER_CURRENT_TICK``, ``USER_M1_NUM_ISR_TICKS_PER_SPEED_TICK`` (the control and
  speed-loop periods).
- ``.../src_board/user_mtr1.c`` (TI, commit 4498890):
  ``motor_ratedFlux_Wb = USER_MOTOR1_RATED_FLUX_VpHz / MATH_TWO_PI`` and ``Kctrl_Wb_p_kgm2 = 3 p
  motor_ratedFlux_Wb / (2 J)``: the lab's torque is ``1.5 p psi i_q``, so its flux is the peak,
  amplitude-invariant ``psi_f`` of the simulator and ``USER_MOTOR1_RATED_FLUX_VpHz = 2 pi psi_f`` (volts of
  peak phase back-EMF per electrical hertz); ``maxCurrent_A = USER_MOTOR1_MAX_CURRENT_A``.
- ``solutions/universal_motorcontrol_lab/common/source/motor_common.c`` (mirror; TI's
  ``src_control/motor_common.c``, commit bae4f5c, alike),
  ``setupControllers``: ``PI_setGains(piHandle_Id, Kp_Id, Ki_Id)`` with ``Kp_Id = Ls_d_H * BWc_rps`` (V/A)
  and ``Ki_Id = 0.25 * Rs/Ls_d * currentCtrlPeriod_sec`` (per period, no unit), likewise ``Iq``; the speed
  PI's output limited to ``+-maxCurrent_A``; its period ``numCtrlTicksPerSpeedTick / ctrlFreq_Hz``.
- ``libraries/control/pi/include/pi.h`` (mirror), ``PI_run_series``: ``Up = Kp * Error``, ``Ui =
  sat(Ui + Ki * Up)``, output ``sat(Up + Ui + ffwd)``: the series form, the integral updated before the
  output (TI's AM26x ``source/control/pi/include/pi.h``, commit 46f1d4a, calls ``DCL_runPISeries``: the
  same update, the integral held while the output saturates, in a copy of TI's DCL whose repository the
  search did not name).
- ``.../src_control/motor1_drive.c`` (TI, commit 4498890): the speed PI runs ``PI_run_series(piHandle_spd,
  speed_int_Hz, speed_reg_Hz, ...)`` every ``numCtrlTicksPerSpeedTick`` periods, in electrical hertz
  (``rpm2Hz_sf = motor_numPolePairs / 60``), into ``IsRef_A`` (the q-axis current reference, A); the Id PI
  is ``PI_run_series`` with a zero feed-forward (no decoupling), the Iq PI ``PI_run`` limited to
  ``sqrt(VsMax^2 - Vd^2)``.

Discretisation: the simulator's PI is forward Euler, ``u_k = kp e_k + ki Ts sum_{j<k} e_j``; TI's series PI
gives ``u_k = Kp (1 + Ki) e_k + Kp Ki sum_{j<k} e_j``. They are the same difference equation for ``Kp = kp -
ki Ts`` and ``Ki = ki Ts / (kp - ki Ts)`` (exact in the linear range when the lab runs the loop every
``Ts``); the inverse is ``kp = Kp (1 + Ki)``, ``ki = Kp Ki / Ts``. The speed PI takes ``kp + B_a``
(active damping folded in, [`pmsmjax.export.vendor_gains`][pmsmjax.export.vendor_gains]) and ``ki`` per
electrical hertz (``2 pi / p`` times the per-rad/s gains) at the speed loop's period. Refused in one line:
MTPA or field weakening (the lab's own FWC and MTPA are other loops), and a tuned gain pair whose ``Kp``
would not be positive (``ki Ts >= kp``).
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

__all__ = ["TI_FILES", "ti_parameters", "ti_files", "series_gains", "hz_per_rad_s"]

#: The files the TI target writes.
TI_FILES = ("ti_user_mtr1.h", "ti_user_mtr1.json")
#: The names of the PI gains (not user_mtr1.h names: the lab computes its gains at run time and sets them
#: with ``PI_setGains``), prefixed so that they cannot clash with the SDK's.
GAIN_PREFIX = "PMSMJAX_M1_"


def series_gains(kp: float, ki: float, Ts: float) -> tuple[float, float]:
    """``(Kp, Ki)`` of TI's series PI (``PI_run_series``) run every ``Ts`` seconds that is the simulator's
    forward-Euler PI with proportional gain ``kp`` and integral gain ``ki`` (per second): ``Kp = kp - ki
    Ts`` in the PI's own units, ``Ki = ki Ts / Kp`` per period (module docstring)."""
    kp_series = kp - ki * Ts
    return kp_series, ki * Ts / kp_series if kp_series != 0.0 else math.inf


def hz_per_rad_s(pole_pairs: int) -> float:
    """Electrical hertz (the lab's speed unit, ``speed_Hz``) per mechanical rad/s."""
    return pole_pairs / (2.0 * math.pi)


def _pi(axis: str, kp: float, ki: float, Ts: float, kp_unit: str, per: str) -> list:
    kp_series, ki_series = series_gains(kp, ki, Ts)
    return [
        VendorParameter(
            f"{GAIN_PREFIX}KP_{axis}_{kp_unit}",
            kp_series,
            kp_unit.replace("p", "/"),
            f"Kp = kp - ki Ts, Ts = {Ts:.6g} s (series PI){per}",
        ),
        VendorParameter(f"{GAIN_PREFIX}KI_{axis}", ki_series, "", f"Ki = ki Ts / Kp, per period{per}"),
    ]


def ti_parameters(d: ControllerDescription, where: str = "--motor") -> list:
    """The TI universal-lab parameters of the drive ``d``, a list of
    [`VendorParameter`][pmsmjax.export.vendor_gains.VendorParameter].

    Raises:
        ParameterError: one line, for what the lab's parameters cannot hold (module docstring).
    """
    refuse_d_axis(d, "ti", where)
    per_hz = 1.0 / hz_per_rad_s(d.pole_pairs)  # mechanical rad/s per electrical Hz: 2 pi / p
    gains = [
        *_pi("ID", d.current_kp_d, d.current_ki_d, d.Ts_s, "VpA", ""),
        *_pi("IQ", d.current_kp_q, d.current_ki_q, d.Ts_s, "VpA", ""),
        *_pi(
            "SPD",
            speed_kp_without_damping(d) * per_hz,
            d.speed_ki * per_hz,
            d.speed_period_s,
            "ApHz",
            "; kp = (kp + B_a) 2 pi/p, ki = ki 2 pi/p (per electrical Hz)",
        ),
    ]
    check_finite_positive("ti", gains)
    return [
        VendorParameter("USER_MOTOR1_TYPE", "MOTOR_TYPE_PM", "", "permanent-magnet synchronous motor"),
        VendorParameter("USER_MOTOR1_NUM_POLE_PAIRS", d.pole_pairs, "", "p"),
        VendorParameter("USER_MOTOR1_Rs_Ohm", d.R_ohm, "Ohm", "R"),
        VendorParameter("USER_MOTOR1_Ls_d_H", d.L_d_h, "H", "L_d"),
        VendorParameter("USER_MOTOR1_Ls_q_H", d.L_q_h, "H", "L_q"),
        VendorParameter(
            "USER_MOTOR1_RATED_FLUX_VpHz",
            2.0 * math.pi * d.psi_f_wb,
            "V/Hz",
            "2 pi psi_f: peak phase back-EMF per electrical Hz (user_mtr1.c: Wb = VpHz / 2 pi)",
        ),
        VendorParameter(
            "USER_MOTOR1_MAX_CURRENT_A", d.current_limit_a, "A", "I_max, peak (the speed PI's output limit)"
        ),
        VendorParameter("USER_M1_PWM_FREQ_kHz", 1e-3 / d.Ts_s, "kHz", "1/Ts: PWM and control frequency"),
        VendorParameter("USER_M1_NUM_PWM_TICKS_PER_ISR_TICK", 1, "", "the control loop every PWM period"),
        VendorParameter("USER_M1_NUM_ISR_TICKS_PER_CURRENT_TICK", 1, "", "the current loop every period"),
        VendorParameter(
            "USER_M1_NUM_ISR_TICKS_PER_SPEED_TICK", d.speed_divider, "", "the speed loop's divider"
        ),
        *gains,
    ]


def _notes(d: ControllerDescription) -> list[str]:
    return [
        "TI's PI_run_series (pi.h) updates the integral before the output: Kp = kp - ki Ts, Ki = ki Ts/Kp "
        "make it the simulator's forward-Euler PI when the lab runs the current loop every Ts = "
        f"{d.Ts_s:.6g} s and the speed loop every {d.speed_period_s:.6g} s.",
        "The speed PI runs in electrical Hz (speed_int_Hz, speed_reg_Hz): its gains are the per-rad/s gains "
        f"times 2 pi/p = {2.0 * math.pi / d.pole_pairs:.6g}; the simulator's active damping B_a = "
        f"{d.speed_active_damping:.6g} A/(rad/s) is folded into its proportional gain (same feedback loop, "
        "the reference path sees the PI zero).",
        "Anti-windup: TI's PI clamps the integral and the output to the limits (the simulator: "
        "back-calculation); the lab limits Vd, then Vq to sqrt(VsMax^2 - Vd^2).",
        "Not carried: decoupling, delay compensation, angle advance, dead-time compensation (the lab's own "
        "loop runs instead); not written: USER_M1_MAX_VS_MAG_PU (the voltage limit; its scaling against "
        "U_dc was not checked here), USER_MOTOR1_INERTIA_Kgm2 (the lab's own speed-gain rule; these gains "
        "replace it).",
    ]


def _c_value(p: VendorParameter) -> str:
    if isinstance(p.value, str):
        return p.value
    if isinstance(p.value, int):
        return f"({p.value})"
    text = f"{p.value:.9g}"
    return f"({text}{'' if any(c in text for c in '.e') else '.0'}f)"


def ti_files(d: ControllerDescription, where: str = "--motor") -> dict[str, str]:
    """``{file name: text}`` of the TI target (`TI_FILES`): ``ti_user_mtr1.h`` and the JSON."""
    parameters = ti_parameters(d, where)
    gains = "design rules of the drive file" if d.gains_source is None else f"gains file {d.gains_source}"
    defines = {p.name: p for p in parameters}
    width = max(len(name) for name in defines) + 1

    def define(p: VendorParameter) -> str:
        unit = f"{p.unit}: " if p.unit else ""
        return f"#define {p.name:<{width}} {_c_value(p)}  // {unit}{p.meaning}"

    user = [define(p) for p in parameters if not p.name.startswith(GAIN_PREFIX)]
    pi = [define(p) for p in parameters if p.name.startswith(GAIN_PREFIX)]
    g = GAIN_PREFIX
    lines = [
        f"// TI MotorControl SDK (universal motor control lab) parameters of the drive {d.source}, {gains};",
        "// written by pmsmjax export.",
        *(f"// {note}" for note in _notes(d)),
        "#ifndef PMSMJAX_TI_USER_MTR1_H",
        "#define PMSMJAX_TI_USER_MTR1_H",
        "",
        "// user_mtr1.h names: give these values to the motor block that USER_MOTOR1 selects and to the",
        "// board block's timing defines (a name defined twice with different values draws a diagnostic).",
        *user,
        "",
        "// PI gains for PI_setGains (pi.h, series form): set them after setupControllers(handle), which",
        "// computes the lab's own, e.g. with PMSMJAX_M1_SET_GAINS(obj) in initMotor1CtrlParameters, then",
        "// getControllers(handle) so that the lab's copies hold them.",
        *pi,
        "",
        "#define PMSMJAX_M1_SET_GAINS(obj) \\",
        "    do \\",
        "    { \\",
        f"        PI_setGains((obj)->piHandle_Id, {g}KP_ID_VpA, {g}KI_ID); \\",
        f"        PI_setGains((obj)->piHandle_Iq, {g}KP_IQ_VpA, {g}KI_IQ); \\",
        f"        PI_setGains((obj)->piHandle_spd, {g}KP_SPD_ApHz, {g}KI_SPD); \\",
        "    } while (0)",
        "",
        "#endif  // PMSMJAX_TI_USER_MTR1_H",
    ]
    return {
        TI_FILES[0]: "\n".join(lines) + "\n",
        TI_FILES[1]: gains_json("ti", d, parameters, _notes(d)),
    }
