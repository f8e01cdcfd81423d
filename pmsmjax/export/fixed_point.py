"""The per-unit scaling and word formats of the fixed-point C target (``pmsmjax export --target c
--fixed-point q15 | q31``): the bases, each signal's Q format, every constant of the control step as an
integer mantissa and a power-of-two exponent, and the bound on the duty error the quantisation causes.

Bases (per unit, pu):

- current ``I_b`` = the drive's current limit, A (peak phase current);
- voltage ``U_b`` = ``U_dc / sqrt(3)`` of the drive file, V (the modulator's linear limit at the nominal DC
  link; the measured ``u_dc`` is an input in the same base, nominally ``sqrt(3)`` pu);
- speed ``w_b`` = ``U_b / (p psi_f)``, mechanical rad/s: the top speed of the i_d = 0 drive, where the
  magnets' back-EMF reaches the voltage limit (with it the back-EMF coefficient is exactly 1 pu);
- angle ``pi`` rad: the angle word wraps once per electrical turn.

Words (``W`` bits; ``q15``: int16 words, int32 intermediates; ``q31``: int32 words, int64 intermediates):
currents, voltages and speeds in ``Q2.(W-3)`` (range [-4, 4) pu, so overcurrent, a transient voltage
demand and the nominal DC link ``sqrt(3)`` pu fit), the angle in ``Q0.(W-1)`` of ``pi``, sine and cosine in
``Q1.(W-2)``, the PI integrals in a wider ``Q4.(I)`` accumulator (``q15``: int32, I = 27; ``q31``: int64,
I = 59) so that ``Ts ki e`` is not rounded away, the duties in ``Q0.(W-1)`` of the period. Each constant is
``m 2^-s`` with ``m`` a word (``|m|`` in ``[2^(W-2), 2^(W-1))``, relative error at most ``2^-(W-1)``).
"""

import dataclasses
import math

from pmsmjax.export.description import ControllerDescription
from pmsmjax.spec.validation import ParameterError

__all__ = ["FORMATS", "FixedFormat", "FixedScaling", "fixed_scaling", "quantise_constant", "duty_error_bound"]


@dataclasses.dataclass(frozen=True)
class FixedFormat:
    """One fixed-point variant's words.

    Attributes:
        name: ``"q15"`` or ``"q31"``.
        word_bits: bits of a signal word (16, 32).
        word, acc, uacc: the C types of a word, an intermediate, an unsigned intermediate.
        signal_frac: fractional bits of currents, voltages and speeds (pu).
        trig_frac: fractional bits of sine and cosine.
        integral_frac: fractional bits of the PI integrals (held in ``acc``).
        table_bits: log2 of the sine table's points per electrical turn (linear interpolation between).
    """

    name: str
    word_bits: int
    word: str
    acc: str
    uacc: str
    signal_frac: int
    trig_frac: int
    integral_frac: int
    table_bits: int

    @property
    def duty_frac(self) -> int:
        """Fractional bits of the duties (and of the dwell times' sum, ``Q(W-1)``)."""
        return self.word_bits - 1

    @property
    def time_frac(self) -> int:
        """Fractional bits of SVPWM's dwell times, in periods."""
        return self.word_bits - 2


FORMATS = {
    "q15": FixedFormat("q15", 16, "int16_t", "int32_t", "uint32_t", 13, 14, 27, 10),
    "q31": FixedFormat("q31", 32, "int32_t", "int64_t", "uint64_t", 29, 30, 59, 12),
}


def quantise_constant(value: float, word_bits: int) -> tuple[int, int]:
    """``(m, s)`` with ``m 2^-s`` nearest ``value``, ``|m|`` in ``[2^(W-2), 2^(W-1))``; 0 gives ``(0, 0)``."""
    if value == 0.0:
        return 0, 0
    s = word_bits - 2 - math.floor(math.log2(abs(value)))
    m = round(value * 2.0**s)
    if abs(m) >= 2 ** (word_bits - 1):
        s -= 1
        m = round(value * 2.0**s)
    return int(m), int(s)


@dataclasses.dataclass(frozen=True)
class FixedScaling:
    """The bases and the step's constants of one variant.

    Attributes:
        fmt: the words ([`FixedFormat`][pmsmjax.export.fixed_point.FixedFormat]).
        current_base_a, voltage_base_v, speed_base_rad_s: ``I_b`` (A), ``U_b`` (V), ``w_b`` (mechanical
            rad/s).
        u_dc_v: the drive file's DC link, V.
        constants: ``{C name: (value in pu, m, s, meaning)}``.
    """

    fmt: FixedFormat
    current_base_a: float
    voltage_base_v: float
    speed_base_rad_s: float
    u_dc_v: float
    constants: dict

    def m(self, name: str) -> int:
        """The mantissa of the constant ``name``."""
        return self.constants[name][1]

    def s(self, name: str) -> int:
        """The exponent of the constant ``name``."""
        return self.constants[name][2]


