"""The C99 code of the exported controller's steps, block by block, each the float32 operations of the
simulator's block in the same order (so that the C controller gives the simulator's duties to float32
rounding). [`pmsmjax.export.c_source`][pmsmjax.export.c_source] puts them together.

Every block is a string of statements inside ``pmsm_controller_step``; the names they share:
``in`` (the inputs), ``c`` (the state), ``i_alpha``, ``i_beta`` (A), ``omega_e`` (electrical rad/s),
``u_max`` (V), ``cos_t``, ``sin_t`` (of ``theta_e``), ``id_ref``, ``iq_ref`` (A), ``u_alpha``, ``u_beta`` (V).
Where the simulator writes a product of two Python numbers (``0.5 * SQRT3``), it is one float32 constant
here too (``PMSM_HALF_SQRT3``); ``Ts`` reaches every product as a float32 (``PMSM_TS``).
"""

from pmsmjax.export.description import ControllerDescription

__all__ = [
    "c_float",
    "d_axis_block",
    "speed_block",
    "current_block",
    "dead_time_block",
    "svpwm_block",
]


def c_float(value: float) -> str:
    """A float32 C literal of ``value`` with 9 significant digits (round-trips float32): ``1.5f``,
    ``2.00000009e-06f``."""
    import math

    if not math.isfinite(value):
        raise ValueError(f"not a finite number: {value!r}")
    text = f"{value:.9g}"
    if not any(ch in text for ch in ".en"):
        text += ".0"
    return text + "f"


def d_axis_block(d: ControllerDescription) -> str:
    """Step 1 of the cascade, the d-axis reference (``foc.cascade_references``): i_d* = 0, MTPA on last
    period's i_q* (``mtpa.mtpa_id_from_iq``, rationalised form), or voltage-feedback field weakening
    (``field_weakening.voltage_feedback_update``) over it; then the current circle's room for i_q*."""
    mtpa = """
    {   /* MTPA on last period's i_q* (book ch. 3; rationalised: no division by L_q - L_d) */
        const float dL = PMSM_L_Q - PMSM_L_D;
        const float arg = PMSM_PSI_F * PMSM_PSI_F + (4.0f * (dL * dL)) * (c->iq_ref * c->iq_ref);
        const float den = PMSM_PSI_F + (arg > 0.0f ? sqrtf(arg) : 0.0f);
        id_base = den > 0.0f ? ((-2.0f * dL) * (c->iq_ref * c->iq_ref)) / den : 0.0f;
    }"""
    if d.d_axis == "none":
        code = "    float id_ref = 0.0f; /* i_d = 0 control (the book, ch. 3) */\n"
    elif d.d_axis == "mtpa":
        code = f"    float id_base = 0.0f;{mtpa}\n    float id_ref = id_base;\n"
    else:
        base = f"    float id_base = 0.0f;{mtpa}\n" if d.fw_mtpa else "    const float id_base = 0.0f;\n"
        code = (
            base
            + """    {   /* voltage-feedback field weakening (Kim and Sul 1997) */
        const float u_sq = c->u_d_prev * c->u_d_prev + c->u_q_prev * c->u_q_prev;
        const float u_mag = u_sq > 0.0f ? sqrtf(u_sq) : 0.0f;
        const float margin = PMSM_FW_MARGIN * u_max - u_mag;
        const float w_l = omega_e * PMSM_L_D;
        const float gain = PMSM_FW_BANDWIDTH / sqrtf(PMSM_R * PMSM_R + w_l * w_l);
        float delta = c->fw_delta_id + (PMSM_TS * gain) * margin;
        const float lowest = PMSM_FW_ID_MIN - id_base;
        delta = delta > lowest ? delta : lowest;
        delta = delta < 0.0f ? delta : 0.0f;
        c->fw_delta_id = delta;
    }
    float id_ref = id_base + c->fw_delta_id;
"""
        )
    return (
        code
        + """    id_ref = clip(id_ref, -PMSM_CURRENT_LIMIT, PMSM_CURRENT_LIMIT);
    const float iq_max_sq = PMSM_CURRENT_LIMIT * PMSM_CURRENT_LIMIT - id_ref * id_ref;
    const float iq_max = iq_max_sq > 0.0f ? sqrtf(iq_max_sq) : 0.0f;
"""
    )


