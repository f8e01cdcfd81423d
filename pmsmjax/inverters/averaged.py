"""Averaged two-level bridge: each period the machine sees the period-average phase voltage.

Phase-to-neutral voltages of a star-connected, isolated-neutral machine fed by legs with duty ``d``:
``u_xN = U_dc (d_x - (d_a + d_b + d_c)/3)`` (the common-mode part does not reach the windings). The
voltage is held in the stator frame over the period, as the real inverter holds it.
"""

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.checks.validation import check_positive
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import as_float


def phase_voltages(duties: Array, u_dc: Array) -> Array:
    """Period-average phase-to-neutral voltages ``(3,)`` V from leg duties ``(3,)``."""
    return u_dc * (duties - jnp.mean(duties, axis=-1, keepdims=True))


class AveragedBridge(AbstractBridge):
    """Ideal averaged inverter. `u_dc`: DC-link voltage, V (array leaf: vmappable, differentiable).

    `unroll_substeps` (static): write the period's RK4 sub-steps out rather than loop over them
    (:func:`pmsmjax.machines.integrate.advance`; for GPUs, where it was measured to pay).
    """

    u_dc: Array
    unroll_substeps: bool = eqx.field(static=True, default=False)

    def __init__(self, u_dc=311.0, unroll_substeps: bool = False):
        self.u_dc = as_float(u_dc)
        self.unroll_substeps = bool(unroll_substeps)

    def __check_init__(self):
        check_positive("u_dc (DC-link voltage)", self.u_dc, "V")

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u_ab = abc_to_alpha_beta(phase_voltages(duties, self.u_dc))
        inputs = MachineInput(u_ab, load_torque, "stator")
        new_state = advance(machine, state, inputs, Ts, n_substeps, self.unroll_substeps)
        return new_state, u_ab
