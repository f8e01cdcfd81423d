"""Replay a recorded voltage sequence through the machine model.

A log gives row times ``t_k`` and the dq voltages ``u_dq[k]`` a drive applied; the voltage of row k is
held over ``[t_k, t_{k+1})``. The rows may be irregularly spaced. The machine
([`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq]) is integrated over each interval with a fixed number of RK4
sub-steps inside one jit-compiled ``lax.scan`` (one compile per log length, sub-step count and hold). Row k of
the result is the state at ``t_k`` (row 0 is the initial state), so result and log line up row by row.

**The hold frame.** A zero-order hold is ambiguous for a rotating machine:

- ``hold="rotor"`` (default): ``u_dq[k]`` is constant in the rotor frame over the interval, so the
  stator-frame voltage turns with the rotor. This is what a dq-model simulator does (a Simulink dq PMSM
  block fed by a sampled controller, or this library's scan with a rotor-frame hold): use it to
  reproduce such a simulator's log.
- ``hold="stator"``: the stator-frame (alpha-beta) voltage ``inverse_park(u_dq[k], theta_e(t_k))`` is
  constant over the interval, and its dq components turn backwards as the rotor advances. This is what a
  real inverter does (the PWM switching pattern is fixed for the period): use it for logs of a real
  drive, where ``u_dq[k]`` is the controller's command computed with the angle at ``t_k``.

The two agree at standstill and differ by about ``omega_e * dt / 2`` rad of voltage angle at speed.
[`replay_log`][pmsmjax.recorded.replay.replay_log] (``pmsmjax replay``) defaults to ``hold="auto"`` like
``pmsmjax identify`` ([`DEFAULT_HOLD`][pmsmjax.recorded.replay.DEFAULT_HOLD]): the hold whose replay matches
the log's own currents, ``"stator"`` when it has none.

**Speed.** With an ``omega_m`` column the speed is imposed (a dynamometer): row k's speed holds over
interval k and the mechanical equation is not used. Without it the speed is dynamic,
``J dw/dt = T_e - T_L - B w``, with the load torque ``T_L`` of row k held over interval k (default 0).
"""

import math
import os
import warnings
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.frames.three_phase import inverse_park, wrap_angle
from pmsmjax.io.logs import check_columns, misspelt_columns, write_csv_atomic
from pmsmjax.io.mapped_logs import read_mapped_log
from pmsmjax.machines.base import MachineInput, MachineState
from pmsmjax.machines.integrate import advance, max_stable_substep
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.machines.pmsm3 import PMSMdq
from pmsmjax.presets.three_phase import load_motor
from pmsmjax.spec.plausibility import check_time_step
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "replay",
    "replay_file",
    "replay_log",
    "replay_scan",
    "choose_hold",
    "default_substeps",
    "REPLAY_COLUMNS",
    "LOG_COLUMNS",
    "DEFAULT_HOLD",
]

#: Columns of the replay output, in order.
REPLAY_COLUMNS = ("time", "i_d", "i_q", "omega_m", "theta_e")
#: Log columns replay reads: required, then optional (``omega_m`` imposes the speed, ``T_L`` is the load
#: torque, ``theta_e``/``i_d``/``i_q`` give the initial state from row 0).
LOG_COLUMNS = (("time", "u_d", "u_q"), ("omega_m", "T_L", "theta_e", "i_d", "i_q"))
_HOLDS = ("rotor", "stator")
#: The hold ``pmsmjax replay`` and ``pmsmjax identify`` use unless told: ``"auto"``, found from the log
#: (identify fits both; replay compares both with the logged currents,
#: [`choose_hold`][pmsmjax.recorded.replay.choose_hold]).
DEFAULT_HOLD = "auto"


