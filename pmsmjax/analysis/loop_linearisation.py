"""The sampled-data drive linearised about a steady state, with a loop broken at one point.

**The period map.** One control period of the drive ([`Drive.step`][pmsmjax.drive.Drive.step]: sample,
controller, computational delay, modulator, bridge hold and the machine's RK4 sub-steps) is a map
``x_{k+1} = F(x_k, w_k)`` of the drive's state ``x`` and of a scalar perturbation ``w`` held over the period
and injected at a loop's break point:

- ``loop="current"``: ``w`` (A) is added to the q current the controller measures (its own, estimated, rotor
  frame); the signal after the injection is ``v_k = i_q,measured + w_k``;
- ``loop="speed"``: ``w`` (A) is added to the q-current reference after the speed controller (and after its
  held state); ``v_k = i_q* + w_k``.

With the other loop closed, ``y = v - w`` is what the loop returns, ``y = -L v``, so the sensitivity from
``w`` to ``v`` is ``S = 1 / (1 + L)`` and the loop transfer (return ratio) ``L = 1/S - 1`` (Åström and Murray,
*Feedback Systems*, 2nd ed., 2021: the loop transfer, stability margins and the sensitivity functions).
MATLAB's Field Oriented Control Autotuner estimates each loop's frequency response from sinusoidal
perturbations added to that loop's plant input, one loop at a time, and tunes each to a bandwidth and a phase
margin (https://www.mathworks.com/help/mcb/ref/fieldorientedcontrolautotuner.html). The map's Jacobians
``A = dF/dx``, ``B = dF/dw`` and the output's ``C = dv/dx``, ``D = dv/dw`` come from forward-mode AD
through the whole step, so ``S(z) = C (zI - A)^-1 B + D`` at ``z = exp(j w Ts)`` is the exact small-signal
response of the sampled-data loop (delay, PWM hold and sub-steps included), for a
perturbation held over each period and signals sampled at the period starts.

**The rotating angle.** The state's electrical angle ``theta_e`` grows without bound at a steady speed, and
the stator-frame parts of the state (the duties in force and pending, an alpha-beta or abc machine's currents)
turn with it: a steady state is a periodic orbit of ``F``, not a fixed point. In the rotor frame it is one.
The state is expressed as ``z``: the machine's currents in dq (``currents_to_dq`` at the state's angle), the
duties as the dq voltage they command (``park`` of ``commanded_voltage``), the speeds, the shaft, the
controller's floating state and the thermal state, without the angle. ``G(z) = reduce(F(lift(z, 0)))`` (the
period map seen from the rotor, ``reduce`` at the new angle) does not depend on the angle at which ``z`` is
lifted for a machine without position-dependent terms, and a steady state is its fixed point ``z* = G(z*)``,
found by simulating from the state at speed and then a few Newton steps on ``G(z) - z``. The angle itself is
an integrator of the speed and drops out. Lifting puts duties of the same differential voltage with another
common-mode part: the three-phase bridges apply line-to-line voltages only, so the plant sees the same.

**The fundamental wave.** Magnet flux harmonics, cogging torque, an anticogging table and the inverter's
error voltage (with its compensation) make the period map depend on the rotor angle: their steady state is
a periodic orbit in the rotor frame as well. They are periodic disturbances of the loops, not part of their
small-signal gain, so the drive is linearised without them
([`fundamental_wave`][pmsmjax.analysis.loop_linearisation.fundamental_wave]): the margins are those of the
fundamental-wave drive.

Scope (refused otherwise, before compiling): a three-phase cascaded FOC
([`FOC`][pmsmjax.controllers.foc.FOC]) in speed mode with the speed loop every period, on the exact position
sensor, with a modulator; the operating point inside the voltage and current limits (at the limits the loop is
open and a linearisation says nothing).
"""

import dataclasses
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from pmsmjax._types import Array
from pmsmjax.controllers.current_pi import CurrentLoopGains
from pmsmjax.controllers.foc import FOC
from pmsmjax.controllers.speed_pi import SpeedLoopGains
from pmsmjax.drive import Drive, DriveState, PeriodInputs
from pmsmjax.estimators.position_sensors import ExactSensor
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.machines.base import MachineState
from pmsmjax.spec.validation import ParameterError, check_choice, is_concrete