def _refuse_fixed(d: ControllerDescription, variant: str, where: str) -> None:
    flag = f"--fixed-point {variant}"
    if d.d_axis != "none":
        raise ParameterError(
            f"{flag}: {where} runs {'MTPA' if d.d_axis == 'mtpa' else 'field weakening'}, which the "
            "fixed-point controller does not write (it writes the i_d = 0 cascade); drop --field-weakening, "
            "or drop --fixed-point for the float32 controller."
        )
    if d.dead_time_compensation:
        raise ParameterError(
            f"{flag}: {where} compensates its dead time (tanh of the phase currents), which the fixed-point "
            "controller does not write; set [inverter] dead_time_s = 0 in the drive file, or drop "
            "--fixed-point for the float32 controller."
        )


def fixed_scaling(
    d: ControllerDescription, u_dc_v: float, variant: str, where: str = "--motor"
) -> FixedScaling:
    """The scaling of ``d`` in the variant ``variant`` (``"q15"``, ``"q31"``).

    Args:
        d: the exported controller.
        u_dc_v: the drive file's DC link, V (the voltage base is ``u_dc_v / sqrt(3)``).
        variant: the key of `FORMATS`.
        where: how a refusal names the drive.

    Raises:
        ParameterError: one line, for MTPA, field weakening or dead-time compensation (not written in fixed
            point), or a constant outside the words' range.
    """
    _refuse_fixed(d, variant, where)
    fmt = FORMATS[variant]
    I_b = d.current_limit_a
    U_b = u_dc_v / math.sqrt(3.0)
    w_b = U_b / (d.pole_pairs * d.psi_f_wb)
    we_b = d.pole_pairs * w_b  # electrical rad/s at 1 pu speed
    Ts = d.Ts_s
    values = {
        "K_THIRD": (1.0 / 3.0, "Clarke: (2a - b - c)/3"),
        "K_INV_SQRT3": (1.0 / math.sqrt(3.0), "1/sqrt(3): Clarke's beta and u_max = u_dc/sqrt(3)"),
        "K_SQRT3": (math.sqrt(3.0), "sqrt(3): SVPWM"),
        "K_HALF_SQRT3": (0.5 * math.sqrt(3.0), "sqrt(3)/2: SVPWM"),
        "K_THREE_HALVES": (1.5, "3/2: SVPWM"),
        "K_SPEED_KP": (d.speed_kp * w_b / I_b, "speed PI kp w_b/I_b"),
        "K_SPEED_KI_TS": (d.speed_ki * d.speed_period_s * w_b / I_b, "speed PI ki Ts_speed w_b/I_b"),
        "K_SPEED_B_A": (d.speed_active_damping * w_b / I_b, "active damping B_a w_b/I_b"),
        "K_SPEED_TRACK": (d.speed_tracking, "speed anti-windup tracking gain"),
        "K_KP_D": (d.current_kp_d * I_b / U_b, "kp_d I_b/U_b"),
        "K_KP_Q": (d.current_kp_q * I_b / U_b, "kp_q I_b/U_b"),
        "K_KI_TS_D": (d.current_ki_d * Ts * I_b / U_b, "ki_d Ts I_b/U_b"),
        "K_KI_TS_Q": (d.current_ki_q * Ts * I_b / U_b, "ki_q Ts I_b/U_b"),
        "K_R": (d.R_ohm * I_b / U_b, "R I_b/U_b"),
        "K_WLD": (we_b * d.L_d_h * I_b / U_b, "p w_b L_d I_b/U_b"),
        "K_WLQ": (we_b * d.L_q_h * I_b / U_b, "p w_b L_q I_b/U_b"),
        "K_PSI": (we_b * d.psi_f_wb / U_b, "p w_b psi_f/U_b (1 by the speed base)"),
        "K_TS_LD": (Ts * U_b / (d.L_d_h * I_b), "Ts U_b/(L_d I_b): one period's current change per pu volt"),
        "K_TS_LQ": (Ts * U_b / (d.L_q_h * I_b), "Ts U_b/(L_q I_b)"),
        "K_LEAD": (
            we_b * (1.5 if d.computation_delay else 0.5) * Ts / math.pi,
            "p w_b (1.5 or 0.5) Ts/pi: the angle advance per pu speed, in pi rad",
        ),
    }
    constants = {}
    for name, (value, meaning) in values.items():
        if not math.isfinite(value) or abs(value) >= 2.0 ** (fmt.word_bits - 4):
            raise ParameterError(
                f"--fixed-point {variant}: the constant {name} = {value:.6g} pu ({meaning}) of {where} does "
                "not fit the fixed-point words; check the drive file's ratings and gains, or drop "
                "--fixed-point."
            )
        constants[name] = (value, *quantise_constant(value, fmt.word_bits), meaning)
    return FixedScaling(fmt, I_b, U_b, w_b, u_dc_v, constants)