@eqx.filter_jit
def replay_scan(
    machine: PMSMdq,
    state0: MachineState,
    dt: jnp.ndarray,
    u_dq: jnp.ndarray,
    omega_m: jnp.ndarray | None,
    load_torque: jnp.ndarray,
    n_substeps: int,
    hold: str,
) -> MachineState:
    """The jit-compiled core of [`replay`][pmsmjax.recorded.replay.replay]: a scan over the ``N - 1``
    intervals. No input checks.

    **Arguments:**

    - `machine`: a [`PMSMdq`][pmsmjax.machines.pmsm3.PMSMdq]; ``mechanics="imposed"`` if and only if `omega_m`
      is given.
    - `state0`: state at ``t_0``.
    - `dt`: ``(N-1,)`` interval lengths ``t_{k+1} - t_k``, s.
    - `u_dq`: ``(N-1, 2)`` dq voltage held over each interval, V.
    - `omega_m`: ``(N-1,)`` imposed mechanical speed over each interval, rad/s, or ``None``.
    - `load_torque`: ``(N-1,)`` load torque over each interval, N m.
    - `n_substeps`, `hold`: static; RK4 steps per interval, ``"rotor"`` or ``"stator"``.

    Returns the ``(N-1,)`` stacked states at ``t_1 ... t_{N-1}``. Differentiable with respect to the
    motor parameters, voltages and initial state (each interval is checkpointed, so reverse-mode memory
    grows with rows, not sub-steps).
    """

    @jax.checkpoint
    def interval(state: MachineState, xs):
        dt_k, u_k, w_k, tl_k = xs
        if w_k is not None:
            state = MachineState(state.currents, w_k, state.theta_e)
        if hold == "stator":
            inputs = MachineInput(inverse_park(u_k, state.theta_e), tl_k, frame="stator")
        else:
            inputs = MachineInput(u_k, tl_k, frame="rotor")
        state = advance(machine, state, inputs, dt_k, n_substeps)
        return state, state

    _, states = jax.lax.scan(interval, state0, (dt, u_dq, omega_m, load_torque))
    return states


def default_substeps(motor: PMSMParameters, max_dt: float, max_speed_m: float) -> int:
    """Smallest RK4 sub-step count n with ``max_dt / n <= max_stable_substep(max_speed_m)``, s and rad/s."""
    h_max = float(max_stable_substep(PMSMdq(motor), max_speed_m))
    return max(1, math.ceil(max_dt / h_max * (1.0 - 1e-12)))


