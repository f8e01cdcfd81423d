"""A heat-run log of an imperfect drive made without this project's engine: a warm motor, faulty current
sensors and a turned encoder, recorded in bursts, so that the identification of temperature coefficients,
a thermal network and sensor errors is tested on data the code under test did not make.

**The run.** A dynamometer holds the speed while the drive's current loop follows a periodic pattern of
d- and q-current steps around an operating level; the level is high for the heating part of the run and
low for the cooling part. Every ``capture_every_s`` a capture of one pattern period is recorded (a
re-triggered scope or a firmware datalog buffer: the rows between captures are not in the log), at a
speed that alternates between two values from capture to capture.

**The physics** (the motor of ``MOTOR``):

- dq machine with ``R(T) = R (1 + alpha (T - T_ref))`` and ``psi_f(T) = psi_f (1 + beta (T - T_ref))``
  (one temperature: the magnet at the winding's), the stator-frame voltage held over each control period
  (an averaged inverter) and turned into dq at the rotor angle of each instant;
- one thermal node, ``C_th dT/dt = 1.5 R(T) |i_dq|^2 - (T - T_amb) / R_th`` (amplitude-invariant dq
  currents), integrated with the currents inside a capture, and between captures with the loss of the
  pattern held (its mean ``|i_dq|^2`` over the capture at that level: the pattern repeats between
  captures);
- an inverter that loses ``V_dt sign(i_x)`` on each phase (dead time), at the sign of the phase current at
  the start of each control period, held with the commanded voltage over the period;
- sensors: ``m_k = g_k i_k + o_k + noise`` on phases a and b (the firmware computes ``i_c = -i_a - i_b``),
  the measured angle ``theta_e + delta``, a winding-temperature sensor with white noise.

The current PI (400 Hz bandwidth, back-EMF and cross-coupling feed-forward from the cold nameplate values)
reads the faulty sensors and turns them with the faulty angle, as firmware does. Each capture starts after
one pattern period of warm-up, so the loop and the currents are in their periodic steady state.

**Ripple** (``ripple=RIPPLE``): the motor also has magnet flux harmonics, whose back-EMF is the derivative
of the Clarke transform of the three phase fluxes ``A cos(k (theta_e - s_x) + phi)`` (``harmonic_flux``),
each capture starts at a random angle, and a torque sensor between the motor and the dynamometer logs the
shaft torque ``T_L`` (``shaft_torque``: the electromagnetic torque with the harmonics' part from the power
balance, cogging ``C sin(n theta_e + phi)``, less viscous and Coulomb friction, with white noise).

**Integrators.** SciPy's ``solve_ivp``: DOP853 for the electrical and thermal states of all captures at
once (one control period per call), LSODA for the thermal node between captures. The loss held between
captures is that of the capture at the same level; it is found by two passes (the captures at the
temperatures of the first pass give the losses of the second).
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

__all__ = [
    "DEAD_TIME_V", "MOTOR", "SENSORS", "THERMAL", "RIPPLE", "heat_run_log", "true_values", "harmonic_flux",
    "shaft_torque",
]  # fmt: skip

#: The motor at its reference temperature (ohm, H, H, Wb, pole pairs; degC and 1/K for the coefficients).
MOTOR = {
    "R": 0.5,
    "L_d": 2.0e-3,
    "L_q": 3.0e-3,
    "psi_f": 0.08,
    "pole_pairs": 4,
    "reference_temperature_c": 20.0,
    "r_temp_coeff_per_k": 0.00393,
    "psi_f_temp_coeff_per_k": -0.0011,
}
#: The winding's thermal node: K/W, J/K, degC.
THERMAL = {"r_th_k_per_w": 1.0, "c_th_j_per_k": 300.0, "ambient_c": 25.0}
#: Sensor errors: offsets (A) and gains of the sensors on phases a and b, encoder offset (electrical rad).
SENSORS = {"current_offset_a": (0.08, -0.05), "current_gain": (0.99, 1.005), "encoder_offset_rad": 0.12}
#: The inverter's error voltage per phase, V (dead time x switching frequency x DC-link voltage: 1 us at
#: 10 kHz on 50 V).
DEAD_TIME_V = 0.5
#: Magnet flux harmonics and cogging torque for ``heat_run_log(ripple=RIPPLE)``: ``flux`` rows ``(order,
#: Wb, rad)`` of ``psi_h,x = A cos(k (theta_e - s_x) + phi)`` on phase ``x`` (axis ``s_x``), ``cogging`` rows
#: ``(order, N m, rad)`` of ``T_cog = C sin(n theta_e + phi)``; the motor's friction ``B`` (N m s/rad) and
#: Coulomb torque (N m) and the torque sensor's noise (N m) of the logged shaft torque.
RIPPLE = {
    "flux": ((5, 0.0016, 0.7), (7, 0.0008, -1.9)),
    "cogging": ((6, 0.15, 0.4), (12, 0.05, -2.2)),
    "B": 2e-4,
    "coulomb_nm": 0.01,
    "torque_noise_nm": 0.01,
}
#: The current pattern of one period, (i_d, i_q) in A per step, at the heating level.
PATTERN_A = ((0.0, 9.0), (-3.0, 8.0), (0.0, -9.0), (2.0, 8.0), (-2.5, -8.0))
_TWO_PI_3 = 2.0 * math.pi / 3.0


def true_values() -> dict:
    """Every value the log was made with: ``{"motor", "thermal", "sensors", "V_dt"}``."""
    return {"motor": dict(MOTOR), "thermal": dict(THERMAL), "sensors": dict(SENSORS), "V_dt": DEAD_TIME_V}


def _resistance(T):
    return MOTOR["R"] * (1.0 + MOTOR["r_temp_coeff_per_k"] * (T - MOTOR["reference_temperature_c"]))


def _flux(T):
    return MOTOR["psi_f"] * (1.0 + MOTOR["psi_f_temp_coeff_per_k"] * (T - MOTOR["reference_temperature_c"]))


def harmonic_flux(theta, flux_rows) -> tuple[np.ndarray, np.ndarray]:
    """``(psi_h,ab, d psi_h,ab / d theta)``: the complex alpha-beta harmonic flux (Wb) of the phase fluxes
    ``A cos(k (theta - s_x) + phi)`` (amplitude-invariant Clarke of the three phases) and its derivative
    by the electrical angle ``theta`` (rad), Wb/rad."""
    psi = [np.zeros_like(theta) for _ in range(3)]
    dpsi = [np.zeros_like(theta) for _ in range(3)]
    for k, a, phi in flux_rows:
        for x in range(3):
            arg = k * (theta - x * _TWO_PI_3) + phi
            psi[x] = psi[x] + a * np.cos(arg)
            dpsi[x] = dpsi[x] - a * k * np.sin(arg)
    clarke = lambda v: (2.0 * v[0] - v[1] - v[2]) / 3.0 + 1j * (v[1] - v[2]) / math.sqrt(3.0)
    return clarke(psi), clarke(dpsi)


def _capture_rhs(w_e, u_ab, flux_rows=()):
    """The rhs of every capture's ``(i_d, i_q, theta_e, T)`` with the held stator voltages ``u_ab`` (and the
    back-EMF of the flux harmonics ``flux_rows``, turned into dq at the instant's angle)."""
    L_d, L_q, c_th, r_th, t_amb = (
        MOTOR["L_d"], MOTOR["L_q"], THERMAL["c_th_j_per_k"], THERMAL["r_th_k_per_w"], THERMAL["ambient_c"],
    )  # fmt: skip

    def rhs(_t, flat):
        i_d, i_q, th, T = flat.reshape(4, -1)
        c, s = np.cos(th), np.sin(th)
        u_d, u_q = c * u_ab[0] + s * u_ab[1], -s * u_ab[0] + c * u_ab[1]
        if flux_rows:
            e_h = w_e * harmonic_flux(th, flux_rows)[1] * (c - 1j * s)
            u_d, u_q = u_d - e_h.real, u_q - e_h.imag
        R = _resistance(T)
        di_d = (u_d - R * i_d + w_e * L_q * i_q) / L_d
        di_q = (u_q - R * i_q - w_e * (L_d * i_d + _flux(T))) / L_q
        dT = (1.5 * R * (i_d**2 + i_q**2) - (T - t_amb) / r_th) / c_th
        return np.concatenate([di_d, di_q, w_e, dT])

    return rhs


