"""A log of speed steps on a compliant shaft, made without this project's engine, for the two-mass
identification (``pmsmjax identify --two-mass``).

**The run.** The motor of [`tuning.identify.heat_run_log`][tuning.identify.heat_run_log] (warm: the winding
starts at ``start_c``, R and psi_f follow it), with its faulty current sensors, turned encoder and dead
time, drives a load inertia through a torsional spring and damper. A speed PI (on the motor speed as the
encoder measures it, limited to ``I_MAX_A``) follows steps of the speed reference, and the d current steps
through a pattern so that the stator-frame fit separates the encoder offset; the current PI and its
feed-forward are those of the heat run. The torque steps at the ends of the current limit ring the shaft.

**The physics**: the heat run's dq machine and thermal node, and

- ``J_m dw_m/dt = T_e - B w_m - T_s``, ``J_L dw_L/dt = T_s``, ``dphi/dt = w_m - w_L``,
  ``T_s = K phi + D (w_m - w_L)`` (``SHAFT``), ``T_e = 1.5 p (psi_f(T) i_q + (L_d - L_q) i_d i_q)``;
- the logged speed: the motor's, with white noise ``SPEED_NOISE_RAD_S`` (an encoder's speed estimate).

**Integrator.** SciPy's ``solve_ivp`` (DOP853) over each control period with the stator voltage held.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from tuning.identify.heat_run_log import DEAD_TIME_V, MOTOR, SENSORS, THERMAL, _flux, _resistance

__all__ = ["SHAFT", "I_MAX_A", "SPEED_NOISE_RAD_S", "shaft_log", "resonance_hz"]

#: The mechanics: motor inertia J_m (kg m^2), viscous friction B (N m s/rad), load inertia J_L (kg m^2),
#: shaft stiffness K (N m/rad) and damping D (N m s/rad).
SHAFT = {"J_m": 5e-4, "B": 2e-4, "J_L": 1e-3, "K": 300.0, "D": 0.02}
#: The speed PI's current limit, A.
I_MAX_A = 9.0
#: White noise on the logged motor speed, rad/s.
SPEED_NOISE_RAD_S = 0.05
_TWO_PI_3 = 2.0 * math.pi / 3.0
#: The speed reference's steps, rad/s, and the d-current pattern, A.
STEPS_RAD_S = (40.0, 90.0, -30.0, 60.0, -70.0, 10.0)
ID_PATTERN_A = (0.0, -3.0, 2.0, -1.5)


def resonance_hz(shaft: dict = SHAFT) -> float:
    """The undamped shaft's resonance seen from the motor torque, Hz."""
    j_m, j_l, k = shaft["J_m"], shaft["J_L"], shaft["K"]
    return math.sqrt(k * (j_m + j_l) / (j_m * j_l)) / (2.0 * math.pi)


def _rhs(u_ab):
    L_d, L_q, p = MOTOR["L_d"], MOTOR["L_q"], MOTOR["pole_pairs"]
    c_th, r_th, t_amb = THERMAL["c_th_j_per_k"], THERMAL["r_th_k_per_w"], THERMAL["ambient_c"]
    j_m, b, j_l, k, d = (SHAFT[n] for n in ("J_m", "B", "J_L", "K", "D"))

    def rhs(_t, x):
        i_d, i_q, th, T, w_m, phi, w_l = x
        c, s = math.cos(th), math.sin(th)
        u_d, u_q = c * u_ab[0] + s * u_ab[1], -s * u_ab[0] + c * u_ab[1]
        w_e = p * w_m
        R = _resistance(T)
        di_d = (u_d - R * i_d + w_e * L_q * i_q) / L_d
        di_q = (u_q - R * i_q - w_e * (L_d * i_d + _flux(T))) / L_q
        dT = (1.5 * R * (i_d**2 + i_q**2) - (T - t_amb) / r_th) / c_th
        t_e = 1.5 * p * (_flux(T) * i_q + (L_d - L_q) * i_d * i_q)
        t_s = k * phi + d * (w_m - w_l)
        return [di_d, di_q, w_e, dT, (t_e - b * w_m - t_s) / j_m, w_m - w_l, t_s / j_l]

    return rhs