__all__ = [
    "LOOPS",
    "LinearDrive",
    "check_linearisable",
    "linearise",
    "linearise_traced",
    "steady_state",
    "solve_small",
    "operating_state",
    "current_mode",
    "fundamental_wave",
]

Loop = Literal["current", "speed"]
#: The break points (module docstring).
LOOPS = ("current", "speed")
#: Largest share of the voltage and current limits an operating point may use.
LIMIT_SHARE = 0.95


class LinearDrive(eqx.Module):
    """The drive linearised at a steady state with both break points (module docstring):
    ``z_{k+1} = A z_k + B w_k``, ``y_k = C z_k + D w_k``, ``w = [w_current, w_speed]`` (A) the injections,
    ``y = [i_q measured, i_q* of the speed controller]`` (A) what the loops return before them.

    Attributes:
        A: ``(n, n)`` the period map's Jacobian in the rotor frame.
        B: ``(n, 2)`` its derivative in the injections (held over a period).
        C: ``(2, n)`` the returned signals' derivative in the state.
        D: ``(2, 2)`` their derivative in the injections.
        state: ``(n,)`` the steady state ``z*`` (rotor frame).
        residual: ``|G(z*) - z*|``, the fixed point's residual (state units).
        Ts: Control period, s (static).
    """

    A: Array
    B: Array
    C: Array
    D: Array
    state: Array
    residual: Array
    Ts: float = eqx.field(static=True)

    def transfer(self, freq_hz) -> Array:
        """``H = C (zI - A)^-1 B + D`` at ``z = exp(j 2 pi f Ts)``: ``(..., 2, 2)`` complex, ``freq_hz`` Hz of
        any shape."""
        f = jnp.asarray(freq_hz)
        cdtype = jnp.result_type(self.A.dtype, jnp.complex64)
        eye = jnp.eye(self.A.shape[0], dtype=cdtype)

        def one(fk):
            z = jnp.exp(1j * 2.0 * jnp.pi * fk * self.Ts).astype(cdtype)
            x = solve_small(z * eye - self.A.astype(cdtype), self.B.astype(cdtype))
            return self.C.astype(cdtype) @ x + self.D

        return jax.vmap(one)(f.reshape(-1)).reshape(f.shape + (2, 2))

    def sensitivity(self, loop: str, freq_hz) -> Array:
        """``S = 1 / (1 + L)`` of ``loop`` at ``freq_hz`` (Hz): from its injection to the signal after it.

        ``"speed"``: the current loop closed, ``S = 1 + H_ss``. ``"current"``: the speed loop opened (its
        output held: ``w_speed = -y_speed``), ``S = 1 + H_cc - H_cs H_sc / (1 + H_ss)``; complex.
        """
        check_choice("loop", loop, LOOPS)
        H = self.transfer(freq_hz)
        if loop == "speed":
            return 1.0 + H[..., 1, 1]
        return 1.0 + H[..., 0, 0] - H[..., 0, 1] * H[..., 1, 0] / (1.0 + H[..., 1, 1])

    def loop_transfer(self, loop: str, freq_hz) -> Array:
        """The loop transfer (return ratio) ``L = 1/S - 1`` of ``loop`` at ``freq_hz`` (Hz); complex."""
        return 1.0 / self.sensitivity(loop, freq_hz) - 1.0

    def spectral_radius(self) -> Array:
        """Largest ``|eigenvalue|`` of ``A``: the closed loop (both loops closed) is stable below 1. NumPy
        on concrete values (one or a batch ``(..., n, n)``), not traced."""
        return np.max(np.abs(np.linalg.eigvals(np.asarray(self.A, dtype=np.float64))), axis=-1)


