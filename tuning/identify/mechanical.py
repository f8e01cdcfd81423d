"""Mechanical sub-problem: J, B and a constant load torque from speed and the identified torque.

``J dw_m/dt = T_e - B w_m - T_c - T_L``, with ``T_e = 1.5 p_n [psi_f i_q + (L_d - L_q) i_d i_q]`` from
the measured currents and the electrical parameters
([`tuning.identify.electrical`][tuning.identify.electrical]), ``T_L`` a logged load torque (0 if none) and
``T_c`` an unknown constant load (``load="constant"``) or 0.

**Output error with multiple shooting, end residuals only.** The log is cut into short windows
(default 10 ms); each starts at the measured speed and is integrated with RK4 (torque interpolated
linearly between samples); the residual is the simulated minus the measured speed at the window's end,
which is also the next window's start (the continuity gap). Only the end is compared because the
current noise enters the speed through an integrator: inside a window the speed error is a random
walk, strongly correlated from sample to sample, whereas window-end errors of disjoint windows are
independent, so the Gauss-Newton covariance (which assumes independent residuals) holds.

**Warm start.** Each window's equation integrated exactly is linear in ``(J, B, T_c)``:
``int T_e - int T_L = J (w_end - w_start) + B int w + T_c (t_end - t_start)`` (trapezoidal integrals).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from tuning.identify.parameters import ParameterMap
from tuning.identify.temperature_scaling import scales
from tuning.identify.windows import interval_windows, sample_windows, segment_windows

__all__ = ["MECHANICAL_NAMES", "MechanicalData", "mechanical_residuals", "simulate_speed", "warm_start"]

#: Mechanical unknowns: inertia (kg m^2), viscous friction (N m s/rad), constant load torque (N m).
MECHANICAL_NAMES = ("J", "B", "T_c")


class MechanicalData(eqx.Module):
    """The log cut into windows. `dt`: ``(n_w, W)`` s; `w`: ``(n_w, W+1)`` rad/s; `i`: ``(n_w, W+1, 2)``
    A; `load`: ``(n_w, W+1)`` logged load torque, N m; `sigma`: speed-residual scale, rad/s; static
    `pole_pairs`, `n_substeps`; `psi_scale`: ``(n_w,)`` factor on psi_f at each window's mean winding
    temperature ([`tuning.identify.temperature_scaling`][tuning.identify.temperature_scaling]) or None.
    Windows are laid per capture
    ([`tuning.identify.windows.segment_windows`][tuning.identify.windows.segment_windows])."""

    dt: Array
    w: Array
    i: Array
    load: Array
    sigma: Array
    pole_pairs: int = eqx.field(static=True)
    n_substeps: int = eqx.field(static=True)
    psi_scale: Array | None = None

    @staticmethod
    def from_log(
        log, window: int, sigma: float, pole_pairs: int, n_substeps: int = 1, temperature_coeffs=None
    ):
        starts, W = segment_windows(log.segments, window)
        f = lambda x: jnp.asarray(x, jnp.float64)
        k = scales(log.temperature_c, starts, W, temperature_coeffs)
        return MechanicalData(
            dt=f(interval_windows(np.diff(log.time), starts, W)),
            w=f(sample_windows(log.omega_m, starts, W)),
            i=f(sample_windows(log.i_dq, starts, W)),
            load=f(sample_windows(log.load_torque, starts, W)),
            sigma=f(sigma),
            pole_pairs=pole_pairs,
            n_substeps=n_substeps,
            psi_scale=None if k is None else f(k[1]),
        )


def electromagnetic_torque(pe: dict, i_dq, pole_pairs: int):
    """``T_e`` (N m) from dq currents ``(..., 2)`` A and electrical parameters ``pe``."""
    i_d, i_q = i_dq[..., 0], i_dq[..., 1]
    return 1.5 * pole_pairs * (pe["psi_f"] * i_q + (pe["L_d"] - pe["L_q"]) * i_d * i_q)


def _at_temperature(p: dict, psi_scale):
    """``p`` with psi_f at each window's temperature (``psi_f (n_w, 1)``), or ``p`` when not scaled."""
    return p if psi_scale is None else {**p, "psi_f": p["psi_f"] * psi_scale[:, None]}


