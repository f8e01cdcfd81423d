"""A drive: estimator, controller, modulator, bridge and machine composed into one sampled-data step.

One step is one control period ``Ts``:

1. With imposed speed, the shaft speed is set from the scenario (a dynamometer).
2. **Sample** at the period start: phase currents ``(n,)`` and their alpha-beta components as the
   current sensors read them (``current_sensor``; exact by default), the DC voltage, the voltage
   commanded over the last period, and the ideal shaft sensor
   ([`pmsmjax.signals.Sample`][pmsmjax.signals.Sample]).
3. **Estimator** -> angle and speed (and, for HF-injection estimators, an injection voltage added to the
   controller's voltage command and the carrier-free current the controller gets instead of ``i_ab``).
4. **Controller** -> a stator-frame voltage for the **modulator** (``command_kind == "voltage"``) or
   leg switch states (``"switches"``, no modulator); both become ``(n,)`` leg duties (switch states are
   duties of 0 or 1 held over the period). Which one is a class constant: no runtime branch.
5. With ``computation_delay`` the duties computed now are applied in the *next* period (as on a DSP that
   updates its compare registers at the period boundary).
6. The **bridge** integrates the **machine** over the period (``n_substeps`` RK4 steps).
7. With a **thermal** network ([`WindingThermal`][pmsmjax.machines.thermal.WindingThermal]), the machine is
   integrated at the winding temperature of the period start (its ``R(T)``, ``psi_f(T)``), and the
   temperature is then advanced once over the period by the period's copper loss (not in the RK4 sub-steps:
   the module [`pmsmjax.machines.thermal`][pmsmjax.machines.thermal] says why). Absent (the default), the
   step is the same program as without the field.

Every block is a field of the drive, so ``simulate``, ``jax.vmap``, ``jax.grad``, tuning and Monte Carlo
work on any combination without a second engine.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractController
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.current_sensors import AbstractCurrentSensor, IdealCurrentSensor
from pmsmjax.estimators.position_sensors import ExactSensor
from pmsmjax.frames.three_phase import inverse_park
from pmsmjax.inverters.base import AbstractBridge, AbstractModulator
from pmsmjax.machines.base import AbstractMachine, MachineState
from pmsmjax.machines.thermal import WindingThermal
from pmsmjax.signals import References, Sample
from pmsmjax.spec.validation import ParameterError, check_positive


class PeriodInputs(eqx.Module):
    """Scenario values for one period, sampled at its start (leaves ``(N,)`` when stacked over periods).

    Attributes:
        speed_ref: Speed reference, rad/s (mechanical).
        load_torque: Load torque, N m.
        id_ref: d-axis current reference, A.
        iq_ref: q-axis current reference, A.
        measured_iq_perturbation: A, added to the q current the controller measures (the current loop's
            break point), or None.
        iq_ref_perturbation: A, added to the q-current reference after the speed controller (the speed
            loop's break point), or None.
    """

    speed_ref: Array
    load_torque: Array
    id_ref: Array
    iq_ref: Array
    measured_iq_perturbation: Array | None = None
    iq_ref_perturbation: Array | None = None


class DriveState(eqx.Module):
    """The drive's state at a period boundary (the carry of the simulation's scan).

    Attributes:
        machine: The machine's state.
        estimator: The estimator's state (``None`` for the exact sensor).
        controller: The controller's state.
        pending_duties: ``(n,)`` duties to apply this period when there is a computational delay.
        last_duties: ``(n,)`` duties applied during the last period (the controller knows them).
        thermal: ``(2,)`` the thermal network's state (winding rise above ambient, K, and its summation
            compensation, K), or ``None`` without a thermal network.
    """

    machine: MachineState
    estimator: object  # the estimator's state (None for the exact sensor)
    controller: object  # the controller's state
    pending_duties: Array  # (n,) duties to apply this period when there is a computational delay
    last_duties: Array  # (n,) duties applied during the last period (the controller knows them)
    thermal: Array | None = None  # (2,) K, winding rise above ambient and its compensation, or None


class PeriodRecord(eqx.Module):
    """What the scan keeps per period; everything else in a Trace is derived from it afterwards.

    Kept small on purpose: each extra scan output costs XLA:CPU a separate per-period write, which can
    cost as much as the drive step itself (docs/performance.md, "Engine"). The estimate is kept only when
    it can differ from the plant (not for the exact sensor).

    Attributes:
        machine: The machine's state at the period start (the sampling instant).
        duties: ``(n,)`` leg duties applied during the period.
        u_dq_ref: ``(2,)`` controller voltage command, V.
        i_dq_ref: ``(2,)`` current reference, A.
        estimate: ``(2,)`` estimated electrical angle (rad) and mechanical speed (rad/s), or ``None``.
        temperature: Winding temperature at the period start, K, or ``None`` without a thermal network.
    """

    machine: MachineState  # state at the period start (sampling instant)
    duties: Array  # (n,) leg duties applied during the period
    u_dq_ref: Array  # (2,) V, controller voltage command
    i_dq_ref: Array  # (2,) A, current reference
    estimate: Array | None  # (2,) estimated electrical angle rad and mechanical speed rad/s, or None
    temperature: Array | None = None  # K, winding temperature at the period start, or None


class Drive(eqx.Module):
    """A complete drive.

    Args:
        machine: The plant.
        controller: The controller.
        modulator: Stator voltage -> leg duties; ``None`` for a controller that commands switch states.
        bridge: The inverter bridge, which integrates the machine over a period.
        Ts: Control and PWM period, s (static).
        n_substeps: RK4 steps per period for the machine (static).
        computation_delay: Apply each period's command one period later (static).
        estimator: Angle and speed for the controller; default the exact sensor.
        current_sensor: What the controller and the estimator sample of the phase currents; default the
            true currents ([`IdealCurrentSensor`][pmsmjax.estimators.current_sensors.IdealCurrentSensor]),
            [`CurrentSensors`][pmsmjax.estimators.current_sensors.CurrentSensors] for offsets, gains and
            quantisation. The trace keeps the true currents.
        thermal: The winding's thermal network and temperature coefficients (a warm motor, three-phase
            machines); ``None`` (default): ``R`` and ``psi_f`` constant.

    Raises:
        ParameterError: For a non-positive period, a sub-step count below 1, a voltage-commanding
            controller without modulator, blocks of different phase counts, current sensors the machine's
            phase count has no model for, or a thermal network on a machine that is not three-phase.
    """

    machine: AbstractMachine
    controller: AbstractController
    modulator: AbstractModulator | None
    bridge: AbstractBridge
    Ts: float = eqx.field(static=True, default=1e-4)
    n_substeps: int = eqx.field(static=True, default=10)
    computation_delay: bool = eqx.field(static=True, default=True)
    estimator: AbstractEstimator = eqx.field(default_factory=ExactSensor)
    current_sensor: AbstractCurrentSensor = eqx.field(default_factory=IdealCurrentSensor)
    thermal: WindingThermal | None = None

    def __check_init__(self):
        check_positive("Drive.Ts (control period)", self.Ts, "s")
        if not isinstance(self.n_substeps, int) or self.n_substeps < 1:
            raise ParameterError(f"Drive.n_substeps must be an int >= 1, got {self.n_substeps!r}.")
        if self.controller.command_kind == "voltage" and self.modulator is None:
            raise ParameterError(
                f"{type(self.controller).__name__} commands a voltage: give the Drive a modulator "
                "(e.g. pmsmjax.inverters.SVPWM())."
            )
        n_machine = self.machine.n_phases
        n_modulator = n_machine if self.modulator is None else self.modulator.n_phases
        if n_modulator != n_machine:
            raise ParameterError(
                f"the modulator drives {n_modulator} legs but the machine has {n_machine} phases: "
                "choose a modulator for the machine's phase count."
            )
        if self.bridge.n_phases != n_machine:
            raise ParameterError(
                f"the bridge has {self.bridge.n_phases} legs but the machine has {n_machine} phases: "
                "choose a bridge for the machine's phase count (six phases: MultiPhaseAveragedBridge, "
                "MultiPhaseSwitchingBridge)."
            )
        self.bridge.check_period(self.Ts)
        self.estimator.check_period(self.Ts)
        self.current_sensor.check_phases(n_machine)
        if self.thermal is not None and n_machine != 3:
            raise ParameterError(
                f"a thermal network heats a three-phase machine (its copper loss 1.5 R |i_dq|^2); this "
                f"machine has {n_machine} phases: drop the thermal network."
            )

    @property
    def records_estimate(self) -> bool:
        """Whether the trace keeps the estimator's angle and speed (they can differ from the plant's)."""
        return not isinstance(self.estimator, ExactSensor)

    def sample(self, ms: MachineState, last_duties: Array) -> Sample:
        """What the controller's hardware measures at the start of a period.

        Args:
            ms: The machine's state at the period start.
            last_duties: ``(n,)`` duties applied over the last period (for the commanded voltage).

        Returns:
            The [`Sample`][pmsmjax.signals.Sample]: phase and alpha-beta currents as the current sensors
            read them, DC voltage, last commanded voltage, and the ideal shaft sensor.
        """
        i_ab = self.machine.stationary_currents(ms)
        u_ab_last = self.bridge.commanded_voltage(last_duties)
        i_phase = self.machine.phase_currents(ms)
        i_phase, i_ab = self.current_sensor.measure(i_phase, i_ab)
        return Sample(i_phase, i_ab, self.bridge.u_dc, u_ab_last, ms.theta_e, ms.omega_m)

    def voltage_limit(self) -> Array:
        """Largest stator voltage the modulator reproduces without distortion (peak, V)."""
        if self.modulator is None:
            return self.bridge.u_dc / jnp.sqrt(3.0)  # the hexagon's inscribed circle
        return self.modulator.linear_limit(self.bridge.u_dc)

    def init(self, speed_m=0.0, theta_e=0.0) -> DriveState:
        """State at rest (or at the given speed and angle) with zero currents.

        Args:
            speed_m: Mechanical speed, rad/s.
            theta_e: Electrical angle, rad.

        Returns:
            The [`DriveState`][pmsmjax.drive.DriveState], duties at 0.5 (zero average voltage).
        """
        machine_state = self.machine.initial_state((0.0, 0.0), speed_m, theta_e)
        dtype = machine_state.omega_m.dtype
        duties = jnp.full((self.machine.n_phases,), 0.5, dtype)
        return DriveState(
            machine_state,
            self.estimator.init(self.sample(machine_state, duties)),
            self.controller.init(dtype),
            duties,
            duties,
            None if self.thermal is None else self.thermal.init(dtype),
        )

    def step(self, state: DriveState, x: PeriodInputs) -> tuple[DriveState, PeriodRecord]:
        """One control period (the body of the [`pmsmjax.simulate.simulate`][pmsmjax.simulate.simulate] scan).

        Sample the machine at the period start, estimate, control, modulate, then integrate the machine
        over the period under the duties in force (last period's with a computational delay).

        Args:
            state: The drive's state at the period start.
            x: This period's references (speed rad/s, currents A) and load torque (N m).

        Returns:
            The state at the period end, and the [`PeriodRecord`][pmsmjax.drive.PeriodRecord] of this period
            (the period-start machine state, the applied duties, the dq voltage command V and current
            reference A, and the estimate when recorded).
        """
        ms = state.machine
        if self.machine.mechanics == "imposed":
            ms = MachineState(ms.currents, jnp.asarray(x.speed_ref, ms.omega_m.dtype), ms.theta_e, ms.shaft)
        sample = self.sample(ms, state.last_duties)
        estimator_state, estimate = self.estimator.step(state.estimator, sample, self.Ts)
        refs = References(x.speed_ref, x.id_ref, x.iq_ref, x.iq_ref_perturbation)
        seen = sample
        if estimate.i_ab_fundamental is not None:
            # HF injection: the current loop gets the carrier-free current (stationary frame; the phase
            # currents stay raw, so only controllers that read i_ab are shielded from the carrier)
            seen = dataclasses.replace(sample, i_ab=estimate.i_ab_fundamental)
        if x.measured_iq_perturbation is not None:
            # the current loop's break point: the q axis of the controller's own (estimated) frame
            zero = jnp.zeros_like(x.measured_iq_perturbation)
            extra = inverse_park(jnp.stack([zero, x.measured_iq_perturbation]), estimate.theta_e)
            seen = dataclasses.replace(seen, i_ab=seen.i_ab + extra)
        ctrl_state, out = self.controller.step(
            state.controller, seen, estimate, refs, self.Ts, self.voltage_limit(), self.computation_delay
        )
        if self.controller.command_kind == "voltage":
            u_ab = out.command
            if self.estimator.injects_voltage:
                inj = estimate.u_injection_ab
                # A multi-phase command [alpha, beta, z1, z2, ...]: the injection is in the alpha-beta plane.
                u_ab = u_ab + inj if u_ab.shape == (2,) else u_ab.at[:2].add(inj)
            new_duties = self.modulator.duties(u_ab, self.bridge.u_dc)
        else:
            new_duties = out.command.astype(ms.omega_m.dtype)
        duties = state.pending_duties if self.computation_delay else new_duties
        if self.thermal is None:
            ms_next, _ = self.bridge.advance(
                self.machine, ms, duties, x.load_torque, self.Ts, self.n_substeps
            )
            thermal, temperature = None, None
        else:
            # the plant at the period start's winding temperature for the whole period
            warm = self.thermal.machine_at(self.machine, state.thermal)
            ms_next, _ = self.bridge.advance(warm, ms, duties, x.load_torque, self.Ts, self.n_substeps)
            loss = self.thermal.copper_loss(warm.motor.R, warm.currents_dq(ms), warm.currents_dq(ms_next))
            thermal = self.thermal.step(state.thermal, loss, self.Ts)
            temperature = self.thermal.temperature(state.thermal)
        recorded = jnp.stack([estimate.theta_e, estimate.omega_m]) if self.records_estimate else None
        record = PeriodRecord(ms, duties, out.u_dq_ref, out.i_dq_ref, recorded, temperature)
        return DriveState(ms_next, estimator_state, ctrl_state, new_duties, duties, thermal), record