def solve_small(M: Array, b: Array) -> Array:
    """``M^-1 b`` for a small ``M (n, n)`` and ``b (n, k)`` (real or complex) by Gauss-Jordan elimination
    with partial pivoting, written out in array operations (``n`` steps, no LAPACK call): XLA:CPU runs a
    loop that contains a LAPACK custom call as one kernel under pmsmjax's small-loop setting
    ([`pmsmjax.xla_cpu`][pmsmjax.xla_cpu]), and such a loop (these Newton steps, and their reverse-mode
    transpose) was seen to stall on a loaded 2-core machine."""
    n = M.shape[0]
    Ab = jnp.concatenate([M, b], axis=1)
    rows = jnp.arange(n)
    for k in range(n):
        p = jnp.argmax(jnp.where(rows >= k, jnp.abs(Ab[:, k]), -1.0))
        swapped = Ab.at[k].set(Ab[p]).at[p].set(Ab[k])
        row = swapped[k] / swapped[k, k]
        Ab = (swapped - jnp.outer(swapped[:, k], row)).at[k].set(row)
    return Ab[:, n:]


def check_linearisable(drive: Drive, speed_m, load_nm, where: str = "") -> None:
    """Refuse a drive or an operating point the linearisation does not serve (module docstring's scope).

    Args:
        drive: The drive.
        speed_m: Operating speed, mechanical rad/s.
        load_nm: Load torque, N m.
        where: How the message names the operating point's source (a flag, a table).

    Raises:
        ParameterError: For a drive outside the scope, or an operating point at or beyond
            ``LIMIT_SHARE`` of the voltage or current limit (estimated from the plant's steady-state dq
            equations with ``i_d = 0``).
    """
    c = drive.controller
    if not isinstance(c, FOC) or drive.machine.n_phases != 3:
        raise ParameterError(
            f"loop margins are computed for the three-phase FOC drive (control pi), not for "
            f"{type(c).__name__} on {drive.machine.n_phases} phases: build the drive with control 'pi'."
        )
    if not (isinstance(c.speed, SpeedLoopGains) and isinstance(c.current, CurrentLoopGains)):
        raise ParameterError(
            f"loop margins are computed for the PI speed and current loops (control 'pi'), not for "
            f"{type(c.speed).__name__} and {type(c.current).__name__}: build the drive with control 'pi'."
        )
    if c.mode != "speed" or c.speed_divider != 1:
        raise ParameterError(
            f"loop margins need the FOC in speed mode with the speed loop every period (mode "
            f"{c.mode!r}, speed_divider {c.speed_divider}): use mode='speed', speed_divider=1."
        )
    if not isinstance(drive.estimator, ExactSensor):
        raise ParameterError(
            f"loop margins are computed on the exact position sensor, not {type(drive.estimator).__name__} "
            "(its state turns with the rotor): linearise the sensored drive."
        )
    m = drive.machine.motor
    values = (speed_m, load_nm, m.psi_f, m.R, m.L_q, m.B, drive.bridge.u_dc, c.current_limit)
    if not all(is_concrete(v) for v in values):
        return
    speed, load = float(speed_m), float(load_nm)
    k_t = 1.5 * float(m.pole_pairs) * float(np.max(m.psi_f))
    i_q = (abs(load) + float(np.max(m.B)) * abs(speed)) / k_t
    w_e = float(m.pole_pairs) * abs(speed)
    u = np.hypot(float(np.max(m.R)) * i_q + w_e * float(np.max(m.psi_f)), w_e * float(np.max(m.L_q)) * i_q)
    u_max = float(np.min(drive.voltage_limit()))
    source = f" ({where})" if where else ""
    if u >= LIMIT_SHARE * u_max:
        raise ParameterError(
            f"the operating point{source} {speed:.4g} rad/s, {load:.4g} N m needs {u:.4g} V of the "
            f"{u_max:.4g} V the modulator gives: the current loop would sit on its voltage limit, where a "
            "linearisation is meaningless; choose a lower speed or load."
        )
    limit = float(np.min(c.current_limit))
    if i_q >= LIMIT_SHARE * limit:
        raise ParameterError(
            f"the operating point{source} {load:.4g} N m needs {i_q:.4g} A of the {limit:.4g} A current "
            "limit: the speed loop would sit on its limit, where a linearisation is meaningless; choose a "
            "lower load."
        )


