"""A drive log made without this project's engine: the closed loop of a field-oriented drive written in
NumPy, its motor integrated by SciPy's adaptive Dormand-Prince 8(5,3) (``solve_ivp``, DOP853), so that
identification and the commissioning chain are tested on data the code under test did not make.

The drive (the book, ch. 1 and 3, built independently of [`pmsmjax.controllers`][pmsmjax.controllers]):

- speed PI with active damping at bandwidth ``beta`` (``Kp = beta J / k_t``, ``Ki = beta Kp``,
  ``B_a = (beta J - B) / k_t``), the integrator clamped while the current limit is active (conditional
  integration, where the project's speed PI uses a realisable-reference anti-windup);
- i_d reference: a PRBS ([`tuning.identify.excitation.prbs`][tuning.identify.excitation.prbs]) so that L_d is
  excited; i_q limited to ``sqrt(I_max^2 - i_d^2)``;
- dq current PIs with the internal-model gains at bandwidth ``a_c`` (``Kp = a_c L``, ``Ki = a_c R``) and
  back-EMF/cross-coupling feed-forward, the voltage clamped to the SVPWM circle ``U_dc / sqrt 3``;
- one control period of computation delay with the angle advanced by 1.5 periods, the voltage held in the
  stator frame over each period (an averaged inverter);
- the motor: dq equations with the stator-frame voltage turned into dq at the rotor angle of each instant.

Each row ``k`` of the log is what firmware records (the layout of
[`pmsmjax.recorded.synthetic_logs.LOG_COLUMNS`][pmsmjax.recorded.synthetic_logs.LOG_COLUMNS] ``["dq"]``): the
time ``t_k``, the held stator voltage of ``[t_k, t_k+1)`` turned into dq with the angle at ``t_k``, the
currents, speed and angle sampled at ``t_k``, and the load torque.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from tuning.identify.excitation import prbs

__all__ = ["reference_drive_log", "identification_speeds_rpm", "commissioning_log", "PRBS_SHARE"]

#: The speed staircase of the identification run, as shares of the rated speed (several constant speeds,
#: accelerations both ways and a reversal: J, B and a load separate;
#: [`tuning.identify.excitation`][tuning.identify.excitation]).
SPEED_SHARES = (0.4, 0.9, 0.15, 0.7, -0.3, 0.5, 0.85, 0.25)


#: PRBS amplitude on i_d as a share of the drive's maximum current.
PRBS_SHARE = 0.2


def identification_speeds_rpm(rated_speed_rpm: float) -> tuple[float, ...]:
    """The staircase's speed levels, r/min (`SPEED_SHARES` of ``rated_speed_rpm``)."""
    return tuple(share * rated_speed_rpm for share in SPEED_SHARES)


