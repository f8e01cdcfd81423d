"""Electrical sub-problem: R, L_d, L_q, psi_f (and a dead-time voltage) from voltages, currents and speed.

Given the measured speed, the dq current equations do not involve the mechanics, so this residual group
depends on the electrical parameters only ([`tuning.identify.fit`][tuning.identify.fit] solves it jointly with
[`tuning.identify.mechanical`][tuning.identify.mechanical]):

``L_d di_d/dt = u_d - R i_d + w_e L_q i_q``,  ``L_q di_q/dt = u_q - R i_q - w_e (L_d i_d + psi_f)``,

with ``w_e = p_n w_m`` interpolated linearly between the measured samples. The voltage of row k is held
over interval k as [`pmsmjax.recorded.replay`][pmsmjax.recorded.replay] holds it: ``hold="stator"`` (a real
inverter: the stator-frame voltage is constant, so its dq components turn by ``-(theta_e(t) - theta_e(t_k))``)
or ``"rotor"``.
An optional dead-time term subtracts ``V_dt * tanh(i_x / eps)`` from each phase voltage (the voltage an
inverter loses while its legs are both off, smoothed at zero current so it stays differentiable).

**Output error with multiple shooting.** The log is cut into windows
([`tuning.identify.windows`][tuning.identify.windows]); each window is simulated with RK4 (``n_substeps``
steps per log interval) from the measured current at its first sample. The residuals are the simulated minus
the measured currents at every later sample of the window; the last of them, at the sample where the next
window starts, is the continuity gap between the two. Windows keep long logs from drifting (errors are reset
each window), and all of them run as one ``vmap``'d scan. (Free window initial states were tried: 2 more
unknowns per window made each Jacobian about 15x dearer, 0.37 s against 0.024 s for 20 windows.) Residuals are
divided by each axis's noise level so the sum of squares is a likelihood and the Gauss-Newton covariance is
meaningful ([`tuning.identify.uncertainty`][tuning.identify.uncertainty]).

**Warm start.** The current equations integrated over short blocks are linear in the parameters
(equation error): ``int u_d = R int i_d + L_d (i_d(b) - i_d(a)) - L_q int w_e i_q`` and the like for q.
Least squares on them gives the start of the output-error fit; integrating instead of differentiating
keeps the current noise from being amplified.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import SQRT3, abc_to_alpha_beta, dq_to_abc, park
from tuning.identify.parameters import ParameterMap
from tuning.identify.temperature_scaling import scales
from tuning.identify.windows import block_starts, interval_windows, sample_windows, segment_windows

__all__ = ["ELECTRICAL_NAMES", "ElectricalData", "electrical_residuals", "simulate_windows", "warm_start"]

#: Electrical unknowns; ``V_dt`` (dead-time voltage, V) only when the dead-time term is on.
ELECTRICAL_NAMES = ("R", "L_d", "L_q", "psi_f", "V_dt")


class ElectricalData(eqx.Module):
    """The log cut into windows, with everything that depends only on the data precomputed.

    Within interval k the RK4 stages sit at ``tau_j = j h / 2`` (``j = 0 .. 2 n_substeps``, ``h`` the
    sub-step); the speed, the voltage seen in dq and the rotor angle at those instants depend on the
    measurements only, so they are computed once in NumPy: the compiled scan then holds no
    trigonometric function (which is what made compiling it slow).

    - `dt`: ``(n_w, W)`` interval lengths, s.
    - `u`: ``(n_w, W, S, 2)`` dq voltage at the stages, V (the stator-held voltage turned by the angle
      travelled since the sample; constant for a rotor hold).
    - `w_e`: ``(n_w, W, S)`` electrical speed at the stages (linear between samples), rad/s.
    - `cs`: ``(n_w, W, S, 2)`` cos and sin of the rotor angle at the stages (dead-time term only).
    - `i`: ``(n_w, W+1, 2)`` measured dq currents, A. `sigma`: ``(2,)`` noise level of i_d, i_q, A.
    - static: `n_substeps`, `dead_time` (bool), `dead_time_eps` (smoothing current of its sign, A).
    - `r_scale`, `psi_scale`: ``(n_w,)`` factors on R and psi_f at each window's mean winding temperature
      ([`tuning.identify.temperature_scaling`][tuning.identify.temperature_scaling]), or None.
    """

    dt: Array
    u: Array
    w_e: Array
    cs: Array
    i: Array
    sigma: Array
    n_substeps: int = eqx.field(static=True)
    dead_time: bool = eqx.field(static=True)
    dead_time_eps: float = eqx.field(static=True)
    r_scale: Array | None = None
    psi_scale: Array | None = None

    @staticmethod
    def from_log(
        log,
        window: int,
        sigma,
        pole_pairs,
        hold,
        n_substeps,
        dead_time,
        dead_time_eps,
        temperature_coeffs=None,
    ):
        """From a [`tuning.identify.log.DriveLog`][tuning.identify.log.DriveLog]; `window` is the target
        window length in intervals (windows per capture,
        [`tuning.identify.windows.segment_windows`][tuning.identify.windows.segment_windows])."""
        starts, W = segment_windows(log.segments, window)
        k = scales(log.temperature_c, starts, W, temperature_coeffs)
        dt = np.diff(log.time)
        w0, w1 = log.omega_m[:-1], log.omega_m[1:]
        tau = dt[:, None] * np.arange(2 * n_substeps + 1)[None, :] / (2 * n_substeps)  # (N-1, S)
        slope = ((w1 - w0) / dt)[:, None]
        w_e = pole_pairs * (w0[:, None] + slope * tau)
        phi = pole_pairs * (w0[:, None] * tau + 0.5 * slope * tau**2)  # angle travelled since the sample
        u = np.broadcast_to(log.u_dq[:-1, None, :], phi.shape + (2,))
        if hold == "stator":
            c, s = np.cos(phi), np.sin(phi)
            u = np.stack([c * u[..., 0] + s * u[..., 1], -s * u[..., 0] + c * u[..., 1]], axis=-1)
        th = log.theta_e[:-1, None] + phi
        f = lambda x: jnp.asarray(interval_windows(x, starts, W), jnp.float64)
        return ElectricalData(
            dt=f(dt),
            u=f(u),
            w_e=f(w_e),
            cs=f(np.stack([np.cos(th), np.sin(th)], axis=-1)),
            i=jnp.asarray(sample_windows(log.i_dq, starts, W), jnp.float64),
            sigma=jnp.asarray(sigma, jnp.float64),
            n_substeps=n_substeps,
            dead_time=dead_time,
            dead_time_eps=dead_time_eps,
            r_scale=None if k is None else jnp.asarray(k[0], jnp.float64),
            psi_scale=None if k is None else jnp.asarray(k[1], jnp.float64),
        )


def _dead_time_voltage(i, cs, eps):
    """``(2,)`` dq voltage lost to dead time per volt of ``V_dt``: ``park(clarke(tanh(i_abc / eps)))``."""
    c, s = cs[0], cs[1]
    i_a, i_b = c * i[0] - s * i[1], s * i[0] + c * i[1]  # inverse Park
    i_abc = jnp.stack([i_a, -0.5 * i_a + 0.5 * SQRT3 * i_b, -0.5 * i_a - 0.5 * SQRT3 * i_b])
    sgn = jnp.tanh(i_abc / eps)
    e_a, e_b = (2.0 * sgn[0] - sgn[1] - sgn[2]) / 3.0, (sgn[1] - sgn[2]) / SQRT3  # Clarke
    return jnp.stack([c * e_a + s * e_b, -s * e_a + c * e_b])  # Park


def _window(p: dict, data: ElectricalData, x0, dt, u, w_e, cs):
    """Simulate one window from ``x0 (2,)``; returns ``(W, 2)`` currents at its samples 1..W."""

    def field(i, u_j, we_j, cs_j):
        if data.dead_time:
            u_j = u_j - p["V_dt"] * _dead_time_voltage(i, cs_j, data.dead_time_eps)
        did = (u_j[0] - p["R"] * i[0] + we_j * p["L_q"] * i[1]) / p["L_d"]
        diq = (u_j[1] - p["R"] * i[1] - we_j * (p["L_d"] * i[0] + p["psi_f"])) / p["L_q"]
        return jnp.stack([did, diq])

    def interval(i, xs):
        dt_k, u_k, we_k, cs_k = xs
        h = dt_k / data.n_substeps
        f = lambda j, x: field(x, u_k[j], we_k[j], cs_k[j])
        for n in range(data.n_substeps):  # static and small: unrolled
            j = 2 * n
            k1 = f(j, i)
            k2 = f(j + 1, i + 0.5 * h * k1)
            k3 = f(j + 1, i + 0.5 * h * k2)
            k4 = f(j + 2, i + h * k3)
            i = i + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return i, i

    _, states = jax.lax.scan(interval, x0, (dt, u, w_e, cs))
    return states


@eqx.filter_jit
def simulate_windows(pmap: ParameterMap, theta: Array, x0: Array, data: ElectricalData) -> Array:
    """``(n_w, W, 2)`` simulated currents at samples 1..W of every window from ``x0 (n_w, 2)``, A."""
    p = pmap.values(theta)
    if data.r_scale is None:
        sim = lambda x, dt, u, w_e, cs: _window(p, data, x, dt, u, w_e, cs)
        return jax.vmap(sim)(x0, data.dt, data.u, data.w_e, data.cs)
    at = lambda kr, kp: {**p, "R": p["R"] * kr, "psi_f": p["psi_f"] * kp}
    sim = lambda x, dt, u, w_e, cs, kr, kp: _window(at(kr, kp), data, x, dt, u, w_e, cs)
    return jax.vmap(sim)(x0, data.dt, data.u, data.w_e, data.cs, data.r_scale, data.psi_scale)


def electrical_residuals(theta: Array, args) -> Array:
    """``(n_w, W, 2)`` weighted residuals for optimistix: simulated minus measured currents at samples
    1..W of every window, each window started at its measured first sample. The last residual of a
    window is its continuity gap (the next window starts at that measured sample)."""
    pmap, data = args
    sim = simulate_windows(pmap, theta, data.i[:, 0, :], data)
    return (sim - data.i[:, 1:]) / data.sigma


def warm_start(
    log, pole_pairs: int, hold: str, fixed: dict, dead_time: bool, block: int = 20, temperature_coeffs=None
) -> tuple[dict, float]:
    """Equation-error least squares over blocks of ``block`` intervals, laid per capture (none spans a gap
    between the captures of a burst log); with `temperature_coeffs` and a logged temperature, R and psi_f
    scaled per block as in the output-error fit.

    Returns ``(start values (SI), explained)``: ``explained`` is the fraction of the integrated voltage
    the model explains (near 1 for a consistent log; far below when columns are swapped or mislabelled).

    `fixed`: ``{name: value}`` of parameters not estimated (their terms move to the left side).
    Non-positive or non-finite estimates (a parameter the data does not determine) fall back on a
    plausible value so the output-error fit can start; the fit's identifiability check reports them.
    """
    t, u, i, w = log.time, log.u_dq, log.i_dq, log.omega_m
    dt = np.diff(t)
    w_e = pole_pairs * w
    if hold == "stator":  # the interval-average of a stator-held voltage is turned by half the interval
        phi = -0.5 * w_e[:-1] * dt
        c, s = np.cos(phi), np.sin(phi)
        u = np.stack([c * u[:-1, 0] - s * u[:-1, 1], s * u[:-1, 0] + c * u[:-1, 1]], axis=1)
    else:
        u = u[:-1]
    trap = lambda x: 0.5 * (x[:-1] + x[1:]) * dt[(...,) + (None,) * (x.ndim - 1)]
    starts = block_starts(log.segments, block)
    n_b = starts.size
    blocks = lambda x: interval_windows(x, starts, block).sum(axis=1)
    int_u = blocks(u * dt[:, None])
    int_i = blocks(trap(i))
    d_i = i[starts + block] - i[starts]
    int_wi = blocks(trap(w_e[:, None] * i))
    int_w = blocks(trap(w_e))
    zero = np.zeros(n_b)
    k = scales(log.temperature_c, starts, block, temperature_coeffs)
    if k is not None:
        int_i, int_w = int_i * k[0][:, None], int_w * k[1]
    # rows: d then q; columns R, L_d, L_q, psi_f (+ V_dt)
    cols = {
        "R": np.concatenate([int_i[:, 0], int_i[:, 1]]),
        "L_d": np.concatenate([d_i[:, 0], int_wi[:, 0]]),
        "L_q": np.concatenate([-int_wi[:, 1], d_i[:, 1]]),
        "psi_f": np.concatenate([zero, int_w]),
    }
    if dead_time:
        with jax.enable_x64(True):  # jnp transforms, float64 whatever the process default is
            sgn = np.sign(np.asarray(dq_to_abc(i, log.theta_e)))
            e = np.asarray(park(abc_to_alpha_beta(sgn), log.theta_e))
        int_e = blocks(trap(e))
        cols["V_dt"] = -np.concatenate([int_e[:, 0], int_e[:, 1]])
    lhs = np.concatenate([int_u[:, 0], int_u[:, 1]])
    for name, value in fixed.items():
        if name in cols:
            lhs = lhs - value * cols.pop(name)
    names = list(cols)
    A = np.stack([cols[n] for n in names], axis=1)
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    est = np.linalg.lstsq(A / scale, lhs, rcond=None)[0] / scale
    explained = 1.0 - float(np.sum((lhs - A @ est) ** 2) / max(np.sum(lhs**2), 1e-300))
    out = dict(zip(names, est, strict=True))
    fallback = {"R": 0.1, "L_d": out.get("L_q", 1e-3), "L_q": out.get("L_d", 1e-3), "psi_f": 0.01}
    for name in ("R", "L_d", "L_q", "psi_f"):
        if name in out and not (np.isfinite(out[name]) and out[name] > 0):
            alt = fallback[name]
            out[name] = alt if np.isfinite(alt) and alt > 0 else 1e-3
    # An inductance whose axis carries no current (i_q = 0 at standstill, say) is fitted to noise and can
    # come out tiny: a time constant L / R below one log interval, which the fit's RK4 steps cannot
    # integrate. No current-controlled drive has one, so start such an inductance at the other axis's.
    r = out.get("R", fixed.get("R", 0.0))
    floor = r * float(np.median(dt))
    for name, other in (("L_d", "L_q"), ("L_q", "L_d")):
        if name in out and out[name] < floor:
            alt = out.get(other, fixed.get(other, 0.0))
            out[name] = alt if alt >= floor else 10.0 * floor
    if dead_time and not np.isfinite(out.get("V_dt", 0.0)):
        out["V_dt"] = 0.0
    return {k: float(v) for k, v in out.items()}, explained


def coupling_ratio(log, pole_pairs: int, block: int = 20) -> tuple[float, float]:
    """``(ratio, relative std)`` of L_q seen through the speed term over L_q seen through di_q/dt.

    In ``u_d`` the q inductance multiplies ``w_e i_q``; in ``u_q`` it multiplies ``di_q/dt``. Fitted as
    two separate coefficients they agree (ratio 1) only when the speed is in the right unit: a speed
    column in r/min makes the ratio pi/30. Used when there is no angle to check the speed against.
    """
    t, u, i, w_e = log.time, log.u_dq, log.i_dq, pole_pairs * log.omega_m
    dt = np.diff(t)
    trap = lambda x: 0.5 * (x[:-1] + x[1:]) * dt
    starts = block_starts(log.segments, block)
    blocks = lambda x: interval_windows(x, starts, block).sum(axis=1)
    d = lambda x: x[starts + block] - x[starts]
    lhs_d, lhs_q = blocks(u[:-1, 0] * dt), blocks(u[:-1, 1] * dt)
    A_d = np.stack([blocks(trap(i[:, 0])), d(i[:, 0]), -blocks(trap(w_e * i[:, 1]))], axis=1)
    A_q = np.stack([blocks(trap(i[:, 1])), d(i[:, 1]), blocks(trap(w_e * i[:, 0])), blocks(trap(w_e))], 1)
    coef = []
    for A, lhs, k in ((A_d, lhs_d, 2), (A_q, lhs_q, 1)):
        x, res, *_ = np.linalg.lstsq(A, lhs, rcond=None)
        s2 = float(np.sum((lhs - A @ x) ** 2)) / max(lhs.size - A.shape[1], 1)
        var = s2 * np.linalg.pinv(A.T @ A)[k, k]
        coef.append((x[k], np.sqrt(max(var, 0.0))))
    (a, sa), (b, sb) = coef
    ratio = a / b if b != 0 else np.inf
    return float(ratio), float(np.hypot(sa / a, sb / b)) if a != 0 and b != 0 else np.inf