def fundamental_wave(drive: Drive) -> Drive:
    """``drive`` without its angle-dependent parts (module docstring): the machine's magnet flux harmonics
    and cogging, the controller's anticogging table and dead-time compensation, the averaged bridge's dead
    time and device drop."""
    from pmsmjax.assemble import with_parts
    from pmsmjax.inverters.averaged import AveragedBridge

    parts = {}
    if getattr(drive.machine, "harmonics", None) is not None:
        parts["machine.harmonics"] = None
    c = drive.controller
    if isinstance(c, FOC) and (c.anticogging is not None or c.dead_time_compensation is not None):
        parts["controller"] = dataclasses.replace(c, anticogging=None, dead_time_compensation=None)
    b = drive.bridge
    if isinstance(b, AveragedBridge) and b.voltage_error is not None:
        parts["bridge"] = AveragedBridge(b.u_dc, b.unroll_substeps)
    drive = with_parts(drive, parts)
    return drive


def _inputs(drive: Drive, speed_m, load_nm, w_current=None, w_speed=None) -> PeriodInputs:
    """Constant inputs at the operating point, with the injections (A) where given."""
    dtype = drive.machine.motor.R.dtype
    s = lambda v: None if v is None else jnp.asarray(v, dtype)
    return PeriodInputs(s(speed_m), s(load_nm), s(0.0), s(0.0), s(w_current), s(w_speed))


def _split(drive: Drive, state: DriveState):
    """``(rotor-frame parts (a dict pytree), the controller state's static part)``."""
    ms = state.machine
    th = ms.theta_e
    volts = lambda d: park(drive.bridge.commanded_voltage(d), th)
    controller, static = eqx.partition(state.controller, eqx.is_inexact_array)
    parts = {
        "i_dq": drive.machine.currents_to_dq(ms.currents, th),
        "omega_m": ms.omega_m,
        "shaft": ms.shaft,
        "estimator": state.estimator,
        "controller": controller,
        "u_pending": volts(state.pending_duties),
        "u_last": volts(state.last_duties),
        "thermal": state.thermal,
    }
    return parts, static


def _join(drive: Drive, parts: dict, static, theta_e) -> DriveState:
    """The drive state whose rotor-frame parts are ``parts``, at the electrical angle ``theta_e`` (rad)."""
    duties = lambda u: drive.modulator.duties(inverse_park(u, theta_e), drive.bridge.u_dc)
    i = drive.machine.currents_from_dq(parts["i_dq"], theta_e)
    ms = MachineState(i, parts["omega_m"], jnp.asarray(theta_e, parts["omega_m"].dtype), parts["shaft"])
    controller = eqx.combine(parts["controller"], static)
    return DriveState(
        ms,
        parts["estimator"],
        controller,
        duties(parts["u_pending"]),
        duties(parts["u_last"]),
        parts["thermal"],
    )


def steady_state(drive: Drive, speed_m, load_nm, settle_periods: int = 2000) -> DriveState:
    """The drive's state after ``settle_periods`` periods at a constant speed reference (rad/s) and load
    (N m), from the state at speed with the speed loop's no-load integral: the start of the Newton steps
    of [`linearise`][pmsmjax.analysis.loop_linearisation.linearise] (no gradient flows through it)."""
    state = drive.init(speed_m=speed_m)
    speed_state = drive.controller.speed.steady_state(state.controller.speed, speed_m)
    state = dataclasses.replace(state, controller=dataclasses.replace(state.controller, speed=speed_state))
    x = _inputs(drive, speed_m, load_nm)

    def body(s, _):
        return drive.step(s, x)[0], None

    state, _ = jax.lax.scan(body, state, None, length=settle_periods)
    return jax.lax.stop_gradient(state)


