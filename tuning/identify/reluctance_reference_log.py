"""A flux-map identification log of a PM-assisted synchronous reluctance machine made without this project's
engine: an algebraic saturation model with strong self- and cross-saturation, the stator flux as the state,
integrated by SciPy's ``solve_ivp`` (DOP853) under the NumPy current loop of
[`tuning.identify.saturated_reference_log`][tuning.identify.saturated_reference_log].

**The machine: the power-law current map** of Hinkkanen, Pescetto, Mölsä, Saarakkala, Pellegrino and Bojoi,
"Sensorless self-commissioning of synchronous reluctance motors at standstill without rotor locking", IEEE
Trans. Ind. Appl., 2017, doi:10.1109/TIA.2016.2644624 (the form motulator implements as
``SaturationModelSyRM``). It gives the current as the gradient of a magnetic energy ``W(psi)``, so the map
is reciprocal and, where ``W`` is convex, stores energy. In that paper's reluctance axes (d: the
high-permeance axis)

``W = a_d0 y^2/2 + a_dd |y|^(S+2)/(S+2) + a_q0 x^2/2 + a_qq |x|^(T+2)/(T+2)
+ a_dq |y|^(U+2) |x|^(V+2) / ((U+2)(V+2))``, ``i = grad W``,

``y`` the high-permeance axis' flux and ``x`` the other's, Wb; ``1/a_d0``, ``1/a_q0`` the unsaturated
inductances (H).

**pmsmjax's axes.** pmsmjax's d axis is the magnet's; a PM-assisted rotor's magnets sit in the flux barriers,
across the high-permeance axis, along the reluctance frame's -q axis (as SyR-e's "SR" maps,
[`pmsmjax.io.flux_map_formats.syre`][pmsmjax.io.flux_map_formats.syre]). So pmsmjax's q axis is the
high-permeance axis: ``y = psi_q``, ``x = psi_d - psi_pm`` (the reluctance frame's ``-psi_q``),
``i_d = dW/dx``, ``i_q = dW/dy``; the magnet is a flux ``psi_pm`` in series with the iron (the magnet's flux
at zero current; a simple assistance, not a bridge-saturation model). The q-axis (high-permeance)
incremental inductance is the one that falls tenfold with the current
([`SYRM`][tuning.identify.reluctance_reference_log.SYRM]); the motoring quadrant is ``i_d < 0``.

**The integration.** ``dpsi/dt = u - R i(psi) - w_e J psi`` (rotor frame, ``J = [[0, -1], [1, 0]]``): the
current map is explicit, so the flux needs no inversion while integrating; the log's currents are
``i(psi)``. The reference (true) map ``psi(i)``
([`syrm_flux`][tuning.identify.reluctance_reference_log.syrm_flux]) inverts it by Newton's method.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from pmsmjax.machines.flux_map import FluxMapGrid
from tuning.identify.saturated_reference_log import (
    _add_noise,
    _columns,
    _CurrentLoop,
    _held_dq,
    operating_walk,
)

__all__ = [
    "SYRM",
    "syrm_current",
    "syrm_flux",
    "syrm_drive_log",
    "syrm_staircase_log",
    "syrm_speed_controlled_log",
    "STAIRCASE_D",
    "STAIRCASE_Q",
    "steady_state_map",
]

#: The current map's coefficients (A/Wb, A/Wb^(1+S), ...) of motulator's 6.7 kW SyRM example, with a small
#: magnet flux ``psi_pm`` (Wb), the stator resistance (ohm) and pole pairs of that example. Over 0 to 24 A
#: of i_q the q-axis incremental inductance falls from 57 mH to about 6 mH.
SYRM = dict(
    a_d0=17.4, a_dd=373.0, S=5.0, a_q0=52.1, a_qq=658.0, T=1.0, a_dq=1120.0, U=1.0, V=0.0,
    psi_pm=0.05, R=0.54, pole_pairs=2,
)  # fmt: skip
#: The staircase's operating points, A: 5 x 7 = 35, the motoring half plane of i_q >= 0.
STAIRCASE_D = np.array([-16.0, -12.0, -8.0, -4.0, 0.0])
STAIRCASE_Q = np.array([0.0, 4.0, 8.0, 12.0, 16.0, 20.0, 24.0])
_J = np.array([[0.0, -1.0], [1.0, 0.0]])


def syrm_current(machine: dict, psi_d, psi_q):
    """``(i (..., 2) A, G (..., 2, 2) 1/H)``: the current and its Jacobian ``di/dpsi`` (the inverse of the
    incremental inductance) of ``machine`` ([`SYRM`][tuning.identify.reluctance_reference_log.SYRM]'s keys)
    at the fluxes ``psi_d, psi_q`` (Wb, equal shapes); module docstring."""
    m = machine
    x = np.asarray(psi_d, dtype=float) - m["psi_pm"]
    y = np.asarray(psi_q, dtype=float)
    ax, ay = np.abs(x), np.abs(y)
    cross = m["a_dq"] * ay ** m["U"] * ax ** m["V"]  # a_dq |y|^U |x|^V
    i_d = (m["a_q0"] + m["a_qq"] * ax ** m["T"] + cross * ay**2 / (m["U"] + 2.0)) * x
    i_q = (m["a_d0"] + m["a_dd"] * ay ** m["S"] + cross * ax**2 / (m["V"] + 2.0)) * y
    G = np.empty(x.shape + (2, 2))
    G[..., 0, 0] = (
        m["a_q0"]
        + (m["T"] + 1.0) * m["a_qq"] * ax ** m["T"]
        + (m["V"] + 1.0) * cross * ay**2 / (m["U"] + 2.0)
    )
    G[..., 1, 1] = (
        m["a_d0"]
        + (m["S"] + 1.0) * m["a_dd"] * ay ** m["S"]
        + (m["U"] + 1.0) * cross * ax**2 / (m["V"] + 2.0)
    )
    G[..., 0, 1] = G[..., 1, 0] = cross * x * y
    return np.stack([i_d, i_q], -1), G


def syrm_flux(machine: dict, i_d, i_q, *, tol_a: float = 1e-11):
    """``(psi (..., 2) Wb, L_inc (..., 2, 2) H)`` of ``machine`` at the currents ``i_d, i_q`` (A, equal
    shapes): the current map inverted by Newton's method (from a flux below the q-axis solution, where the
    convex map's Newton steps approach it from above), to ``tol_a`` A."""
    target = np.stack(np.broadcast_arrays(np.asarray(i_d, float), np.asarray(i_q, float)), -1)
    psi = np.stack([machine["psi_pm"] + target[..., 0] / machine["a_q0"], np.zeros(target.shape[:-1])], -1)
    psi[..., 1] = np.sign(target[..., 1]) * np.minimum(
        np.abs(target[..., 1]) / machine["a_d0"],
        (np.abs(target[..., 1]) / machine["a_dd"]) ** (1 / (machine["S"] + 1)),
    )
    for _ in range(200):
        i, G = syrm_current(machine, psi[..., 0], psi[..., 1])
        r = i - target
        if np.max(np.abs(r), initial=0.0) < tol_a:
            break
        psi = psi - np.linalg.solve(G, r[..., None])[..., 0]
    else:
        raise RuntimeError("syrm_flux: Newton's method did not converge")
    return psi, np.linalg.inv(G)


class _SyrmLoop(_CurrentLoop):
    """The log maker's current loop designed on ``machine``'s unsaturated inductances and magnet flux."""

    def __init__(self, machine: dict, a_c: float, u_dc_v: float, Ts: float):
        self.L = 1.0 / np.array([machine["a_q0"], machine["a_d0"]])
        self.psi0 = float(machine["psi_pm"])
        self.u_max = u_dc_v / math.sqrt(3.0)
        self.a_c, self.Ts = a_c, Ts
        self.integral = np.zeros(2)


def syrm_drive_log(
    machine: dict,
    references,
    *,
    speed_rpm: float,
    dwell_s: float,
    Ts: float = 1e-4,
    current_bandwidth_rad_s: float = 1000.0,
    u_dc_v: float = 540.0,
    rtol: float = 1e-8,
) -> dict[str, np.ndarray]:
    """Noise-free log of ``machine`` at constant ``speed_rpm`` (mechanical, r/min), the current reference
    stepping through ``references (P, 2)`` A, each held ``dwell_s`` s; control period ``Ts`` s; DC link
    ``u_dc_v`` V. Columns as
    [`saturated_drive_log`][tuning.identify.saturated_reference_log.saturated_drive_log]'s."""
    m = machine
    refs = np.asarray(references, dtype=float)
    per_point = int(round(dwell_s / Ts))
    n = per_point * len(refs)
    w_m = speed_rpm * math.pi / 30.0
    w_e = m["pole_pairs"] * w_m
    loop = _SyrmLoop(m, current_bandwidth_rad_s, u_dc_v, Ts)

    def field(t, psi, u_alpha, u_beta, theta0):
        u = np.array(_held_dq((u_alpha, u_beta), theta0 + w_e * t))
        return u - m["R"] * syrm_current(m, psi[0], psi[1])[0] - w_e * (_J @ psi)

    psi = syrm_flux(m, *refs[0])[0]
    i = refs[0].copy()
    steady = m["R"] * i + w_e * (_J @ psi)
    pending = steady.copy()
    loop.integral = steady - loop.feed_forward(i, w_e)
    rows = np.empty((n, 7))
    for k in range(n):
        th = w_e * k * Ts
        i = syrm_current(m, psi[0], psi[1])[0]
        command = loop.command(refs[k // per_point], i, w_e, th)
        rows[k] = (k * Ts, *_held_dq(pending, th), i[0], i[1], w_m, th)
        sol = solve_ivp(field, (0.0, Ts), psi, method="DOP853", rtol=rtol, atol=1e-12, args=(*pending, th))
        psi = sol.y[:, -1]
        pending = command
    return _columns(rows)


def syrm_staircase_log(
    machine: dict = SYRM,
    i_d_points=STAIRCASE_D,
    i_q_points=STAIRCASE_Q,
    *,
    speed_rpm: float = 400.0,
    dwell_s: float = 0.04,
    noise: dict | None = None,
    seed: int = 0,
    **kwargs,
) -> dict[str, np.ndarray]:
    """The staircase: the walk of [`operating_walk`][tuning.identify.saturated_reference_log.operating_walk]
    over ``i_d_points x i_q_points`` (A) at one ``speed_rpm`` (one direction: R must be given to the fit),
    ``dwell_s`` s a point, with white noise of ``noise`` (default
    [`FLUX_MAP_LOG_NOISE`][tuning.identify.saturated_reference_log.FLUX_MAP_LOG_NOISE]: 0.05 A, 0.5 V)
    drawn with ``seed``; other arguments as
    [`syrm_drive_log`][tuning.identify.reluctance_reference_log.syrm_drive_log]. The walk visits every
    operating point twice (along i_q, then along i_d); a staircase visits each once, so the walk's first
    half (a snake along i_q at each i_d) is the staircase, and its second half only retraces it across."""
    walk = operating_walk(i_d_points, i_q_points)[: len(i_d_points) * len(i_q_points)]
    raw = syrm_drive_log(machine, walk, speed_rpm=speed_rpm, dwell_s=dwell_s, **kwargs)
    return _add_noise(raw, noise, seed)


def syrm_speed_controlled_log(
    machine: dict,
    speed_steps,
    load_steps,
    *,
    duration_s: float,
    inertia_kgm2: float,
    friction_nms: float = 0.0,
    speed_bandwidth_rad_s: float = 30.0,
    current_limit_a: float = 24.0,
    i_d_share: float = 0.5,
    Ts: float = 1e-4,
    current_bandwidth_rad_s: float = 1000.0,
    u_dc_v: float = 540.0,
    noise: dict | None = None,
    seed: int = 0,
    rtol: float = 1e-8,
) -> dict[str, np.ndarray]:
    """Ordinary closed-loop operation of ``machine``: as
    [`speed_controlled_log`][tuning.identify.saturated_reference_log.speed_controlled_log] (speed loop
    from rest, load steps, the d reference ``-i_d_share |i_q*|``, speed and angle integrated with the flux
    by the same DOP853), the speed PI designed on the torque per q ampere of the unsaturated map at the
    d current the rule sets for ``current_limit_a / 2``."""
    m = machine
    p = m["pole_pairs"]
    n = int(round(duration_s / Ts))
    loop = _SyrmLoop(m, current_bandwidth_rad_s, u_dc_v, Ts)
    k_t = 1.5 * p * (m["psi_pm"] + (1.0 / m["a_d0"] - 1.0 / m["a_q0"]) * i_d_share * current_limit_a / 2)
    kp_w = inertia_kgm2 * speed_bandwidth_rad_s / k_t
    ki_w = speed_bandwidth_rad_s * kp_w / 2.0

    def held(steps, t):
        value = 0.0
        for t_step, v in steps:
            if t >= t_step:
                value = v
        return value

    def field(t, x, u_alpha, u_beta, load):
        psi, w_m, th = x[:2], x[2], x[3]
        u = np.array(_held_dq((u_alpha, u_beta), th))
        i = syrm_current(m, psi[0], psi[1])[0]
        w_e = p * w_m
        torque = 1.5 * p * (psi[0] * i[1] - psi[1] * i[0])
        dpsi = u - m["R"] * i - w_e * (_J @ psi)
        return np.array([dpsi[0], dpsi[1], (torque - load - friction_nms * w_m) / inertia_kgm2, w_e])

    x = np.array([m["psi_pm"], 0.0, 0.0, 0.0])
    speed_integral = 0.0
    pending = np.zeros(2)
    rows = np.empty((n, 7))
    for k in range(n):
        t = k * Ts
        w_m, th = x[2], x[3]
        i = syrm_current(m, x[0], x[1])[0]
        error = held(speed_steps, t) * math.pi / 30.0 - w_m
        i_q_free = kp_w * error + speed_integral
        i_q_ref = min(max(i_q_free, -current_limit_a), current_limit_a)
        if i_q_ref == i_q_free:
            speed_integral += ki_w * Ts * error
        reference = np.array([-i_d_share * abs(i_q_ref), i_q_ref])
        command = loop.command(reference, i, p * w_m, th)
        rows[k] = (t, *_held_dq(pending, th), i[0], i[1], w_m, th)
        sol = solve_ivp(
            field, (0.0, Ts), x, method="DOP853", rtol=rtol, atol=1e-12, args=(*pending, held(load_steps, t))
        )
        x = sol.y[:, -1]
        pending = command
    return _add_noise(_columns(rows), noise, seed)


def steady_state_map(
    log, R: float, pole_pairs: int, i_d_points=STAIRCASE_D, i_q_points=STAIRCASE_Q
) -> FluxMapGrid:
    """The naive estimate a staircase gives without its transients: at each operating point of
    [`syrm_staircase_log`][tuning.identify.reluctance_reference_log.syrm_staircase_log]'s ``log`` (a
    [`DriveLog`][tuning.identify.log.DriveLog]), the flux from the steady-state voltage equation
    ``u = R i + w_e J psi`` (``R`` ohm, ``pole_pairs``) with the voltage, current and speed averaged over
    the dwell's second half (the voltage over each period as the stator-frame hold applies it), on the grid
    of the operating points (``i_d_points x i_q_points``, A) and interpolated as every map is."""
    from tuning.identify.flux_map_fit import _voltage_integrals

    n = len(i_d_points) * len(i_q_points)
    per_point = log.n // n
    w_e = pole_pairs * np.asarray(log.omega_m, dtype=float)
    dt = np.diff(log.time)
    u = _voltage_integrals(np.asarray(log.u_dq), w_e, dt, log.hold) / dt[:, None]
    walk = operating_walk(i_d_points, i_q_points)[:n]
    psi = np.zeros((len(i_d_points), len(i_q_points), 2))
    for k, (d, q) in enumerate(walk):
        s = slice(k * per_point + per_point // 2, (k + 1) * per_point - 1)
        um, im, wm = u[s].mean(axis=0), log.i_dq[s].mean(axis=0), w_e[s].mean()
        j, c = int(np.flatnonzero(i_d_points == d)[0]), int(np.flatnonzero(i_q_points == q)[0])
        psi[j, c] = [(um[1] - R * im[1]) / wm, (R * im[0] - um[0]) / wm]
    return FluxMapGrid(i_d_points, i_q_points, psi[..., 0], psi[..., 1], source="steady-state estimate")
