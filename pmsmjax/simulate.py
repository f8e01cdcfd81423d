"""The simulation engine: one jit-compiled ``lax.scan`` over control periods.

- The scenario is sampled on the period grid before the scan (one vectorised pass), so the scan body is
  only the drive step.
- Each period is wrapped in ``jax.checkpoint``: reverse-mode AD stores one small carry per period and
  recomputes the sub-steps, so memory grows with periods, not with RK4 stages.
- ``decimate=D`` records the first period of every block of D: an outer scan over blocks, an inner scan
  over the D - 1 unrecorded periods whose record is dead code that XLA removes.
- Every scan over periods runs in blocks small enough for XLA:CPU to execute the loop body sequentially
  (:func:`scan_in_blocks`): a body that touches any buffer over 512 bytes, such as the whole record or the
  whole input, is run as a task graph on the thread pool, which cost the book drive 40 % of its run time.
- ``simulate`` checks concrete inputs before compiling (period count, decimation, sub-step length) and
  composes with ``jax.vmap``/``jax.grad``/``jax.jit`` (checks are skipped on traced values).
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from pmsmjax.checks.validation import ParameterError, is_concrete
from pmsmjax.drive import Drive, DriveState, PeriodInputs, PeriodRecord
from pmsmjax.frames.three_phase import dq_to_abc
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.machines.integrate import max_stable_substep
from pmsmjax.scenarios import Scenario
from pmsmjax.trace import Trace

__all__ = ["simulate", "check_simulation", "period_inputs", "scan_in_blocks"]

#: Largest buffer (bytes) a loop body may touch and still be executed sequentially by XLA:CPU's thunk
#: executor (``ThunkExecutor::Options::execute_sequential_buffer_threshold`` in
#: xla/backends/cpu/runtime/thunk_executor.h, fixed at 512 in jax 0.10; no flag sets it).
SEQUENTIAL_BUFFER_BYTES = 512


def period_inputs(scenario: Scenario, Ts: float) -> PeriodInputs:
    """Scenario values at every period start ``k Ts``: a PeriodInputs of ``(N,)`` arrays.

    Sampled by integer period index (:meth:`Profile.sample_periods`), so an event at a whole number of
    periods lands in that period in float32 as in float64.
    """
    n = scenario.n_periods(Ts)
    return PeriodInputs(
        scenario.speed_ref.sample_periods(n, Ts),
        scenario.load_torque.sample_periods(n, Ts),
        scenario.id_ref.sample_periods(n, Ts),
        scenario.iq_ref.sample_periods(n, Ts),
    )


def check_simulation(drive: Drive, scenario: Scenario, decimate: int = 1) -> None:
    """Raise :class:`ParameterError` for inputs that would give a wrong or unstable simulation."""
    n_exact = scenario.duration_s / drive.Ts
    n = int(round(n_exact))
    if n < 1 or abs(n_exact - n) > 1e-6 * max(n, 1):
        raise ParameterError(
            f"Scenario.duration_s = {scenario.duration_s} s is not a whole number of control periods "
            f"Ts = {drive.Ts} s: make the duration a multiple of Ts."
        )
    if not isinstance(decimate, int) or decimate < 1 or n % decimate:
        raise ParameterError(
            f"decimate = {decimate!r} must be a positive int dividing the {n} periods of the scenario."
        )
    drive.bridge.check_period(drive.Ts)  # also for a bridge swapped in with eqx.tree_at (no __check_init__)
    values = scenario.speed_ref.values
    motor = drive.machine.motor
    if all(is_concrete(x) for x in (values, motor.R, motor.L_d, motor.L_q)):
        # Allow 50 % overshoot above the largest reference when judging the fastest electrical rate.
        max_speed = 1.5 * float(np.max(np.abs(np.asarray(values)))) + 1.0
        h_max = max_stable_substep(motor, max_speed)
        h = drive.Ts / drive.n_substeps
        if h > h_max:
            need = math.ceil(drive.Ts / h_max)
            raise ParameterError(
                f"sub-step Ts/n_substeps = {h:.3g} s is too long for the machine's fastest electrical "
                f"rate (max of R/L and omega_e, limit {h_max:.3g} s): set Drive.n_substeps >= {need}."
            )


def simulate(
    drive: Drive,
    scenario: Scenario,
    *,
    decimate: int = 1,
    initial_state: DriveState | None = None,
) -> Trace:
    """Simulate ``drive`` through ``scenario``; returns a :class:`Trace` of ``N / decimate`` rows.

    **Arguments:**

    - `drive`: :class:`pmsmjax.drive.Drive`.
    - `scenario`: :class:`pmsmjax.scenarios.Scenario` (unbatched; ``jax.vmap`` for batches).
    - `decimate`: record every this many periods (int dividing the period count).
    - `initial_state`: start from this state instead of rest.
    """
    check_simulation(drive, scenario, decimate)
    return _simulate(drive, scenario, decimate, initial_state)


@eqx.filter_jit
def _simulate(drive: Drive, scenario: Scenario, decimate: int, initial_state) -> Trace:
    xs = period_inputs(scenario, drive.Ts)
    state = drive.init() if initial_state is None else initial_state
    step = jax.checkpoint(lambda d, s, x: d.step(s, x))
    # The record's layout (to unpack the packed rows) from shapes alone: no extra traced step.
    record_shape = jax.eval_shape(drive.step, state, jax.tree.map(lambda a: a[0], xs))[1]
    _, unravel = ravel_pytree(jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), record_shape))
    leaves = jax.tree.leaves(record_shape)
    row_bytes = sum(leaf.size for leaf in leaves) * jnp.result_type(*leaves).itemsize
    input_bytes = max(a.dtype.itemsize for a in jax.tree.leaves(xs))  # one period of one input

    def recorded_step(s, x):
        s, record = step(drive, s, x)
        # One packed vector per period: a single output buffer instead of one per field.
        return s, ravel_pytree(record)[0]

    def unrecorded_step(s, x):
        return step(drive, s, x)[0], None

    if decimate == 1:
        _, packed = scan_in_blocks(recorded_step, state, xs, row_bytes)
    else:
        blocks = jax.tree.map(lambda a: a.reshape((-1, decimate) + a.shape[1:]), xs)

        def block(s, xb):
            s, r = recorded_step(s, jax.tree.map(lambda a: a[0], xb))
            rest = jax.tree.map(lambda a: a[1:], xb)
            s, _ = scan_in_blocks(unrecorded_step, s, rest, input_bytes)
            return s, r

        _, packed = scan_in_blocks(block, state, blocks, max(row_bytes, decimate * input_bytes))
        xs = jax.tree.map(lambda a: a[::decimate], xs)

    rec: PeriodRecord = jax.vmap(unravel)(packed)
    return trace_from_records(drive, rec, xs, drive.Ts * decimate)


def block_length(n: int, bytes_per_step: int) -> int:
    """The largest divisor ``B`` of ``n`` steps whose buffers of ``B`` steps (``B * bytes_per_step``)
    stay within :data:`SEQUENTIAL_BUFFER_BYTES`; at least 1."""
    fitting = max(SEQUENTIAL_BUFFER_BYTES // max(bytes_per_step, 1), 1)
    return max(b for b in range(1, min(n, fitting) + 1) if n % b == 0)


def scan_in_blocks(f, init, xs, bytes_per_step: int):
    """``jax.lax.scan(f, init, xs)`` as an outer scan over blocks of ``B`` steps and an inner scan over
    the steps of a block (same results, same order of operations).

    ``bytes_per_step``: the largest per-step slice, in bytes, of any one input or output array (an input
    scalar: its itemsize; a packed record row: its length times its itemsize). ``B`` is the largest
    divisor of the step count with ``B * bytes_per_step <= 512`` (:func:`block_length`).

    Why: XLA:CPU runs a loop body sequentially on the calling thread only if every buffer it touches is
    at most 512 bytes (:data:`SEQUENTIAL_BUFFER_BYTES`); otherwise it runs the body's kernels as a task
    graph, handing independent kernels to its thread pool. A drive period is some forty small kernels on
    scalars, so the hand-offs cost more than the arithmetic: a flat scan over 4000 periods, which slices
    the ``(4000,)`` inputs and writes the ``(4000, 11)`` record, ran the book drive at 1.5-2.0 us per
    period, the same scan in blocks of 10 at 0.9-1.0 us (float32, 2-core AMD EPYC;
    benchmarks/engine_cost_profile.py). Only the outer body, one iteration per block, touches the whole
    arrays.
    """
    n = jax.tree.leaves(xs)[0].shape[0]
    b = block_length(n, bytes_per_step)
    if b in (1, n):  # nothing to gain: one step per block, or the whole scan already fits
        return jax.lax.scan(f, init, xs)
    blocks = jax.tree.map(lambda a: a.reshape((n // b, b) + a.shape[1:]), xs)
    carry, ys = jax.lax.scan(lambda c, xb: jax.lax.scan(f, c, xb), init, blocks)
    return carry, jax.tree.map(lambda y: y.reshape((n,) + y.shape[2:]), ys)


def trace_from_records(drive: Drive, rec: PeriodRecord, xs: PeriodInputs, dt: float) -> Trace:
    """Derive every Trace signal from the per-period records in one vectorised pass."""
    machine = drive.machine
    ms = rec.machine
    i_dq = jax.vmap(machine.currents_dq)(ms)
    n = i_dq.shape[0]
    if rec.estimate is None:  # the exact sensor: the estimate is the plant's angle and speed
        theta_e_est, omega_m_est = ms.theta_e, ms.omega_m
    else:
        theta_e_est, omega_m_est = rec.estimate[:, 0], rec.estimate[:, 1]
    return Trace(
        t=jnp.arange(n, dtype=i_dq.dtype) * dt,
        omega_m=ms.omega_m,
        speed_ref=xs.speed_ref,
        theta_e=ms.theta_e,
        i_dq=i_dq,
        i_dq_ref=rec.i_dq_ref,
        i_abc=dq_to_abc(i_dq, ms.theta_e) if machine.n_phases == 3 else jax.vmap(machine.phase_currents)(ms),
        u_dq_ref=rec.u_dq_ref,
        u_abc=(
            phase_voltages(rec.duties, drive.bridge.u_dc)
            if machine.n_phases == 3
            else drive.bridge.phase_voltages(rec.duties)
        ),
        duties=rec.duties,
        torque=jax.vmap(machine.electromagnetic_torque)(ms),
        load_torque=xs.load_torque,
        theta_e_est=theta_e_est,
        omega_m_est=omega_m_est,
    )