def shaft_log(step_s: float = 0.15, ts: float = 1e-4, start_c: float = 60.0, bandwidth_hz: float = 15.0,
              seed: int = 0) -> dict:  # fmt: skip
    """Columns of the speed-step run (module docstring).

    Args:
        step_s: Time per speed step, s (the d-current pattern steps four times as often).
        ts: Control and sampling period, s.
        start_c: The winding's temperature at the start, degC.
        bandwidth_hz: The speed loop's crossover, Hz.
        seed: Noise seed.

    Returns:
        ``{column: (N,) array}``: ``time`` (s), ``u_alpha``, ``u_beta`` (V, held from a row to the next),
        ``i_a``, ``i_b`` (A, as the sensors read them), ``theta_e`` (measured, rad), ``omega_m`` (measured
        motor speed, rad/s), ``temperature_c`` (degC, with 0.2 K noise).
    """
    rng = np.random.default_rng(seed)
    p = MOTOR["pole_pairs"]
    gain, offset = np.asarray(SENSORS["current_gain"]), np.asarray(SENSORS["current_offset_a"])
    delta = SENSORS["encoder_offset_rad"]
    bw = 2.0 * math.pi * 400.0
    w_c = 2.0 * math.pi * bandwidth_hz
    k_t = 1.5 * p * MOTOR["psi_f"]
    kp = (SHAFT["J_m"] + SHAFT["J_L"]) * w_c / k_t
    ki = kp * w_c / 4.0
    per_step = round(step_s / ts)
    n = per_step * len(STEPS_RAD_S) + 1
    x = np.array([0.0, 0.0, 0.3, start_c, 0.0, 0.0, 0.0])
    integ, speed_integ = np.zeros(2), 0.0
    names = ("u_alpha", "u_beta", "i_a", "i_b", "theta_e", "omega_m", "temperature_c")
    log = {k: np.zeros(n) for k in names}
    for j in range(n):
        i_d, i_q, th, T, w_m = x[:5]
        i_abc = np.array(
            [math.cos(th - q * _TWO_PI_3) * i_d - math.sin(th - q * _TWO_PI_3) * i_q for q in range(3)]
        )
        m = gain * i_abc[:2] + offset + 0.01 * rng.standard_normal(2)
        th_m = th + delta
        w_meas = w_m + SPEED_NOISE_RAD_S * rng.standard_normal()
        i_al, i_be = m[0], (m[0] + 2.0 * m[1]) / math.sqrt(3.0)
        c, s = math.cos(th_m), math.sin(th_m)
        md, mq = c * i_al + s * i_be, -s * i_al + c * i_be
        e_w = STEPS_RAD_S[min(j // per_step, len(STEPS_RAD_S) - 1)] - w_meas
        iq_ref = kp * e_w + speed_integ
        if abs(iq_ref) < I_MAX_A:
            speed_integ += ki * ts * e_w
        iq_ref = min(max(iq_ref, -I_MAX_A), I_MAX_A)
        id_ref = ID_PATTERN_A[(4 * j // per_step) % len(ID_PATTERN_A)]
        e = np.array([id_ref - md, iq_ref - mq])
        integ += MOTOR["R"] * bw * ts * e
        w_e = p * w_meas
        u_d = MOTOR["L_d"] * bw * e[0] + integ[0] - w_e * MOTOR["L_q"] * mq
        u_q = MOTOR["L_q"] * bw * e[1] + integ[1] + w_e * (MOTOR["L_d"] * md + MOTOR["psi_f"])
        u_ab = np.array([c * u_d - s * u_q, s * u_d + c * u_q])
        sgn = np.sign(i_abc)
        lost = DEAD_TIME_V * np.array(
            [(2 * sgn[0] - sgn[1] - sgn[2]) / 3, (sgn[1] - sgn[2]) / math.sqrt(3.0)]
        )
        log["u_alpha"][j], log["u_beta"][j] = u_ab
        log["i_a"][j], log["i_b"][j] = m
        log["theta_e"][j] = math.remainder(th_m, 2.0 * math.pi)
        log["omega_m"][j] = w_meas
        log["temperature_c"][j] = T + 0.2 * rng.standard_normal()
        if j < n - 1:
            sol = solve_ivp(_rhs(u_ab - lost), (0.0, ts), x, method="DOP853", rtol=1e-10, atol=1e-12)
            x = sol.y[:, -1]
    log["time"] = ts * np.arange(n)
    return log