def speed_block(d: ControllerDescription) -> str:
    """Step 2, the speed PI with active damping (``speed_pi.SpeedLoopGains`` through ``pi.pi_update``):
    forward-Euler integral, output clipped to the current circle's room, back-calculation anti-windup with
    tracking gain ``PMSM_SPEED_TRACKING``; run every ``PMSM_SPEED_DIVIDER`` periods, held in between."""
    return """    float iq_ref = c->iq_ref;
    if (c->counter == 0) {   /* speed PI with active damping (book ch. 3) */
        const float e = in->speed_ref - in->omega_m;
        const float ff = (-PMSM_SPEED_B_A) * in->omega_m;
        const float v = (PMSM_SPEED_KP * e + c->speed_integral) + ff;
        const float u = clip(v, -iq_max, iq_max);
        c->speed_integral = (c->speed_integral + (PMSM_TS_SPEED * PMSM_SPEED_KI) * e)
                            + PMSM_SPEED_TRACKING * (u - v);
        iq_ref = u;
    }
    c->counter = (c->counter + 1) % PMSM_SPEED_DIVIDER;
    c->iq_ref = iq_ref;
    c->i_d_ref = id_ref;
"""


def current_block(d: ControllerDescription) -> str:
    """Step 3, the dq current PIs (``current_pi.CurrentLoopGains``): Park, the one-period prediction of the
    current (delay compensation), decoupling, PI with the voltage vector limited to the modulator's linear
    range (back-calculation, tracking gain 1: the integral reset onto the limit), inverse Park at the angle
    advanced to the middle of the period the command is applied in."""
    predict = d.computation_delay and d.delay_compensation
    code = """    const float i_d = i_alpha * cos_t + i_beta * sin_t;
    const float i_q = -i_alpha * sin_t + i_beta * cos_t;
"""
    if predict:
        code += """    /* delay compensation: the current one period ahead (committed voltage) */
    const float did = ((c->u_d_prev - PMSM_R * i_d) + (omega_e * PMSM_L_Q) * i_q) / PMSM_L_D;
    const float diq = ((c->u_q_prev - PMSM_R * i_q) - omega_e * (PMSM_L_D * i_d + PMSM_PSI_F)) / PMSM_L_Q;
    const float ic_d = i_d + PMSM_TS * did;
    const float ic_q = i_q + PMSM_TS * diq;
"""
    else:
        code += "    const float ic_d = i_d, ic_q = i_q;\n"
    if d.decoupling:
        code += """    const float ff_d = ((-omega_e) * PMSM_L_Q) * ic_q;   /* decoupling feed-forward */
    const float ff_q = omega_e * (PMSM_L_D * ic_d + PMSM_PSI_F);
"""
    else:
        code += "    const float ff_d = 0.0f, ff_q = 0.0f;\n"
    code += """    const float e_d = id_ref - ic_d, e_q = iq_ref - ic_q;
    const float v_d = (PMSM_KP_D * e_d + c->current_integral_d) + ff_d;
    const float v_q = (PMSM_KP_Q * e_q + c->current_integral_q) + ff_q;
    const float v_sq = v_d * v_d + v_q * v_q;
    float scale = 1.0f;
    if (v_sq > 0.0f) {
        const float norm = sqrtf(v_sq);
        if (norm > u_max) scale = u_max / norm;
    }
    const float u_d = v_d * scale, u_q = v_q * scale;
    c->current_integral_d = (c->current_integral_d + (PMSM_TS * PMSM_KI_D) * e_d) + 1.0f * (u_d - v_d);
    c->current_integral_q = (c->current_integral_q + (PMSM_TS * PMSM_KI_Q) * e_q) + 1.0f * (u_q - v_q);
    c->u_d_prev = u_d;
    c->u_q_prev = u_q;
    const float lead = in->theta_e + omega_e * PMSM_ANGLE_LEAD;   /* angle advance */
    const float cos_l = cosf(lead), sin_l = sinf(lead);
    float u_alpha = u_d * cos_l - u_q * sin_l;
    float u_beta = u_d * sin_l + u_q * cos_l;
"""
    return code


