"""The simulation engine: one jit-compiled ``lax.scan`` over control periods.

- The scenario is sampled on the period grid before the scan (one vectorised pass), so the scan body is
  only the drive step.
- Each period is wrapped in ``jax.checkpoint``: reverse-mode AD stores one small carry per period and
  recomputes the sub-steps, so memory grows with periods, not with RK4 stages.
- ``decimate=D`` records the first period of every block of D: an outer scan over blocks, an inner scan
  over the D - 1 unrecorded periods whose record is dead code that XLA removes.
- The scan over periods is a plain ``lax.scan``, not cut into blocks of periods: with the loop limit
  [`pmsmjax.xla_cpu`][pmsmjax.xla_cpu] sets, XLA:CPU compiles the loops of a period into one kernel each, and
  blocks do not change the run time (docs/performance.md, "Engine").
- ``simulate`` checks concrete inputs before compiling (period count, decimation, sub-step length) and
  composes with ``jax.vmap``/``jax.grad``/``jax.jit`` (checks are skipped on traced values).
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from pmsmjax.drive import Drive, DriveState, PeriodInputs, PeriodRecord
from pmsmjax.frames.three_phase import dq_to_abc
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.machines.integrate import max_stable_substep
from pmsmjax.scenarios import Scenario
from pmsmjax.spec.validation import ParameterError, is_concrete
from pmsmjax.trace import Trace

__all__ = ["simulate", "check_simulation", "period_inputs"]


def period_inputs(scenario: Scenario, Ts: float) -> PeriodInputs:
    """Scenario values at every period start ``k Ts``.

    Sampled by integer period index ([`Profile.sample_periods`][pmsmjax.scenarios.Profile.sample_periods]), so
    an event at a whole number of periods lands in that period in float32 as in float64.

    Args:
        scenario: The references and load to sample.
        Ts: Control period, s.

    Returns:
        A [`PeriodInputs`][pmsmjax.drive.PeriodInputs] of ``(N,)`` arrays, ``N`` the scenario's period count.
    """
    n = scenario.n_periods(Ts)
    optional = lambda p: None if p is None else p.sample_periods(n, Ts)
    return PeriodInputs(
        scenario.speed_ref.sample_periods(n, Ts),
        scenario.load_torque.sample_periods(n, Ts),
        scenario.id_ref.sample_periods(n, Ts),
        scenario.iq_ref.sample_periods(n, Ts),
        optional(scenario.measured_iq_perturbation),
        optional(scenario.iq_ref_perturbation),
    )


def check_simulation(drive: Drive, scenario: Scenario, decimate: int = 1) -> None:
    """Refuse inputs that would give a wrong or unstable simulation.

    Checked: the scenario is a whole number of control periods, ``decimate`` divides the period count, the
    bridge accepts the control period, and (for concrete values) the sub-step ``Ts / n_substeps`` is
    within the stable step of the machine's fastest electrical rate at 1.5 times the largest speed
    reference.

    Args:
        drive: The drive to simulate.
        scenario: The scenario to run it through.
        decimate: Record every this many periods.

    Raises:
        ParameterError: For the first check that fails, saying what to change.
    """
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
    drive.bridge.check_period(drive.Ts)  # also for a bridge patched into the drive (no __check_init__ then)
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
    """Simulate ``drive`` through ``scenario``.

    Concrete inputs are checked first ([`check_simulation`][pmsmjax.simulate.check_simulation]); under
    ``jax.vmap``, ``jax.grad`` or ``jax.jit`` the checks of traced values are skipped.

    Args:
        drive: The drive ([`pmsmjax.drive.Drive`][pmsmjax.drive.Drive]).
        scenario: The scenario ([`pmsmjax.scenarios.Scenario`][pmsmjax.scenarios.Scenario]), unbatched;
            ``jax.vmap`` for batches.
        decimate: Record every this many periods (an int dividing the period count).
        initial_state: Start from this state instead of rest.

    Returns:
        A [`Trace`][pmsmjax.trace.Trace] of ``N / decimate`` rows, ``N`` the scenario's period count.

    Raises:
        ParameterError: For inputs that would give a wrong or unstable simulation.
    """
    check_simulation(drive, scenario, decimate)
    return _simulate(drive, scenario, decimate, initial_state)


@eqx.filter_jit
def _simulate(drive: Drive, scenario: Scenario, decimate: int, initial_state) -> Trace:
    xs = period_inputs(scenario, drive.Ts)
    state = drive.init() if initial_state is None else initial_state
    step = jax.checkpoint(lambda d, s, x: d.step(s, x))
    # How to unpack a packed row, kept when the scan traces its step: shapes and dtypes only, no values.
    unravel_of_record = []

    def recorded_step(s, x):
        s, record = step(drive, s, x)
        # One packed vector per period: a single output buffer instead of one per field.
        packed, unravel = ravel_pytree(record)
        unravel_of_record.append(unravel)
        return s, packed

    def unrecorded_step(s, x):
        return step(drive, s, x)[0], None

    if decimate == 1:
        _, packed = jax.lax.scan(recorded_step, state, xs)
    else:
        blocks = jax.tree.map(lambda a: a.reshape((-1, decimate) + a.shape[1:]), xs)

        def block(s, xb):
            s, r = recorded_step(s, jax.tree.map(lambda a: a[0], xb))
            rest = jax.tree.map(lambda a: a[1:], xb)
            s, _ = jax.lax.scan(unrecorded_step, s, rest)
            return s, r

        _, packed = jax.lax.scan(block, state, blocks)
        xs = jax.tree.map(lambda a: a[::decimate], xs)

    rec: PeriodRecord = jax.vmap(unravel_of_record[-1])(packed)
    return trace_from_records(drive, rec, xs, drive.Ts * decimate)


def _torque(drive: Drive, ms, temperature):
    """``(N,)`` electromagnetic torque of the recorded states, N m; with a thermal network, each period's
    from the machine at that period's winding temperature ``temperature (N,)`` (K)."""
    machine = drive.machine
    if temperature is None:
        return jax.vmap(machine.electromagnetic_torque)(ms)
    thermal = drive.thermal

    def warm_torque(state, temperature_k):
        k_r, k_psi = thermal.factors(temperature_k)
        return machine.at_temperature(k_r, k_psi).electromagnetic_torque(state)

    return jax.vmap(warm_torque)(ms, temperature)


def trace_from_records(drive: Drive, rec: PeriodRecord, xs: PeriodInputs, dt: float) -> Trace:
    """Derive every Trace signal from the per-period records in one vectorised pass.

    Args:
        drive: The simulated drive (its machine turns states into currents and torque).
        rec: The stacked per-period records, ``(N, ...)`` leaves.
        xs: The period inputs at the recorded periods.
        dt: Time between recorded rows, s (``Ts`` times the decimation).

    Returns:
        The [`Trace`][pmsmjax.trace.Trace] of the ``N`` recorded periods.
    """
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
        torque=_torque(drive, ms, rec.temperature),
        load_torque=xs.load_torque,
        theta_e_est=theta_e_est,
        omega_m_est=omega_m_est,
        winding_temperature=rec.temperature,
        load_speed=None if ms.shaft is None else ms.shaft[:, 1],
        cogging_torque=_cogging(machine, ms.theta_e),
    )


def _cogging(machine, theta_e):
    """``(N,)`` cogging torque at the recorded angles, N m, or None for a machine without cogging (computed
    from the recorded angle after the scan: no cost per period)."""
    harmonics = getattr(machine, "harmonics", None)
    if harmonics is None or not harmonics.has_cogging:
        return None
    return jax.vmap(harmonics.cogging_torque)(theta_e)