def replay(
    motor: PMSMParameters,
    time,
    u_dq,
    omega_m=None,
    load_torque=None,
    *,
    hold: str = "rotor",
    n_substeps: int | None = None,
    theta_e0: float = 0.0,
    i_dq0=(0.0, 0.0),
    omega_m0: float = 0.0,
    flux_map=None,
) -> dict[str, np.ndarray]:
    """Run ``motor`` under a recorded voltage sequence; returns ``(N,)`` arrays by
    [`REPLAY_COLUMNS`][pmsmjax.recorded.replay.REPLAY_COLUMNS].

    The voltage of row k is held until row k+1 (in the rotor frame by default, see the module docstring
    for ``hold="stator"``); row k of every output is the state at ``time[k]``, row 0 the initial state.
    The last row's voltage, speed and load are not used (nothing follows them).

    **Arguments:**

    - `motor`: [`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters] (one motor, scalar fields).
    - `time`: ``(N,)`` row times, s, strictly increasing, N >= 2; irregular spacing is fine.
    - `u_dq`: ``(N, 2)`` dq stator voltage ``[u_d, u_q]`` of each row, V.
    - `omega_m`: ``(N,)`` imposed mechanical speed, rad/s (``rpm * pi / 30``), or ``None`` for dynamic
      speed. Imposed speed is reported back unchanged in the ``omega_m`` output.
    - `load_torque`: ``(N,)`` or scalar load torque, N m, used with dynamic speed (default 0).
    - `hold`: ``"rotor"`` (dq-model simulator) or ``"stator"`` (real inverter).
    - `flux_map`: a [`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap]: the saturated machine of the map
      (with ``motor``'s R, J, B, pole pairs) instead of the linear one.
    - `n_substeps`: RK4 steps per row interval. Default: the smallest count keeping the longest interval's
      sub-step within [`max_stable_substep`][pmsmjax.machines.integrate.max_stable_substep] at the largest
      speed (the imposed speed, or for dynamic speed 1.5x the voltage-limited speed
      ``(max|u| + R |T_L| / k_t) / (p_n psi_f)`` and the initial speed). Too small a count is an error.
    - `theta_e0`: electrical angle at ``time[0]``, rad. `i_dq0`: ``(2,)`` dq current at ``time[0]``, A.
    - `omega_m0`: mechanical speed at ``time[0]``, rad/s (dynamic speed only).

    Every input is checked before compiling; bad input raises
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the field and the fix. Outputs are
    float64 NumPy arrays (values computed in the motor's precision).
    """
    if hold not in _HOLDS:
        raise ParameterError(
            f"hold must be 'rotor' (voltage held in the rotor frame, dq-model simulators) or 'stator' "
            f"(held in the stator frame, real inverters), got {hold!r}."
        )
    if not isinstance(motor, PMSMParameters):
        raise ParameterError(
            f"motor must be a PMSMParameters (or use presets.load_motor), got {type(motor).__name__}."
        )
    if any(np.ndim(getattr(motor, f)) != 0 for f in ("R", "L_d", "L_q", "psi_f", "J", "B")):
        raise ParameterError(
            "replay runs one motor: give PMSMParameters with scalar fields (for a batch, jax.vmap "
            "replay_scan)."
        )
    u = np.asarray(u_dq, dtype=np.float64)
    if u.ndim != 2 or u.shape[1] != 2:
        raise ParameterError(f"u_dq must have shape (N, 2) = [u_d, u_q] per row, V; got shape {u.shape}.")
    columns = {"time": np.asarray(time), "u_d": u[:, 0], "u_q": u[:, 1]}
    if omega_m is not None:
        columns["omega_m"] = np.asarray(omega_m)
    if load_torque is not None:
        tl = np.asarray(load_torque, dtype=np.float64)
        columns["T_L"] = np.broadcast_to(tl, u.shape[:1]) if tl.ndim == 0 else tl
    for name in ("time", "omega_m", "T_L"):
        if name in columns and np.ndim(columns[name]) != 1:
            raise ParameterError(
                f"{name} must be a 1-D array with one value per row, got shape {np.shape(columns[name])}."
            )
    cols = check_columns(columns, ("time", "u_d", "u_q"), ("omega_m", "T_L"), source="replay input")
    i0 = np.asarray(i_dq0, dtype=np.float64)
    if i0.shape != (2,) or not np.all(np.isfinite(i0)):
        raise ParameterError(f"i_dq0 must be a finite (2,) [i_d, i_q] in A, got {i_dq0!r}.")
    for name, v in (("theta_e0", theta_e0), ("omega_m0", omega_m0)):
        if np.ndim(v) != 0 or not np.isfinite(float(v)):
            raise ParameterError(f"{name} must be a finite scalar, got {v!r}.")

    t = cols["time"]
    dt = np.diff(t)
    imposed = omega_m is not None
    tl = cols.get("T_L", np.zeros_like(t))
    if imposed:
        max_speed = float(np.max(np.abs(cols["omega_m"])))
    else:
        max_speed = _dynamic_speed_bound(motor, u, tl, float(omega_m0))
    need = default_substeps(motor, float(dt.max()), max_speed)
    auto = n_substeps is None
    if auto:
        n_substeps = need
    elif not isinstance(n_substeps, (int, np.integer)) or isinstance(n_substeps, bool) or n_substeps < 1:
        raise ParameterError(
            f"n_substeps must be a positive int (RK4 steps per row interval), got {n_substeps!r}."
        )
    elif n_substeps < need:
        h_max = float(max_stable_substep(PMSMdq(motor), max_speed))
        raise ParameterError(
            f"n_substeps = {n_substeps} gives a sub-step of {dt.max() / n_substeps:.3g} s on the longest row "
            f"interval ({dt.max():.3g} s), longer than the {h_max:.3g} s the machine's fastest electrical "
            f"rate allows (max of R/L and p_n omega_m at {max_speed:.4g} rad/s): set n_substeps >= {need} "
            "or leave it unset."
        )
    n_substeps = int(n_substeps)

    dtype = motor.R.dtype
    mechanics = "imposed" if imposed else "dynamic"
    if flux_map is None:
        machine = PMSMdq(motor, mechanics=mechanics)
    else:
        from pmsmjax.machines.pmsm_flux_map import PMSMFluxMapdq

        machine = PMSMFluxMapdq(motor, flux_map, mechanics)
    w0 = cols["omega_m"][0] if imposed else omega_m0
    state0 = machine.initial_state(i0, w0, theta_e0)
    f = lambda x: jnp.asarray(x, dtype)
    args = (f(dt), f(u[:-1]), f(cols["omega_m"][:-1]) if imposed else None, f(tl[:-1]))
    for _ in range(3):
        states = replay_scan(machine, state0, *args, n_substeps, hold)
        i_dq = np.concatenate([i0[None], np.asarray(states.currents, np.float64)])
        if imposed:
            omega = cols["omega_m"].copy()
        else:
            omega = np.concatenate([[float(omega_m0)], np.asarray(states.omega_m, np.float64)])
        finite = np.isfinite(i_dq).all(axis=1) & np.isfinite(omega)
        if imposed or not auto or not finite.all():
            break
        # Dynamic speed: the sub-step was chosen for an estimated top speed; if the run went faster, run
        # again with the sub-step the reached speed asks for (rarely needed, the estimate is generous).
        reached = float(np.max(np.abs(omega)))
        more = default_substeps(motor, float(dt.max()), reached)
        if more <= n_substeps:
            break
        n_substeps, max_speed = more, reached
    if not finite.all():
        row = int(np.argmax(~finite))
        raise ParameterError(
            f"replay diverged (non-finite state at row {row}, t = {t[row]:g} s): the speed probably exceeded "
            f"the {max_speed:.4g} rad/s the {n_substeps} sub-steps were chosen for; pass a larger n_substeps."
        )
    if not imposed and not auto:
        reached = float(np.max(np.abs(omega)))
        if default_substeps(motor, float(dt.max()), reached) > n_substeps:
            warnings.warn(
                f"replay reached {reached:.4g} rad/s, where n_substeps = {n_substeps} is beyond the "
                "stable sub-step: the result may be inaccurate; raise n_substeps or leave it unset.",
                stacklevel=2,
            )
    # Row 0 is the given angle, wrapped to [-pi, pi) like every later row (left exact when already there).
    th0 = float(theta_e0) if -np.pi <= theta_e0 < np.pi else float(wrap_angle(float(theta_e0)))
    theta = np.concatenate([[th0], np.asarray(states.theta_e, np.float64)])
    return {"time": t.copy(), "i_d": i_dq[:, 0], "i_q": i_dq[:, 1], "omega_m": omega, "theta_e": theta}