def reference_drive_log(
    motor: dict,
    *,
    u_dc_v: float,
    Ts: float,
    max_current_a: float,
    current_bandwidth_rad_s: float,
    speed_bandwidth_rad_s: float,
    speeds_rpm,
    duration_s: float,
    id_amplitude_a: float,
    prbs_clock_s: float = 0.01,
    load_nm: float = 0.0,
    seed: int = 1,
    rtol: float = 1e-9,
) -> dict[str, np.ndarray]:
    """Noise-free dq log of the reference drive (module docstring) on ``motor`` (SI dict: ``R, L_d, L_q,
    psi_f, pole_pairs, J, B``) following the speed staircase ``speeds_rpm`` (equal shares of
    ``duration_s``), a PRBS of ``id_amplitude_a`` A on i_d with bit length ``prbs_clock_s``, and a constant
    ``load_nm``. Columns: ``time`` s, ``u_d, u_q`` V, ``i_d, i_q`` A, ``omega_m`` rad/s, ``theta_e`` rad,
    ``T_L`` N m, each ``(N,)`` with ``N = duration_s / Ts``."""
    R, L_d, L_q, psi = (float(motor[k]) for k in ("R", "L_d", "L_q", "psi_f"))
    J, B, p = float(motor["J"]), float(motor["B"]), int(motor["pole_pairs"])
    n = int(round(duration_s / Ts))
    speeds = np.asarray(speeds_rpm, dtype=float) * math.pi / 30.0
    levels = prbs(max(1, math.ceil(duration_s / prbs_clock_s)), seed=seed)
    k_t = 1.5 * p * psi
    kp_w, b_a = speed_bandwidth_rad_s * J / k_t, (speed_bandwidth_rad_s * J - B) / k_t
    ki_w = speed_bandwidth_rad_s * kp_w
    a_c = current_bandwidth_rad_s
    u_max = u_dc_v / math.sqrt(3.0)

    def field(t, x, u_alpha, u_beta):
        i_d, i_q, w_m, th = x
        c, s = math.cos(th), math.sin(th)
        u_d, u_q = u_alpha * c + u_beta * s, -u_alpha * s + u_beta * c
        w_e = p * w_m
        torque = 1.5 * p * (psi * i_q + (L_d - L_q) * i_d * i_q)
        return (
            (u_d - R * i_d + w_e * L_q * i_q) / L_d,
            (u_q - R * i_q - w_e * (L_d * i_d + psi)) / L_q,
            (torque - B * w_m - load_nm) / J,
            w_e,
        )

    x = np.zeros(4)
    speed_integral = 0.0
    current_integral = np.zeros(2)
    pending = np.zeros(2)  # the stator voltage computed last period, applied this period
    rows = np.empty((n, 8))
    for k in range(n):
        t = k * Ts
        i_d, i_q, w_m, th = x
        w_ref = speeds[min(int(t / duration_s * speeds.size), speeds.size - 1)]
        i_d_ref = id_amplitude_a * levels[min(int(t / prbs_clock_s), levels.size - 1)]
        # speed PI with active damping; integration stops while the limit is active
        i_q_max = math.sqrt(max(max_current_a**2 - i_d_ref**2, 0.0))
        error_w = w_ref - w_m
        i_q_ref = kp_w * error_w + speed_integral - b_a * w_m
        if abs(i_q_ref) < i_q_max:
            speed_integral += ki_w * Ts * error_w
        i_q_ref = min(max(i_q_ref, -i_q_max), i_q_max)
        # current PIs with feed-forward; the voltage clamped to the SVPWM circle
        w_e = p * w_m
        error_i = np.array([i_d_ref - i_d, i_q_ref - i_q])
        feed = np.array([-w_e * L_q * i_q, w_e * (L_d * i_d + psi)])
        u_dq = a_c * np.array([L_d, L_q]) * error_i + current_integral + feed
        magnitude = math.hypot(*u_dq)
        if magnitude > u_max:
            u_dq *= u_max / magnitude
        else:
            current_integral += a_c * np.array([R, R]) * Ts * error_i
        # applied next period: advance the angle by 1.5 periods (delay and hold)
        angle = th + 1.5 * w_e * Ts
        c, s = math.cos(angle), math.sin(angle)
        command = np.array([u_dq[0] * c - u_dq[1] * s, u_dq[0] * s + u_dq[1] * c])
        u_alpha, u_beta = pending
        c, s = math.cos(th), math.sin(th)
        rows[k] = (t, u_alpha * c + u_beta * s, -u_alpha * s + u_beta * c, i_d, i_q, w_m, th, load_nm)
        solution = solve_ivp(
            field, (t, t + Ts), x, method="DOP853", rtol=rtol, atol=1e-12, args=(u_alpha, u_beta)
        )
        x = solution.y[:, -1]
        pending = command
    names = ("time", "u_d", "u_q", "i_d", "i_q", "omega_m", "theta_e", "T_L")
    return {name: rows[:, j].copy() for j, name in enumerate(names)}


def commissioning_log(spec, duration_s: float, prbs_clock_s: float, noise=None, seed: int = 0) -> dict:
    """The identification log of drive file ``spec``
    ([`pmsmjax.spec.drive_spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]): the reference drive at the
    file's DC link, control rate, current limit and design-rule bandwidths, the staircase of
    [`identification_speeds_rpm`][tuning.identify.reference_log.identification_speeds_rpm], a PRBS of
    [`PRBS_SHARE`][tuning.identify.reference_log.PRBS_SHARE] x the maximum current on i_d; ``noise`` (default
    [`pmsmjax.recorded.synthetic_logs.ID_LOG_NOISE`][pmsmjax.recorded.synthetic_logs.ID_LOG_NOISE]: 1 % on the
    currents, 0.5 % on the voltages) drawn with ``seed``."""
    from pmsmjax.recorded.synthetic_logs import ID_LOG_NOISE, add_measurement_noise

    log = reference_drive_log(
        spec.motor,
        u_dc_v=spec.u_dc_v,
        Ts=spec.Ts,
        max_current_a=spec.current_limit_a,
        current_bandwidth_rad_s=spec.control["current_bandwidth_rad_s"],
        speed_bandwidth_rad_s=spec.control["speed_bandwidth_rad_s"],
        speeds_rpm=identification_speeds_rpm(spec.ratings["rated_speed_rpm"]),
        duration_s=duration_s,
        id_amplitude_a=PRBS_SHARE * spec.current_limit_a,
        prbs_clock_s=prbs_clock_s,
    )
    return add_measurement_noise(log, ID_LOG_NOISE if noise is None else noise, seed)