def dead_time_block(d: ControllerDescription) -> str:
    """Step 4, dead-time compensation (``dead_time_compensation.DeadTimeCompensation``): each phase's
    current sign predicted at the middle of the period the command is applied in, smoothed
    ``tanh(i / i_eps)``, the legs' predicted error at duty 0.5 added back (common mode dropped)."""
    if not d.dead_time_compensation:
        return ""
    if d.dead_time_current_source == "reference":
        source = "        const float s_d = id_ref, s_q = iq_ref;   /* the current reference */\n"
    else:
        source = "        const float s_d = i_d, s_q = i_q;   /* the measured current */\n"
    return (
        "    {   /* dead-time compensation (Murai et al. 1987): add the predicted leg error back */\n"
        + source
        + """        const float ahead = in->theta_e + (omega_e * PMSM_DT_AHEAD_PERIODS) * PMSM_TS;
        const float ca = cosf(ahead), sa = sinf(ahead);
        const float a = s_d * ca - s_q * sa;
        const float b = s_d * sa + s_q * ca;
        const float i_ph[3] = {
            a + 0.0f,
            (-0.5f * a + PMSM_HALF_SQRT3 * b) + 0.0f,
            (-0.5f * a - PMSM_HALF_SQRT3 * b) + 0.0f,
        };
        const float window = PMSM_DT_DEAD_TIME < 0.5f * PMSM_TS ? PMSM_DT_DEAD_TIME : 0.5f * PMSM_TS;
        float err[3];
        for (int k = 0; k < 3; ++k) {
            const float s = tanhf(i_ph[k] / PMSM_DT_SIGN_CURRENT);
            const float dead = (0.5f * (1.0f + s)) * window - (0.5f * (1.0f - s)) * window;
            err[k] = (-(in->u_dc / PMSM_TS)) * dead - PMSM_DT_DROP * s;
        }
        u_alpha = u_alpha + (-((2.0f * err[0] - err[1] - err[2]) / 3.0f));
        u_beta = u_beta + (-((err[1] - err[2]) / PMSM_SQRT3));
    }
"""
    )


def svpwm_block() -> str:
    """The book's SVPWM (``svpwm.switching_times`` at ``Ts = 1``, ch. 2): sector code
    ``N = [U1>0] + 2[U2>0] + 4[U3>0]``, dwell times from X, Y, Z, over-modulation scaled to the period,
    the 7-segment centre-aligned sequence; duty ``1 - 2 T_cm``."""
    return """    {   /* SVPWM (book ch. 2), times in periods */
        const float k = PMSM_SQRT3 / in->u_dc;
        const float X = k * u_beta;
        const float Y = k * (PMSM_HALF_SQRT3 * u_alpha + 0.5f * u_beta);
        const float Z = k * (-PMSM_HALF_SQRT3 * u_alpha + 0.5f * u_beta);
        const float U2 = 0.5f * (PMSM_SQRT3 * u_alpha - u_beta);
        const float U3 = 0.5f * (-PMSM_SQRT3 * u_alpha - u_beta);
        const int N = (u_beta > 0.0f) + 2 * (U2 > 0.0f) + 4 * (U3 > 0.0f);
        const float cand[6] = {X, Y, Z, -X, -Y, -Z};
        static const unsigned char dwell[8][2] = {
            {0, 1}, {2, 1}, {1, 3}, {5, 0}, {3, 2}, {0, 4}, {4, 5}, {0, 1}};
        static const unsigned char leg[8][3] = {
            {0, 1, 2}, {1, 0, 2}, {0, 2, 1}, {0, 1, 2}, {2, 1, 0}, {2, 0, 1}, {1, 2, 0}, {0, 1, 2}};
        float T1 = cand[dwell[N][0]], T2 = cand[dwell[N][1]];
        const float total = T1 + T2;
        if (total > 1.0f) {   /* over-modulation: scale to the period, keep the direction */
            const float s = 1.0f / total;
            T1 = T1 * s;
            T2 = T2 * s;
        }
        float T[3];
        T[0] = 0.25f * ((1.0f - T1) - T2);
        T[1] = T[0] + 0.5f * T1;
        T[2] = T[1] + 0.5f * T2;
        out->d_a = 1.0f - 2.0f * T[leg[N][0]];
        out->d_b = 1.0f - 2.0f * T[leg[N][1]];
        out->d_c = 1.0f - 2.0f * T[leg[N][2]];
    }
"""
