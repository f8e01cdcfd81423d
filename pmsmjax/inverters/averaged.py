"""Averaged two-level bridge: each period the machine sees the period-average phase voltage.

Phase-to-neutral voltages of a star-connected, isolated-neutral machine fed by legs with duty ``d``:
``u_xN = U_dc (d_x - (d_a + d_b + d_c)/3)`` (the common-mode part does not reach the windings). The
voltage is held in the stator frame over the period, as the real inverter holds it.

Optionally the legs' voltage error ([`pmsmjax.inverters.voltage_error`][pmsmjax.inverters.voltage_error]: dead
time and device drops, period-averaged, the current's sign taken at the period start and smoothed) is added to
the pole voltages before the common mode is removed. Without it (``dead_time=None`` and ``device_drop=None``,
the default) the program is the ideal bridge's, bit for bit.
"""

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.inverters.voltage_error import VoltageError, check_dead_time
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import check_positive


def phase_voltages(duties: Array, u_dc: Array) -> Array:
    """Period-average phase-to-neutral voltages from leg duties.

    Args:
        duties: ``(3,)`` leg duty cycles.
        u_dc: DC-link voltage, V.

    Returns:
        ``(3,)`` voltages, V.
    """
    return u_dc * (duties - jnp.mean(duties, axis=-1, keepdims=True))


class AveragedBridge(AbstractBridge):
    """Averaged inverter, ideal or with the legs' voltage error.

    With a dead time or a drop, ``voltage_error`` holds them (``None`` otherwise).

    Args:
        u_dc: DC-link voltage, V (array leaf: vmappable, differentiable).
        unroll_substeps: Write the period's RK4 sub-steps out rather than loop over them (static;
            [`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance]; for GPUs, where it
            pays).
        dead_time: Blanking time per switching edge, s (0 <= t_d < Ts/2, checked against the drive's Ts);
            ``None`` leaves the dead time out of the program.
        device_drop: On-state voltage of a switch or diode, V (>= 0); ``None`` leaves it out.
        sign_smoothing: ``i_eps`` of the ``tanh(i / i_eps)`` current sign, A (used with either error).
    """

    u_dc: Array
    voltage_error: VoltageError | None
    unroll_substeps: bool = eqx.field(static=True, default=False)

    def __init__(
        self,
        u_dc=311.0,
        unroll_substeps: bool = False,
        *,
        dead_time=None,
        device_drop=None,
        sign_smoothing=0.05,
    ):
        self.u_dc = as_float(u_dc)
        self.unroll_substeps = bool(unroll_substeps)
        if dead_time is None and device_drop is None:
            self.voltage_error = None
        else:
            t_d = 0.0 if dead_time is None else dead_time
            v_f = 0.0 if device_drop is None else device_drop
            self.voltage_error = VoltageError(t_d, v_f, sign_smoothing)

    def __check_init__(self):
        check_positive("u_dc (DC-link voltage)", self.u_dc, "V")

    def check_period(self, Ts: float) -> None:
        """Refuse a dead time that does not fit the PWM period: ``t_d < Ts/2`` (both edges of one pulse).

        Args:
            Ts: PWM period, s.

        Raises:
            ParameterError: For a dead time of half the period or more.
        """
        if self.voltage_error is not None:
            check_dead_time(self.voltage_error.dead_time, Ts, "AveragedBridge.dead_time")

    def output_voltages(self, machine, state, duties, Ts) -> Array:
        """Period-average phase-to-neutral voltages for the legs' duties.

        Args:
            machine: The machine model.
            state: The machine state at the period start (its currents set the voltage error's sign).
            duties: ``(3,)`` leg duty cycles.
            Ts: PWM period, s.

        Returns:
            ``(3,)`` voltages, V.
        """
        u = phase_voltages(duties, self.u_dc)
        if self.voltage_error is None:
            return u
        error = self.voltage_error.pole_error(machine.phase_currents(state), duties, self.u_dc, Ts)
        return u + (error - jnp.mean(error, axis=-1, keepdims=True))

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u_ab = abc_to_alpha_beta(self.output_voltages(machine, state, duties, Ts))
        inputs = MachineInput(u_ab, load_torque, "stator")
        new_state = advance(machine, state, inputs, Ts, n_substeps, self.unroll_substeps)
        return new_state, u_ab