def linearise(
    drive: Drive,
    speed_m,
    load_nm,
    settle_periods: int = 500,
    newton_steps: int = 4,
    check: bool = True,
) -> LinearDrive:
    """The drive linearised at the steady state of the speed reference ``speed_m`` (mechanical rad/s) and
    load ``load_nm`` (N m), with both break points (module docstring).

    One forward-mode Jacobian of the period map in the state and both injections serves the Newton steps
    to the fixed point and, at the last of them, ``(A, B, C, D)``.

    Args:
        drive: The drive.
        speed_m: Operating speed, mechanical rad/s.
        load_nm: Load torque, N m.
        settle_periods: Periods simulated towards the steady state before the Newton steps.
        newton_steps: Newton steps to the fixed point (differentiable: at a converged point the gradient is
            the implicit one).
        check: Run [`check_linearisable`][pmsmjax.analysis.loop_linearisation.check_linearisable] first
            (skipped for traced values anyway).

    Returns:
        The [`LinearDrive`][pmsmjax.analysis.loop_linearisation.LinearDrive].

    Raises:
        ParameterError: From the check.
    """
    if check:
        check_linearisable(drive, speed_m, load_nm)
    dtype = drive.machine.motor.R.dtype
    return linearise_traced(
        drive, jnp.asarray(speed_m, dtype), jnp.asarray(load_nm, dtype), settle_periods, newton_steps
    )


def linearise_traced(drive: Drive, speed_m, load_nm, settle_periods: int = 500, newton_steps: int = 4):
    """[`linearise`][pmsmjax.analysis.loop_linearisation.linearise] without the check, for use inside
    ``jax.jit``, ``jax.vmap`` and ``jax.grad`` (compiled with the caller)."""
    drive = fundamental_wave(drive)
    parts, static = _split(drive, steady_state(drive, speed_m, load_nm, settle_periods))
    z0, unravel = ravel_pytree(parts)
    n = z0.shape[0]
    dtype = z0.dtype

    def lift(zz):
        return _join(drive, unravel(zz), static, 0.0)

    def f(zw):
        """``[z_next, y]`` of the period map at ``zw = [z, w_current, w_speed]``."""
        zz, w_c, w_s = zw[:n], zw[n], zw[n + 1]
        state = lift(zz)
        x = _inputs(drive, speed_m, load_nm, w_c, w_s)
        new, record = drive.step(state, x)
        sample = drive.sample(state.machine, state.last_duties)
        y = jnp.stack([park(sample.i_ab, state.machine.theta_e)[1], record.i_dq_ref[1] - w_s])
        return jnp.concatenate([ravel_pytree(_split(drive, new)[0])[0], y])

    eye = jnp.eye(n, dtype=dtype)
    basis = jnp.eye(n + 2, dtype=dtype)

    def newton(zz, _):
        zw = jnp.concatenate([zz, jnp.zeros(2, dtype)])
        out, jvp = jax.linearize(f, zw)
        J = jax.vmap(jvp, out_axes=1)(basis)
        r = out[:n] - zz
        return zz - solve_small(J[:n, :n] - eye, r[:, None])[:, 0], (J, jnp.linalg.norm(r), zz)

    # newton_steps updates, and one more pass for the Jacobian at the last point (its update unused)
    _, (Js, residuals, zs) = jax.lax.scan(newton, z0, None, length=newton_steps + 1)
    J = Js[-1]
    return LinearDrive(J[:n, :n], J[:n, n:], J[n:, :n], J[n:, n:], zs[-1], residuals[-1], drive.Ts)


def operating_state(drive: Drive, lin: LinearDrive, settle_periods: int = 500) -> DriveState:
    """The drive's state at the steady state ``lin.state`` (at electrical angle 0), e.g. to start a
    simulation there; ``settle_periods`` as given to
    [`linearise`][pmsmjax.analysis.loop_linearisation.linearise] (it fixes the state's layout only)."""
    dtype = drive.machine.motor.R.dtype
    template = jax.eval_shape(
        lambda d: steady_state(d, jnp.zeros((), dtype), jnp.zeros((), dtype), settle_periods), drive
    )
    template = jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype), template)
    parts, static = _split(drive, template)
    unravel = ravel_pytree(parts)[1]
    return _join(drive, unravel(lin.state), static, 0.0)


def current_mode(drive: Drive) -> Drive:
    """``drive`` with its FOC in current mode: the speed loop opened, ``i_q*`` from the scenario."""
    from pmsmjax.assemble import with_parts

    return with_parts(drive, {"controller": dataclasses.replace(drive.controller, mode="current")})
