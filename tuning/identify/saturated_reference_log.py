"""A flux-map identification log made without this project's engine: a saturated PMSM (an analytic
co-energy model with cross-saturation) integrated by SciPy's ``solve_ivp`` (DOP853, current as state)
under a current controller written in NumPy, at a constant speed held by a dynamometer, so that flux-map
identification ([`tuning.identify.flux_map_fit`][tuning.identify.flux_map_fit]) is tested on data the code
under test did not make.

**The machine** (the model written in the header of ``pmsmjax/presets/motors/saturated_ipm_map.csv``):
co-energy ``W'(i) = psi_m i_d + L_d i_d^2/2 + L_ql i_q^2/2 + L_mq s^2 ln cosh(r/s)`` with
``r = sqrt(s0^2 + i_q^2 + (c i_d)^2)``; ``psi = grad W'`` and ``L_inc = hess W'`` in closed form
([`saturated_flux`][tuning.identify.saturated_reference_log.saturated_flux]). Voltage equations in the rotor
frame (amplitude-invariant dq, peak values): ``u = R i + L_inc(i) di/dt + w_e J psi(i)``,
``J = [[0, -1], [1, 0]]``, integrated for ``di/dt``.

**The inverter.** The controller's stator-frame voltage is held over each control period (an averaged
inverter) and applied one period after it is computed (the angle advanced by 1.5 periods). An optional
voltage error of a two-level bridge is subtracted from each phase voltage
([`bridge_error`][tuning.identify.saturated_reference_log.bridge_error]): the PWM-period average of a dead
time ``t_d`` and a device drop ``V_f``, ``u_err = (t_d / Ts) U_dc + V_f`` (Murai et al., IEEE Trans. Ind.
Appl. 23(5), 1987, doi:10.1109/TIA.1987.4505004), whose sign moves linearly between its two values while the
phase current's PWM ripple crosses zero inside the period (``|i_x|`` below the ripple's half amplitude;
exactly sharp for no ripple). It is written here apart from the fit's own model (a ``tanh`` sign) so that the
fit is not tested on the shape it assumes. The log records the controller's references, as firmware does.

**The controller.** dq current PIs at bandwidth ``a_c`` on the unsaturated inductances (``Kp = a_c L``,
``Ki =`` `INTEGRAL_SHARE` ``a_c Kp``) and back-EMF feed-forward from the linear model at zero current,
voltage clamped to the SVPWM
circle; the current reference walks a grid of operating points
([`operating_walk`][tuning.identify.saturated_reference_log.operating_walk]): along i_q at each i_d, then
along i_d at each i_q, so every segment of the grid is crossed by a transient.

Each log row ``k`` is ``time, u_d, u_q, i_d, i_q, omega_m, theta_e``: the held stator voltage of
``[t_k, t_k+1)`` in dq at ``theta_e(t_k)``, and the currents, speed and angle sampled at ``t_k``.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

__all__ = [
    "SATURATED_IPM",
    "saturated_flux",
    "operating_walk",
    "saturated_drive_log",
    "speed_controlled_log",
    "flux_map_log",
    "FLUX_MAP_LOG_NOISE",
    "bridge_error",
    "ripple_half_amplitude",
]

#: The machine of ``saturated_ipm_map.csv`` (Wb, H, A, -) with the drive file's R, pole pairs.
SATURATED_IPM = dict(psi_m=0.1, L_d=3e-3, L_ql=2.5e-3, L_mq=10e-3, s=4.0, s0=1.0, c=0.5, R=0.5, pole_pairs=4)
#: Measurement noise (standard deviations) of a flux-map log: currents, A; voltages, V.
FLUX_MAP_LOG_NOISE = {"current_a": 0.05, "voltage_v": 0.5}
#: Integral gain of the current PIs as a share of ``a_c Kp``: the feed-forward of a linear model misses
#: the saturated flux by tens of volts, which the internal-model integral (``a_c R``) would remove only
#: at the slow rate R/L; this one removes it within a few milliseconds.
INTEGRAL_SHARE = 0.25
_J = np.array([[0.0, -1.0], [1.0, 0.0]])


def saturated_flux(machine: dict, i_d, i_q):
    """``(psi (..., 2) Wb, L_inc (..., 2, 2) H)`` of the co-energy model (module docstring) at currents
    ``i_d, i_q`` (A, any equal shapes)."""
    m = machine
    i_d, i_q = np.asarray(i_d, dtype=float), np.asarray(i_q, dtype=float)
    a = np.array([m["c"] ** 2, 1.0])
    x = np.stack([i_d, i_q], -1)
    ax = a * x  # dr/di * r
    r = np.sqrt(m["s0"] ** 2 + (x * ax).sum(-1))
    th = np.tanh(r / m["s"])
    g = m["s"] * th / r  # saturating part: psi_sat = L_mq g(r) A x
    dg = (r * (1.0 - th**2) - m["s"] * th) / r**2  # dg/dr
    psi = np.stack([m["psi_m"] + m["L_d"] * i_d, m["L_ql"] * i_q], -1) + m["L_mq"] * g[..., None] * ax
    L = np.zeros(x.shape + (2,))
    L[..., 0, 0], L[..., 1, 1] = m["L_d"], m["L_ql"]
    L = L + m["L_mq"] * (
        g[..., None, None] * np.diag(a) + (dg / r)[..., None, None] * ax[..., :, None] * ax[..., None, :]
    )
    return psi, L


def operating_walk(i_d_points, i_q_points) -> np.ndarray:
    """``(P, 2)`` current references, A: a snake along i_q at each i_d, then along i_d at each i_q."""
    i_d_points, i_q_points = np.asarray(i_d_points, float), np.asarray(i_q_points, float)
    rows = [
        (d, q) for j, d in enumerate(i_d_points) for q in (i_q_points if j % 2 == 0 else i_q_points[::-1])
    ]
    last_q = rows[-1][1]
    q_order = i_q_points if last_q == i_q_points[0] else i_q_points[::-1]
    d_start = i_d_points[::-1]
    cols = [(d, q) for k, q in enumerate(q_order) for d in (d_start if k % 2 == 0 else d_start[::-1])]
    return np.array(rows + cols)


def ripple_half_amplitude(machine: dict, u_dc_v: float, Ts: float) -> float:
    """Half the peak-to-peak PWM current ripple, A, of a phase at mid modulation: ``U_dc Ts / (8 L)``
    (centre-aligned PWM, a leg at duty 1/2 against a neutral near mid supply), ``L`` the smaller unsaturated
    incremental inductance of ``machine``; the current width over which
    [`bridge_error`][tuning.identify.saturated_reference_log.bridge_error] turns."""
    L0 = saturated_flux(machine, 0.0, 0.0)[1]
    return u_dc_v * Ts / (8.0 * float(np.min(np.diag(L0))))


def bridge_error(i_dq, theta, u_err_v: float, ripple_a: float) -> np.ndarray:
    """``(2,)`` dq voltage, V, that a bridge losing ``u_err_v`` V per phase (module docstring) takes away at
    the mean current ``i_dq (2,)`` A and electrical angle ``theta`` rad: per phase
    ``u_err clip(i_x / ripple_a, -1, 1)`` (``np.sign`` for ``ripple_a = 0``: the share of the period's
    dead-time edges at which the rippling current is positive, minus the share at which it is negative,
    for a ripple spread evenly over ``+-ripple_a``), common mode removed (isolated neutral)."""
    c, s = math.cos(theta), math.sin(theta)
    i_alpha, i_beta = c * i_dq[0] - s * i_dq[1], s * i_dq[0] + c * i_dq[1]
    i_abc = np.array(
        [i_alpha, -0.5 * i_alpha + 0.5 * math.sqrt(3) * i_beta, -0.5 * i_alpha - 0.5 * math.sqrt(3) * i_beta]
    )
    sign = np.sign(i_abc) if ripple_a <= 0.0 else np.clip(i_abc / ripple_a, -1.0, 1.0)
    e = u_err_v * sign
    e_alpha, e_beta = (2.0 * e[0] - e[1] - e[2]) / 3.0, (e[1] - e[2]) / math.sqrt(3)
    return np.array([c * e_alpha + s * e_beta, -s * e_alpha + c * e_beta])


def saturated_drive_log(
    machine: dict,
    references,
    *,
    speed_rpm: float,
    dwell_s: float,
    Ts: float = 1e-4,
    current_bandwidth_rad_s: float = 1000.0,
    u_dc_v: float = 311.0,
    dead_time_s: float = 0.0,
    device_drop_v: float = 0.0,
    ripple_a: float | None = None,
    rtol: float = 1e-8,
) -> dict[str, np.ndarray]:
    """Noise-free log (module docstring) of ``machine``
    ([`SATURATED_IPM`][tuning.identify.saturated_reference_log.SATURATED_IPM]'s keys) at constant
    ``speed_rpm`` (mechanical, r/min; negative turns backwards), the current reference stepping through
    ``references (P, 2)`` A, each held ``dwell_s`` s; control period ``Ts`` s (also the PWM period); the
    bridge's dead time ``dead_time_s`` s and device drop ``device_drop_v`` V, its sign turning over
    ``ripple_a`` A (default
    [`ripple_half_amplitude`][tuning.identify.saturated_reference_log.ripple_half_amplitude]; 0: sharp).
    Columns ``time`` s, ``u_d, u_q`` V, ``i_d, i_q`` A, ``omega_m`` rad/s, ``theta_e`` rad, each ``(N,)``,
    ``N = P dwell_s / Ts``."""
    m = machine
    refs = np.asarray(references, dtype=float)
    per_point = int(round(dwell_s / Ts))
    n = per_point * len(refs)
    w_m = speed_rpm * math.pi / 30.0
    w_e = m["pole_pairs"] * w_m
    loop = _CurrentLoop(m, current_bandwidth_rad_s, u_dc_v, Ts)
    u_err = dead_time_s / Ts * u_dc_v + device_drop_v
    ripple = ripple_half_amplitude(m, u_dc_v, Ts) if ripple_a is None else ripple_a

    def field(t, i, u_alpha, u_beta, theta0):
        th = theta0 + w_e * t
        u = np.array(_held_dq((u_alpha, u_beta), th))
        if u_err:
            u = u - bridge_error(i, th, u_err, ripple)
        psi, L = saturated_flux(m, i[0], i[1])
        return np.linalg.solve(L, u - m["R"] * i - w_e * (_J @ psi))

    # Start settled at the first point: the steady-state voltage applied (stator frame = dq at angle 0)
    # and the integrators holding what the feed-forward misses of it.
    i = refs[0].copy()
    steady = m["R"] * i + w_e * (_J @ saturated_flux(m, i[0], i[1])[0])
    pending = steady.copy()
    loop.integral = steady - loop.feed_forward(i, w_e)
    rows = np.empty((n, 7))
    for k in range(n):
        t = k * Ts
        th = w_e * t
        command = loop.command(refs[k // per_point], i, w_e, th)
        rows[k] = (t, *_held_dq(pending, th), i[0], i[1], w_m, th)
        sol = solve_ivp(field, (0.0, Ts), i, method="DOP853", rtol=rtol, atol=1e-10, args=(*pending, th))
        i = sol.y[:, -1]
        pending = command
    return _columns(rows)


def speed_controlled_log(
    machine: dict,
    speed_steps,
    load_steps,
    *,
    duration_s: float,
    inertia_kgm2: float,
    friction_nms: float = 0.0,
    speed_bandwidth_rad_s: float = 60.0,
    current_limit_a: float = 12.0,
    i_d_share: float = 0.4,
    Ts: float = 1e-4,
    current_bandwidth_rad_s: float = 1000.0,
    u_dc_v: float = 311.0,
    noise: dict | None = None,
    seed: int = 0,
    rtol: float = 1e-8,
) -> dict[str, np.ndarray]:
    """A log of ordinary closed-loop operation: ``machine``
    ([`SATURATED_IPM`][tuning.identify.saturated_reference_log.SATURATED_IPM]'s keys) from rest under a speed
    loop and load steps, the speed and angle integrated with the currents by the same DOP853.

    **Arguments:** `speed_steps`, `load_steps`: ``[(time_s, value), ...]`` step references of the speed
    (mechanical, r/min) and the load torque (N m), each value held from its time on (zero before the
    first); `duration_s`: s; `inertia_kgm2`, `friction_nms`: the shaft's J (kg m^2) and B (N m s/rad);
    `speed_bandwidth_rad_s`: the speed PI's bandwidth, designed on the unsaturated torque constant
    ``1.5 p psi(0)`` (``Kp = J beta / k_t``, ``Ki = beta Kp / 2``, the integral held while the current is
    limited); `current_limit_a`: the q reference's limit, A; `i_d_share`: the d reference
    ``-i_d_share |i_q*|`` (a fixed MTPA-like rule, not the map's MTPA); the current loop, bridge and log
    columns as [`saturated_drive_log`][tuning.identify.saturated_reference_log.saturated_drive_log] (no
    inverter error); `noise`, `seed` as
    [`flux_map_log`][tuning.identify.saturated_reference_log.flux_map_log].

    The currents then follow the operating points the speed and load ask for, along one path through
    the current plane with the transients around it: the fit determines the map there and marks the rest.
    """
    m = machine
    p = m["pole_pairs"]
    n = int(round(duration_s / Ts))
    loop = _CurrentLoop(m, current_bandwidth_rad_s, u_dc_v, Ts)
    k_t = 1.5 * p * loop.psi0
    kp_w = inertia_kgm2 * speed_bandwidth_rad_s / k_t
    ki_w = speed_bandwidth_rad_s * kp_w / 2.0

    def held(steps, t):
        value = 0.0
        for t_step, v in steps:
            if t >= t_step:
                value = v
        return value

    def field(t, x, u_alpha, u_beta, load):
        i, w_m, th = x[:2], x[2], x[3]
        u = np.array(_held_dq((u_alpha, u_beta), th))
        psi, L = saturated_flux(m, i[0], i[1])
        w_e = p * w_m
        di = np.linalg.solve(L, u - m["R"] * i - w_e * (_J @ psi))
        torque = 1.5 * p * (psi[0] * i[1] - psi[1] * i[0])
        return np.array([di[0], di[1], (torque - load - friction_nms * w_m) / inertia_kgm2, w_e])

    x = np.zeros(4)
    speed_integral = 0.0
    pending = np.zeros(2)
    rows = np.empty((n, 7))
    for k in range(n):
        t = k * Ts
        i, w_m, th = x[:2], x[2], x[3]
        error = held(speed_steps, t) * math.pi / 30.0 - w_m
        i_q_free = kp_w * error + speed_integral
        i_q_ref = min(max(i_q_free, -current_limit_a), current_limit_a)
        if i_q_ref == i_q_free:
            speed_integral += ki_w * Ts * error
        reference = np.array([-i_d_share * abs(i_q_ref), i_q_ref])
        command = loop.command(reference, i, p * w_m, th)
        rows[k] = (t, *_held_dq(pending, th), i[0], i[1], w_m, th)
        sol = solve_ivp(
            field, (0.0, Ts), x, method="DOP853", rtol=rtol, atol=1e-10, args=(*pending, held(load_steps, t))
        )
        x = sol.y[:, -1]
        pending = command
    return _add_noise(_columns(rows), noise, seed)


class _CurrentLoop:
    """The log maker's current controller (module docstring): dq PIs at bandwidth ``a_c`` (rad/s) on the
    unsaturated inductances, the linear model's back-EMF feed-forward at zero current, the voltage clamped
    to the SVPWM circle of ``u_dc_v`` (V) with the integral held while clamped, and the command turned
    to the stator frame at the angle it will be applied at (1.5 periods ahead)."""

    def __init__(self, machine: dict, a_c: float, u_dc_v: float, Ts: float):
        psi0, L0 = saturated_flux(machine, 0.0, 0.0)
        self.L = np.diag(L0)
        self.psi0 = float(psi0[0])
        self.u_max = u_dc_v / math.sqrt(3.0)
        self.a_c, self.Ts = a_c, Ts
        self.integral = np.zeros(2)

    def feed_forward(self, i, w_e: float) -> np.ndarray:
        return np.array([-w_e * self.L[1] * i[1], w_e * (self.L[0] * i[0] + self.psi0)])

    def command(self, reference, i, w_e: float, theta_e: float) -> np.ndarray:
        """``(2,)`` stator-frame voltage, V, for the current reference ``(2,)`` A at the measured current
        ``i (2,)`` A, electrical speed ``w_e`` rad/s and angle ``theta_e`` rad."""
        error = reference - i
        u_dq = self.a_c * self.L * error + self.integral + self.feed_forward(i, w_e)
        magnitude = math.hypot(*u_dq)
        if magnitude > self.u_max:
            u_dq *= self.u_max / magnitude
        else:
            self.integral = self.integral + self.a_c * INTEGRAL_SHARE * self.a_c * self.L * self.Ts * error
        angle = theta_e + 1.5 * w_e * self.Ts
        c, s = math.cos(angle), math.sin(angle)
        return np.array([u_dq[0] * c - u_dq[1] * s, u_dq[0] * s + u_dq[1] * c])


def _held_dq(u_ab, theta_e: float) -> tuple[float, float]:
    """The held stator-frame voltage ``u_ab (2,)`` V in dq at ``theta_e`` rad (a log row's ``u_d, u_q``, and
    the voltage the machine sees at each instant of the period)."""
    c, s = math.cos(theta_e), math.sin(theta_e)
    return u_ab[0] * c + u_ab[1] * s, -u_ab[0] * s + u_ab[1] * c


def _columns(rows: np.ndarray) -> dict[str, np.ndarray]:
    names = ("time", "u_d", "u_q", "i_d", "i_q", "omega_m", "theta_e")
    out = {name: rows[:, j].copy() for j, name in enumerate(names)}
    out["theta_e"] = np.mod(out["theta_e"] + math.pi, 2 * math.pi) - math.pi
    return out


def _add_noise(log: dict, noise: dict | None, seed: int) -> dict:
    """``log`` with white noise of ``noise`` (default
    [`FLUX_MAP_LOG_NOISE`][tuning.identify.saturated_reference_log.FLUX_MAP_LOG_NOISE]; ``{}`` for none) on
    its currents and voltages, drawn with ``seed``."""
    noise = FLUX_MAP_LOG_NOISE if noise is None else noise
    rng = np.random.default_rng(seed)
    for cols, key in ((("i_d", "i_q"), "current_a"), (("u_d", "u_q"), "voltage_v")):
        for col in cols:
            log[col] = log[col] + noise.get(key, 0.0) * rng.standard_normal(log[col].shape)
    return log


def flux_map_log(
    machine: dict,
    i_d_points,
    i_q_points,
    *,
    speed_rpm: float,
    dwell_s: float,
    noise: dict | None = None,
    seed: int = 0,
    **kwargs,
) -> dict[str, np.ndarray]:
    """The identification log: the walk of
    [`operating_walk`][tuning.identify.saturated_reference_log.operating_walk] over
    ``i_d_points x i_q_points`` (A) at ``+speed_rpm`` and then retraced at ``-speed_rpm`` (both directions of
    rotation separate R from the flux), joined in time (the speed reverses between two rows), with white noise
    of ``noise`` (default [`FLUX_MAP_LOG_NOISE`][tuning.identify.saturated_reference_log.FLUX_MAP_LOG_NOISE];
    ``{}`` for none) drawn with ``seed``. Other arguments as
    [`saturated_drive_log`][tuning.identify.saturated_reference_log.saturated_drive_log]."""
    walk = operating_walk(i_d_points, i_q_points)
    # Backwards the walk is retraced, so the current is continuous where the dynamometer reverses.
    parts = [
        saturated_drive_log(machine, path, speed_rpm=sign * speed_rpm, dwell_s=dwell_s, **kwargs)
        for sign, path in ((1.0, walk), (-1.0, walk[::-1]))
    ]
    dt = parts[0]["time"][1] - parts[0]["time"][0]
    parts[1]["time"] = parts[1]["time"] + parts[0]["time"][-1] + dt
    return _add_noise({k: np.concatenate([p[k] for p in parts]) for k in parts[0]}, noise, seed)
