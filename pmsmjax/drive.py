"""A drive: controller, modulator, bridge and machine composed into one sampled-data step.

One step is one control (PWM) period ``Ts``:

1. With imposed speed, the shaft speed is set from the scenario (a dynamometer).
2. Measurements are sampled at the period start (currents in the stator frame, speed, angle).
3. The controller computes a stator-frame voltage command; the modulator turns it into duties.
4. With ``computation_delay`` the duties computed now are applied in the *next* period (as on a DSP
   that updates its compare registers at the period boundary); the controller's inverse Park then
   leads by 1.5 periods instead of 0.5, and it compensates the delay in its current loop.
5. The bridge integrates the machine over the period with ``n_substeps`` RK4 steps.
"""

import equinox as eqx
import jax.numpy as jnp

from ._types import Array
from .controllers.foc import FOC, FOCState, Measurement, References
from .frames import inverse_park
from .inverters.base import AbstractBridge, AbstractModulator
from .machines.base import AbstractMachine, MachineState
from .validation import ParameterError, check_positive


class PeriodInputs(eqx.Module):
    """Scenario values for one period (sampled at its start): speed ref rad/s, load N m, id/iq refs A."""

    speed_ref: Array
    load_torque: Array
    id_ref: Array
    iq_ref: Array


class DriveState(eqx.Module):
    machine: MachineState
    controller: FOCState
    pending_duties: Array  # (3,) duties to apply this period when there is a computational delay


class PeriodRecord(eqx.Module):
    """What the scan keeps per period; everything else in a Trace is derived from it afterwards.

    Kept small on purpose: each extra scan output costs XLA:CPU a separate per-period write, which was
    measured to cost as much as the drive step itself (benchmarks/bench_core.py).
    """

    machine: MachineState  # state at the period start (sampling instant)
    duties: Array  # (3,) leg duties applied during the period
    u_dq_ref: Array  # (2,) V, controller voltage command
    i_dq_ref: Array  # (2,) A, current reference


class Drive(eqx.Module):
    """A complete drive.

    **Arguments:**

    - `machine`, `controller`, `modulator`, `bridge`: the blocks.
    - `Ts`: control and PWM period, s (static).
    - `n_substeps`: RK4 steps per period for the machine (static).
    - `computation_delay`: apply each period's command one period later (static).
    """

    machine: AbstractMachine
    controller: FOC
    modulator: AbstractModulator
    bridge: AbstractBridge
    Ts: float = eqx.field(static=True, default=1e-4)
    n_substeps: int = eqx.field(static=True, default=10)
    computation_delay: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        check_positive("Drive.Ts (control period)", self.Ts, "s")
        if not isinstance(self.n_substeps, int) or self.n_substeps < 1:
            raise ParameterError(f"Drive.n_substeps must be an int >= 1, got {self.n_substeps!r}.")
        self.bridge.check_period(self.Ts)

    def init(self, speed_m=0.0, theta_e=0.0) -> DriveState:
        """State at rest (or at the given speed, rad/s, and angle, rad) with zero currents."""
        machine_state = self.machine.initial_state((0.0, 0.0), speed_m, theta_e)
        dtype = machine_state.omega_m.dtype
        return DriveState(machine_state, self.controller.init(), jnp.full((3,), 0.5, dtype))

    def step(self, state: DriveState, x: PeriodInputs) -> tuple[DriveState, PeriodRecord]:
        ms = state.machine
        if self.machine.mechanics == "imposed":
            ms = MachineState(ms.currents, jnp.asarray(x.speed_ref, ms.omega_m.dtype), ms.theta_e)
        i_ab = inverse_park(self.machine.currents_dq(ms), ms.theta_e)
        meas = Measurement(i_ab, ms.omega_m, ms.theta_e)
        refs = References(x.speed_ref, x.id_ref, x.iq_ref)
        u_max = self.modulator.linear_limit(self.bridge.u_dc)
        ctrl_state, out = self.controller.step(
            state.controller, meas, refs, self.Ts, u_max, self.computation_delay
        )
        new_duties = self.modulator.duties(out.u_ab_ref, self.bridge.u_dc)
        duties = state.pending_duties if self.computation_delay else new_duties
        ms_next, _ = self.bridge.advance(self.machine, ms, duties, x.load_torque, self.Ts, self.n_substeps)
        record = PeriodRecord(ms, duties, out.u_dq_ref, out.i_dq_ref)
        return DriveState(ms_next, ctrl_state, new_duties), record