def _dynamic_speed_bound(motor: PMSMParameters, u: np.ndarray, load: np.ndarray, omega0: float) -> float:
    """A generous bound on |omega_m| (rad/s) for dynamic speed, used to choose the sub-step.

    In steady state the back-EMF ``p_n w psi_f`` is at most the voltage plus the resistive drop of the
    current that carries the load, ``|u| + R |T_L| / k_t``; 50 % margin covers the transient overshoot.
    """
    p, psi_f, R = motor.pole_pairs, float(motor.psi_f), float(motor.R)
    u_max = float(np.max(np.hypot(u[:, 0], u[:, 1])))
    if psi_f > 0:
        k_t = 1.5 * p * psi_f
        w_volt = (u_max + R * float(np.max(np.abs(load))) / k_t) / (p * psi_f)
    else:  # a reluctance machine has no back-EMF bound; fall back on the initial speed
        w_volt = 0.0
    return 1.5 * max(w_volt, abs(omega0)) + 1.0


#: What each column replay reads means, for messages.
COLUMN_MEANINGS = {
    "time": "time, s",
    "u_d": "d-axis voltage, V",
    "u_q": "q-axis voltage, V",
    "omega_m": "imposed mechanical speed, rad/s",
    "T_L": "load torque, N m",
    "theta_e": "initial electrical angle, rad",
    "i_d": "d-axis current, A",
    "i_q": "q-axis current, A",
}
#: Time units a log may use (``time_unit``), factor to s.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}


