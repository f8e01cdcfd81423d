"""Replay of a logged duty sequence: the leg duties ``d_a, d_b, d_c`` and the DC link ``U_dc`` of each row
through the averaged inverter, with the drive file's inverter error, into the machine with its magnet flux
harmonics and cogging (``pmsmjax replay`` of a log with duty columns instead of ``u_d, u_q``).

**The bridge** ([`pmsmjax.inverters.averaged`][pmsmjax.inverters.averaged]): row k's phase voltages
``U_dc (d_x - mean(d))`` plus the legs' error of
[`VoltageError`][pmsmjax.inverters.voltage_error.VoltageError] (``[inverter]`` ``dead_time_s`` and
``device_drop_v``; the dead time loses ``U_dc t_d`` per PWM period, ``f_sw dt`` periods in a row of ``dt``
seconds), less its common mode (the isolated neutral), at the sign of the phase currents at the row's
start, are held in the stator frame over the row: a real inverter's hold, so the hold is ``stator``.
The sign is smoothed over [`CURRENT_LIMIT_SHARE`][pmsmjax.inverters.voltage_error.CURRENT_LIMIT_SHARE] of
the file's ``[ratings] max_current_a``, as the drive's bridge has it.

**The machine**: the drive file's ``[motor]`` as [`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq] with its
``[harmonics]`` (flux harmonics' EMF and torque, cogging torque), speed imposed by an ``omega_m`` column
or dynamic under the load torque ``T_L``.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.machines.base import MachineInput, MachineState
from pmsmjax.machines.integrate import advance

__all__ = ["DUTY_COLUMNS", "duty_scan", "inverter_error", "stator_voltages", "replay_duty_log"]

#: The columns of a duty log (besides ``time``).
DUTY_COLUMNS = ("d_a", "d_b", "d_c", "U_dc")


def inverter_error(spec, dt: float):
    """The drive file's ``[inverter]`` error for rows of ``dt`` seconds
    ([`VoltageError`][pmsmjax.inverters.voltage_error.VoltageError]), or None without a dead time and drop."""
    from pmsmjax.inverters.voltage_error import CURRENT_LIMIT_SHARE, VoltageError

    inv = spec.inverter
    t_d, drop = float(inv.get("dead_time_s", 0.0)), float(inv.get("device_drop_v", 0.0))
    if t_d == 0.0 and drop == 0.0:
        return None
    per_row = t_d * float(inv["switching_frequency_hz"]) * dt  # the dead time of f_sw dt PWM periods
    scale = CURRENT_LIMIT_SHARE * float(spec.ratings["max_current_a"])
    return VoltageError(per_row, drop, scale)


def stator_voltages(duties, u_dc) -> np.ndarray:
    """``(N, 2)`` alpha-beta voltages of ideal legs, V (for the speed bound that picks the sub-steps)."""
    u = np.asarray(u_dc)[:, None] * (duties - duties.mean(axis=1, keepdims=True))
    return np.stack([(2 * u[:, 0] - u[:, 1] - u[:, 2]) / 3, (u[:, 1] - u[:, 2]) / np.sqrt(3.0)], axis=1)


@eqx.filter_jit
def duty_scan(machine, error, state0, dt, duties, u_dc, omega_m, load_torque, n_substeps: int):
    """The ``(N-1,)`` stacked states at ``t_1 ... t_{N-1}`` (module docstring).

    Args:
        machine: A [`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq] (``mechanics="imposed"`` if and only if
            ``omega_m`` is given).
        error: A [`VoltageError`][pmsmjax.inverters.voltage_error.VoltageError] or None.
        state0: The state at ``t_0``.
        dt: ``(N-1,)`` row intervals, s. duties: ``(N-1, 3)`` leg duties. u_dc: ``(N-1,)`` DC link, V.
        omega_m: ``(N-1,)`` imposed speed, rad/s, or None. load_torque: ``(N-1,)`` N m.
        n_substeps: RK4 steps per row (static).
    """

    @jax.checkpoint
    def interval(state: MachineState, xs):
        dt_k, d_k, udc_k, w_k, tl_k = xs
        if w_k is not None:
            state = MachineState(state.currents, w_k, state.theta_e)
        u = phase_voltages(d_k, udc_k)
        if error is not None:
            e = error.pole_error(machine.phase_currents(state), d_k, udc_k, dt_k)
            u = u + (e - jnp.mean(e))
        inputs = MachineInput(abc_to_alpha_beta(u), tl_k, frame="stator")
        state = advance(machine, state, inputs, dt_k, n_substeps)
        return state, state

    _, states = jax.lax.scan(interval, state0, (dt, duties, u_dc, omega_m, load_torque))
    return states


def replay_duty_log(motor, spec, log: dict, n_substeps: int) -> dict:
    """Replay the SI columns ``log`` (``time``, ``d_a``, ``d_b``, ``d_c``, ``U_dc``, and ``omega_m``,
    ``T_L``, ``theta_e``, ``i_d``, ``i_q`` when present) on ``motor``
    ([`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters]) with the drive file ``spec``'s harmonics and
    inverter error; returns ``{time, i_d, i_q, omega_m, theta_e}`` (``(N,)`` float64, row 0 the initial
    state: the first row's ``theta_e``, ``i_d``, ``i_q`` when logged, else rest at angle 0), with
    ``n_substeps`` RK4 steps per row."""
    from pmsmjax.frames.three_phase import wrap_angle
    from pmsmjax.machines.harmonics import MagnetHarmonics
    from pmsmjax.machines.pmsm3 import PMSMdq

    t = np.asarray(log["time"], float)
    dt = np.diff(t)
    duties = np.stack([log[c] for c in ("d_a", "d_b", "d_c")], axis=1)
    u_dc = np.asarray(log["U_dc"], float)
    imposed = "omega_m" in log
    tl = np.asarray(log.get("T_L", np.zeros_like(t)), float)
    h = spec.harmonics
    harmonics = MagnetHarmonics.from_rows(h.get("flux", ()), h.get("cogging", ())) if h else None
    machine = PMSMdq(motor, mechanics="imposed" if imposed else "dynamic", harmonics=harmonics)
    error = inverter_error(spec, float(np.median(dt)))
    i0 = np.array([log["i_d"][0], log["i_q"][0]]) if "i_d" in log and "i_q" in log else np.zeros(2)
    th0 = float(log["theta_e"][0]) if "theta_e" in log else 0.0
    w0 = float(log["omega_m"][0]) if imposed else 0.0
    dtype = motor.R.dtype
    f = lambda x: jnp.asarray(x, dtype)
    state0 = machine.initial_state(f(i0), f(w0), f(th0))
    omega = f(log["omega_m"][:-1]) if imposed else None
    states = duty_scan(machine, error, state0, f(dt), f(duties[:-1]), f(u_dc[:-1]), omega, f(tl[:-1]),
                       int(n_substeps))  # fmt: skip
    i_dq = np.concatenate([i0[None], np.asarray(states.currents, np.float64)])
    w = (
        np.asarray(log["omega_m"], float)
        if imposed
        else np.concatenate([[0.0], np.asarray(states.omega_m, float)])
    )
    theta = np.concatenate([[float(wrap_angle(th0))], np.asarray(states.theta_e, np.float64)])
    return {"time": t.copy(), "i_d": i_dq[:, 0], "i_q": i_dq[:, 1], "omega_m": w, "theta_e": theta}