def shaft_torque(i_d, i_q, th, T, omega_m, ripple) -> np.ndarray:
    """The torque a sensor between the motor and the dynamometer reads at a held speed, N m: the
    electromagnetic torque (``1.5 p (psi_f(T) i_q + (L_d - L_q) i_d i_q)`` and the flux harmonics'
    ``1.5 p Re(conj(i_ab) d psi_h,ab / d theta)``, from the power balance) plus cogging, less friction."""
    p = MOTOR["pole_pairs"]
    torque = 1.5 * p * (_flux(T) * i_q + (MOTOR["L_d"] - MOTOR["L_q"]) * i_d * i_q)
    i_ab = (i_d + 1j * i_q) * np.exp(1j * th)
    torque = torque + 1.5 * p * np.real(np.conj(i_ab) * harmonic_flux(th, ripple["flux"])[1])
    for n, c, phi in ripple["cogging"]:
        torque = torque + c * np.sin(n * th + phi)
    return torque - ripple["B"] * omega_m - ripple["coulomb_nm"] * np.sign(omega_m)


def _captures(t0, T0, speeds, levels, ts, rows, rng, ripple=None):
    """Simulate every capture (a warm-up period, then ``rows`` logged rows); returns the logged columns
    ``(n, rows)`` and each capture's mean true ``|i_dq|^2``, A^2."""
    n = t0.size
    p = MOTOR["pole_pairs"]
    w_e = p * speeds
    gain, offset = np.asarray(SENSORS["current_gain"]), np.asarray(SENSORS["current_offset_a"])
    delta = SENSORS["encoder_offset_rad"]
    bw = 2.0 * math.pi * 400.0
    steps = len(PATTERN_A)
    period = rows - 1
    th0 = np.full(n, 0.3) if ripple is None else rng.uniform(-math.pi, math.pi, n)
    flux_rows = () if ripple is None else ripple["flux"]
    x = np.stack([np.zeros(n), np.zeros(n), th0, T0])
    integ = np.zeros((2, n))
    names = ("u_alpha", "u_beta", "i_a", "i_b", "theta_e", "temperature_c", "i_sq_true")
    names += () if ripple is None else ("T_L",)
    log = {k: np.zeros((n, rows)) for k in names}
    for j in range(period + rows):
        i_d, i_q, th, T = x
        ph = [th - q * _TWO_PI_3 for q in range(3)]
        i_abc = np.stack([np.cos(a) * i_d - np.sin(a) * i_q for a in ph])
        i_true = i_abc[:2]
        m = gain[:, None] * i_true + offset[:, None] + 0.01 * rng.standard_normal((2, n))
        th_m = th + delta
        i_al, i_be = m[0], (m[0] + 2.0 * m[1]) / math.sqrt(3.0)
        c, s = np.cos(th_m), np.sin(th_m)
        md, mq = c * i_al + s * i_be, -s * i_al + c * i_be
        ref = np.asarray(PATTERN_A[(j % period) * steps // period], float)[:, None] * levels[None, :]
        e = ref - np.stack([md, mq])
        integ += MOTOR["R"] * bw * ts * e
        u_d = MOTOR["L_d"] * bw * e[0] + integ[0] - w_e * MOTOR["L_q"] * mq
        u_q = MOTOR["L_q"] * bw * e[1] + integ[1] + w_e * (MOTOR["L_d"] * md + MOTOR["psi_f"])
        u_ab = np.stack([c * u_d - s * u_q, s * u_d + c * u_q])
        sgn = np.sign(i_abc)
        lost = DEAD_TIME_V * np.stack(
            [(2 * sgn[0] - sgn[1] - sgn[2]) / 3, (sgn[1] - sgn[2]) / math.sqrt(3.0)]
        )
        k = j - period
        if k >= 0:
            log["u_alpha"][:, k], log["u_beta"][:, k] = u_ab
            log["i_a"][:, k], log["i_b"][:, k] = m
            log["theta_e"][:, k] = np.remainder(th_m + math.pi, 2.0 * math.pi) - math.pi
            log["temperature_c"][:, k] = T + 0.2 * rng.standard_normal(n)
            log["i_sq_true"][:, k] = i_d**2 + i_q**2
            if ripple is not None:
                noise = ripple["torque_noise_nm"] * rng.standard_normal(n)
                log["T_L"][:, k] = shaft_torque(i_d, i_q, th, T, speeds, ripple) + noise
        if j < period + rows - 1:
            sol = solve_ivp(_capture_rhs(w_e, u_ab - lost, flux_rows), (0.0, ts), x.ravel(), method="DOP853",
                            rtol=1e-10, atol=1e-12)  # fmt: skip
            x = sol.y[:, -1].reshape(4, n)
    return log, log["i_sq_true"][:, :-1].mean(axis=1)


def _temperatures(t_caps, i_sq, t_end):
    """Winding temperature at ``t_caps`` with each capture's loss held until the next (LSODA), degC."""
    r_th, c_th, t_amb = THERMAL["r_th_k_per_w"], THERMAL["c_th_j_per_k"], THERMAL["ambient_c"]

    def rhs(t, T):
        s = min(max(int(np.searchsorted(t_caps, t, side="right")) - 1, 0), t_caps.size - 1)
        return [(1.5 * _resistance(T[0]) * i_sq[s] - (T[0] - t_amb) / r_th) / c_th]

    grid = np.concatenate([t_caps, [t_end]])
    sol = solve_ivp(rhs, (0.0, t_end), [t_amb], method="LSODA", t_eval=grid, rtol=1e-10, atol=1e-10,
                    max_step=float(np.min(np.diff(grid))) / 2.0)  # fmt: skip
    return sol.y[0, :-1]


def heat_run_log(
    duration_s: float = 1500.0,
    heating_s: float = 900.0,
    capture_every_s: float = 30.0,
    capture_s: float = 0.05,
    ts: float = 1e-4,
    speeds_rad_s: tuple = (60.0, 120.0),
    cooling_level: float = 0.35,
    seed: int = 0,
    ripple: dict | None = None,
) -> dict:
    """Columns of a heat-run log recorded in bursts (module docstring).

    Args:
        duration_s: Length of the run, s. heating_s: The run's heating part, s (the pattern at full level).
        capture_every_s: Time between capture starts, s. capture_s: Length of a capture (one pattern
            period), s. ts: Control and sampling period, s.
        speeds_rad_s: The two mechanical speeds the captures alternate between, rad/s.
        cooling_level: The pattern's scale after ``heating_s``.
        seed: Noise seed.
        ripple: None, or magnet flux harmonics and cogging (as ``RIPPLE``): the motor then has them,
            each capture starts at a random angle, and the log gets the shaft torque ``T_L`` that a torque
            sensor between the motor and the dynamometer reads (``shaft_torque`` with the sensor's
            noise).

    Returns:
        ``{column: (N,) array}``: ``time`` (s, with gaps between captures), ``u_alpha``, ``u_beta`` (V, held
        from a row to the next), ``i_a``, ``i_b`` (A, as the sensors read them), ``theta_e`` (measured,
        rad), ``omega_m`` (rad/s), ``temperature_c`` (measured winding temperature, degC); with ``ripple``
        also ``T_L`` (the measured shaft torque, N m).
    """
    rows = round(capture_s / ts) + 1
    t_caps = np.arange(0.0, duration_s - capture_s, capture_every_s) + capture_s  # after a warm-up period
    n = t_caps.size
    speeds = np.asarray(speeds_rad_s, float)[np.arange(n) % 2]
    levels = np.where(t_caps < heating_s, 1.0, cooling_level)
    i_sq = np.mean(np.sum(np.square(PATTERN_A), axis=1)) * levels**2  # first pass: the references
    for _ in range(2):
        T0 = _temperatures(t_caps - capture_s, i_sq, duration_s)
        rng = np.random.default_rng(seed)
        log, i_sq = _captures(t_caps - capture_s, T0, speeds, levels, ts, rows, rng, ripple)
    time = t_caps[:, None] + ts * np.arange(rows)[None, :]
    out = {"time": time.ravel(), "omega_m": np.repeat(speeds, rows)}
    out.update({k: v.ravel() for k, v in log.items() if k != "i_sq_true"})
    return out