def choose_hold(motor: PMSMParameters, log: dict, **replay_kwargs) -> tuple[str, str]:
    """The hold that reproduces a log's own currents: ``(hold, note)``.

    With ``i_d`` and ``i_q`` over every row, the log is replayed both ways and the hold whose currents
    are closer to the logged ones (RMS over all rows) is chosen, as ``pmsmjax identify`` does by fitting
    both; without them nothing tells the holds apart, and ``"stator"`` (a real inverter; this library's
    own drive) is used.
    """
    if "i_d" not in log or "i_q" not in log:
        return "stator", (
            "hold: stator (the log has no i_d, i_q to tell the holds apart; a dq-model simulator's log needs "
            "--hold rotor)"
        )
    err = {}
    for hold in _HOLDS:
        res = replay(motor, hold=hold, **replay_kwargs)
        err[hold] = float(np.sqrt(np.mean((res["i_d"] - log["i_d"]) ** 2 + (res["i_q"] - log["i_q"]) ** 2)))
    best = min(err, key=err.get)
    other = "stator" if best == "rotor" else "rotor"
    return best, (
        f"hold: {best} (its replay matches the logged currents to {err[best]:.3g} A RMS, the {other} hold "
        f"to {err[other]:.3g} A)"
    )


def replay_file(
    log_path: str | os.PathLike, motor: str | os.PathLike, out_dir: str | os.PathLike, *args, **kwargs
) -> Path:
    """Replay a log file ([`replay_log`][pmsmjax.recorded.replay.replay_log], which takes ``args`` and
    ``kwargs``: the hold, sub-steps, time unit, unit checks and report) and write ``out_dir/replay.csv``;
    returns the path written.

    The output has columns ``time,i_d,i_q,omega_m,theta_e`` (time in s), one row per log row, written
    atomically only after the run succeeded: a failure leaves no (partial) ``replay.csv``.
    """
    result = replay_log(log_path, motor, *args, **kwargs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return write_csv_atomic(out / "replay.csv", result)


#: A step longer than this many median steps is a gap in the log (samples lost, a paused recorder).
GAP_STEPS = 1.5


def check_no_gap(time: np.ndarray, source: str) -> None:
    """Refuse a log whose time column (s) has a gap: a step longer than `GAP_STEPS` median steps. Over a
    gap the recorded voltage would be held for the whole gap and the hold judged on data that is not
    there; ``pmsmjax identify`` and ``observe`` refuse gaps alike."""
    dt = np.diff(np.asarray(time, dtype=float))
    if dt.size == 0:
        return
    med = float(np.median(dt))
    gaps = np.flatnonzero(dt > GAP_STEPS * med)
    if gaps.size:
        row = int(gaps[0]) + 1
        raise ParameterError(
            f"{source}: a gap of {dt[row - 1] * 1e3:.3g} ms before row {row} (t = {time[row]:.6g} s) against "
            f"a median step of {med * 1e3:.3g} ms ({gaps.size} gap(s) in all): cut the log at the gap and "
            "replay each part, or record without gaps."
        )


def _is_duty_log(log_path, columns, dialect) -> bool:
    """Whether the log gives the leg duties ``d_a, d_b, d_c`` (and no ``u_d``): a duty replay."""
    from pmsmjax.io.logs import column_names
    from pmsmjax.io.mapped_logs import resolve_columns

    canonical = ("u_d", "u_q", "d_a", "d_b", "d_c", "U_dc")
    mapped = {k: v for k, v in (columns or {}).items() if k in canonical}
    found, _ = resolve_columns(column_names(log_path, dialect), canonical, mapped, f"log {log_path}")
    return "u_d" not in found and all(c in found for c in ("d_a", "d_b", "d_c"))


def replay_log(
    log_path: str | os.PathLike,
    motor: str | os.PathLike,
    hold: str = DEFAULT_HOLD,
    n_substeps: int | None = None,
    *,
    time_unit: str = "s",
    check_units: bool = True,
    report: list | None = None,
    columns: dict | None = None,
    units: dict | None = None,
    dialect=None,
) -> dict[str, np.ndarray]:
    """Replay a log file; returns ``(N,)`` float64 arrays by
    [`REPLAY_COLUMNS`][pmsmjax.recorded.replay.REPLAY_COLUMNS], in that order.

    **Arguments:**

    - `log_path`: ``.csv``/``.npz``/``.mat`` log with columns ``time`` (s), ``u_d``, ``u_q`` (V) or the leg
      duties ``d_a``, ``d_b``, ``d_c`` with the DC link ``U_dc`` (V; through the averaged inverter with the
      drive file's ``[inverter]`` error and ``[harmonics]``,
      [`pmsmjax.recorded.duty_replay`][pmsmjax.recorded.duty_replay]), and
      optionally ``omega_m`` (imposed speed, mechanical rad/s), ``T_L`` (load torque, N m, dynamic speed)
      and ``theta_e`` (rad), ``i_d``, ``i_q`` (A), whose first row sets the initial state.
    - `motor`: a preset name (``book``, ``book_salient``) or a TOML file with ``R, L_d, L_q, psi_f,
      pole_pairs, J, B`` in SI units (ohm, H, H, Wb, -, kg m^2, N m s).
    - `hold`: ``"auto"`` (default, shared with ``pmsmjax identify``:
      [`choose_hold`][pmsmjax.recorded.replay.choose_hold]), ``"rotor"`` or ``"stator"``; `n_substeps`: as in
      [`replay`][pmsmjax.recorded.replay.replay].
    - `time_unit`: unit of the time column, ``"s"``, ``"ms"`` or ``"us"``.
    - `check_units`: refuse a time step implausible for a drive log (a time in ms read as s) and motor
      values implausible in SI units ([`pmsmjax.spec.plausibility`][pmsmjax.spec.plausibility]).
    - `report`: a list that receives one line per note (the hold chosen, columns not used).
    - `columns`, `units`, `dialect`: the column map, the units map (``time`` as `time_unit`; units in the
      column names count too) and a CSV file's stated dialect
      ([`pmsmjax.io.mapped_logs.read_mapped_log`][pmsmjax.io.mapped_logs.read_mapped_log]).

    Row k is the state at the log's row k (time in s). All input is read and checked before anything is
    compiled. A column that looks like a misspelt one replay reads (``omega`` for ``omega_m``) is refused:
    read as absent it would change what is simulated.
    """
    if hold not in (*_HOLDS, "auto"):
        raise ParameterError(f"hold must be 'auto', 'rotor' or 'stator', got {hold!r}.")
    if time_unit not in TIME_UNITS:
        raise ParameterError(f"time_unit must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}.")
    required, optional = LOG_COLUMNS
    unused: list[str] = []
    units = dict(units or {})
    if time_unit != "s":
        units.setdefault("time", time_unit)
    mot = load_motor(motor, check_units=check_units)
    duty = _is_duty_log(log_path, columns, dialect)
    if duty:
        from pmsmjax.recorded.duty_replay import DUTY_COLUMNS

        if hold == "rotor":
            raise ParameterError(
                f"log {log_path}: duties are held by the inverter in the stator frame, not the rotor's: drop "
                "--hold rotor (or log u_d, u_q of a dq-model simulator)."
            )
        required = ("time", *DUTY_COLUMNS)
    log = read_mapped_log(
        log_path, required, optional, columns=columns, units=units, dialect=dialect,
        pole_pairs=int(mot.pole_pairs), unused=unused,
    )  # fmt: skip
    absent = [c for c in optional if c not in log]
    wrong = misspelt_columns(unused, absent)
    if wrong:
        col, known = wrong[0]
        raise ParameterError(
            f"log {log_path}: column {col!r} is not one replay reads; it looks like {known!r} "
            f"({COLUMN_MEANINGS[known]}), which the log lacks, so it would be simulated without it: rename "
            f"the column to {known!r}, or rename or drop it if it is something else."
        )
    if unused and report is not None:
        report.append(f"columns not used: {', '.join(unused)}")
    from pmsmjax.assemble import spec_flux_map
    from pmsmjax.io.drive_files import drive_spec

    spec = drive_spec(motor, check_units=check_units)
    flux_map = spec_flux_map(spec)  # None without [motor] flux_map
    if check_units:
        tau = min(float(mot.L_d), float(mot.L_q)) / float(mot.R)
        check_time_step(
            float(np.median(np.diff(log["time"]))),
            f"log {log_path}",
            tau,
            how="give --time-unit {unit} (or convert the column to seconds)",
        )
    check_no_gap(log["time"], f"log {log_path}")
    if ("i_d" in log) != ("i_q" in log):
        have, lack = ("i_d", "i_q") if "i_d" in log else ("i_q", "i_d")
        raise ParameterError(
            f"log {log_path} has {have} but not {lack}: give both (row 0 sets the initial current) "
            "or neither."
        )
    if duty:
        from pmsmjax.recorded.duty_replay import replay_duty_log, stator_voltages

        if flux_map is not None:
            raise ParameterError(
                f"log {log_path}: a duty log is replayed on the linear machine; {motor} has a flux map: "
                "replay u_d, u_q instead, or drop [motor] flux_map."
            )
        if report is not None:
            report.append("hold: stator (duties: the inverter holds the stator-frame voltage)")
        if "omega_m" in log:
            top = float(np.max(np.abs(log["omega_m"])))
        else:
            duties = np.stack([log[c] for c in ("d_a", "d_b", "d_c")], axis=1)
            tl = log.get("T_L", np.zeros_like(log["time"]))
            top = _dynamic_speed_bound(mot, stator_voltages(duties, log["U_dc"]), tl, 0.0)
        need = default_substeps(mot, float(np.diff(log["time"]).max()), top)
        if n_substeps is not None and n_substeps < need:
            raise ParameterError(
                f"n_substeps = {n_substeps} is below the {need} RK4 steps per row that the machine's fastest "
                f"rate at {top:.4g} rad/s needs: set n_substeps >= {need} or leave it unset."
            )
        result = replay_duty_log(mot, spec, log, n_substeps or need)
        return {c: result[c] for c in REPLAY_COLUMNS}
    i0 = (log["i_d"][0], log["i_q"][0]) if "i_d" in log else (0.0, 0.0)
    kwargs = dict(
        time=log["time"],
        u_dq=np.stack([log["u_d"], log["u_q"]], axis=1),
        omega_m=log.get("omega_m"),
        load_torque=log.get("T_L"),
        n_substeps=n_substeps,
        theta_e0=float(log["theta_e"][0]) if "theta_e" in log else 0.0,
        i_dq0=i0,
        flux_map=flux_map,
    )
    if hold == "auto":
        hold, note = choose_hold(mot, log, **kwargs)
        if report is not None:
            report.append(note)
    result = replay(mot, hold=hold, **kwargs)
    return {c: result[c] for c in REPLAY_COLUMNS}