def _window(pm: dict, data: MechanicalData, w0, dt, torque):
    """Speed at samples 1..W of one window from ``w0``; ``torque (W+1,)`` net drive torque, N m."""

    def interval(w, xs):
        dt_k, t0, t1 = xs
        h = dt_k / data.n_substeps
        f = lambda tau, x: (t0 + (t1 - t0) * tau / dt_k - pm["T_c"] - pm["B"] * x) / pm["J"]
        for n in range(data.n_substeps):
            tau = n * h
            k1 = f(tau, w)
            k2 = f(tau + 0.5 * h, w + 0.5 * h * k1)
            k3 = f(tau + 0.5 * h, w + 0.5 * h * k2)
            k4 = f(tau + h, w + h * k3)
            w = w + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return w, w

    _, ws = jax.lax.scan(interval, w0, (dt, torque[:-1], torque[1:]))
    return ws


@eqx.filter_jit
def simulate_speed(pmap: ParameterMap, theta, data: MechanicalData):
    """``(n_w, W)`` simulated speed at samples 1..W of every window, each from its measured start, rad/s.

    ``pmap`` holds the electrical parameters too (the torque needs psi_f, L_d, L_q).
    """
    p = _at_temperature(pmap.values(theta), data.psi_scale)
    torque = electromagnetic_torque(p, data.i, data.pole_pairs) - data.load
    return jax.vmap(lambda w0, dt, tq: _window(p, data, w0, dt, tq))(data.w[:, 0], data.dt, torque)


def mechanical_residuals(theta: Array, args) -> Array:
    """``(n_w,)`` weighted window-end speed residuals; args ``(pmap, data)``."""
    pmap, data = args
    return (simulate_speed(pmap, theta, data)[:, -1] - data.w[:, -1]) / data.sigma


def warm_start(data: MechanicalData, pe: dict, fixed: dict) -> tuple[dict, float]:
    """Linear least squares of the window-integrated equation; returns (start values, residual scale).

    The residual scale is the RMS speed error (rad/s) that the equation error implies at a window end,
    ``rms(equation residual) / J``, used as the first weight of the output-error fit.
    """
    d = jax.tree.map(np.asarray, data)
    torque = (
        np.asarray(electromagnetic_torque(_at_temperature(pe, d.psi_scale), d.i, data.pole_pairs)) - d.load
    )
    trap = lambda x: np.sum(0.5 * (x[:, :-1] + x[:, 1:]) * d.dt, axis=1)
    lhs = trap(torque)
    cols = {"J": d.w[:, -1] - d.w[:, 0], "B": trap(d.w), "T_c": d.dt.sum(axis=1)}
    for name, value in fixed.items():
        lhs = lhs - value * cols.pop(name)
    names = list(cols)
    if not names:  # every mechanical parameter held fixed: the residual is the equation's own
        return {}, float(np.sqrt(np.mean(lhs**2)) / fixed["J"])
    A = np.stack([cols[n] for n in names], axis=1)
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    est = np.linalg.lstsq(A / scale, lhs, rcond=None)[0] / scale
    out = dict(zip(names, (float(v) for v in est), strict=True))
    J = out.get("J", fixed.get("J"))
    resid = lhs - A @ est
    if "J" in out and not (np.isfinite(J) and J > 0):
        out["J"] = J = 1e-3
    if "B" in out and not (np.isfinite(out["B"]) and out["B"] > 0):
        out["B"] = 1e-2 * J
    dof = max(resid.size - len(names), 1)
    return out, float(np.sqrt(np.sum(resid**2) / dof) / J)