def duty_error_bound(
    d: ControllerDescription, sc: FixedScaling, i_max_pu: float = 1.25, speed_max_pu: float = 1.0
) -> dict:
    """Worst-case difference of one control step of the fixed-point controller from the float32 controller's
    on the same samples and the same state (the state quantised to the words), in the operating range
    ``|i| <= i_max_pu``, ``|w| <= speed_max_pu``: each quantisation step (an input's half LSB, a product's
    rounding, a constant's relative error, the sine table's error) times the gains it passes through, added
    up (triangle inequality). The clip and the vector limit are nonexpansive; over-modulation is taken as
    linear (its rescaling is a projection in the dwell times).

    Returns:
        ``{"i_dq": pu, "u_dq": pu, "duty": of the period, "trig": sine table error}``.
    """
    f = sc.fmt
    q = 2.0**-f.signal_frac  # signal LSB, pu
    rel = 2.0 ** -(f.word_bits - 1)  # relative error of a constant
    qa = math.pi * 2.0 ** -(f.word_bits - 1)  # angle LSB, rad
    trig = (2 * math.pi / 2**f.table_bits) ** 2 / 8 + 2.0**-f.trig_frac  # sine: interpolation + rounding
    rot = qa / 2 + 2 * trig  # a rotation's error per unit vector length
    K = {name: abs(v[0]) for name, v in sc.constants.items()}
    i_m, w_m, u_m = i_max_pu, speed_max_pu, 1.0 + 4 * q

    def prod(k, x_mag, dx):  # error of k x: the input's error, the constant's, the rounding
        return k * dx + k * x_mag * rel + q / 2

    d_iab = math.hypot(1.5 * q, q / math.sqrt(3) + q / 2)  # Clarke of three half-LSB roundings
    d_idq = d_iab + i_m * rot + q / 2
    d_w = q / 2
    if d.computation_delay and d.delay_compensation:
        d_wi = w_m * d_idq + i_m * d_w + q / 2
        d_sum = q / 2 + prod(K["K_R"], i_m, d_idq) + prod(max(K["K_WLD"], K["K_WLQ"]), w_m * i_m, d_wi)
        d_sum += prod(K["K_PSI"], w_m, d_w)
        mag = u_m + K["K_R"] * i_m + K["K_WLD"] * w_m * i_m + K["K_PSI"] * w_m
        d_ic = d_idq + prod(max(K["K_TS_LD"], K["K_TS_LQ"]), mag, d_sum)
    else:
        d_ic = d_idq
    if d.decoupling:
        d_wi = w_m * d_ic + i_m * d_w + q / 2
        d_ff = prod(max(K["K_WLD"], K["K_WLQ"]), w_m * i_m, d_wi) + prod(K["K_PSI"], w_m, d_w)
    else:
        d_ff = 0.0
    e_w = 2 * w_m
    d_iq_ref = prod(K["K_SPEED_KP"], e_w, 2 * d_w) + prod(K["K_SPEED_B_A"], w_m, d_w) + q + q / 2
    d_e = d_iq_ref + d_ic
    d_v = prod(max(K["K_KP_D"], K["K_KP_Q"]), 2 * i_m, d_e) + q / 2 + 2.0**-f.integral_frac + d_ff
    d_umax = prod(K["K_INV_SQRT3"], 2.0, q / 2)
    d_u = 2 * (d_v + d_umax + 2 * q)  # both axes, the limit's division and square root
    d_lead = qa + math.pi * (K["K_LEAD"] * d_w + K["K_LEAD"] * w_m * rel)  # theta and lead roundings
    d_uab = d_u + u_m * (d_lead + 2 * trig) + q
    u_dc = math.sqrt(3.0)  # nominal DC link, pu
    duty = 2 * d_uab / u_dc + 2 * u_m * (q / 2) / u_dc**2 + 5 * 2.0**-f.time_frac + 2.0 ** -(f.word_bits - 1)
    return {"i_dq": d_ic, "u_dq": d_u, "duty": duty, "trig": trig}
