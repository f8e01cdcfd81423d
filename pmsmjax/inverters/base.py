"""Interfaces of modulators (voltage reference -> duty cycles) and bridges (duties -> machine voltage).

Both carry the number of legs they drive, ``n_phases`` (3 here; the six- and five-phase inverters
override it); [`pmsmjax.drive.Drive`][pmsmjax.drive.Drive] checks that it matches the machine's.
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.machines.base import AbstractMachine, MachineState


class AbstractModulator(eqx.Module):
    """Turns a stator-frame voltage reference into leg duty cycles.

    ``duties(u_ab_ref, u_dc)``: ``u_ab_ref: (2,)`` V, ``u_dc`` V -> ``(3,)`` duty cycles in [0, 1] (fraction
    of the period each upper switch conducts, centre-aligned).
    """

    n_phases: ClassVar[int] = 3

    @abc.abstractmethod
    def duties(self, u_ab_ref: Array, u_dc: Array) -> Array:
        """Leg duty cycles that reproduce the stationary-frame reference on average over one period.

        Beyond the linear range each modulator saturates in its own way (duties clipped to [0, 1], or the
        vector limited to the hexagon).

        Args:
            u_ab_ref: ``(2,)`` voltage reference, V (``(2 n_planes,)`` for the multi-phase modulators:
                alpha-beta first, then the other planes).
            u_dc: DC-link voltage, V.

        Returns:
            ``(n_phases,)`` duty cycles in [0, 1] (the fraction of the period each upper switch conducts,
            centre-aligned).
        """

    @abc.abstractmethod
    def linear_limit(self, u_dc) -> Array:
        """Largest phase-voltage amplitude (peak, V) reproduced without distortion."""


class AbstractBridge(eqx.Module):
    """A two-level voltage-source inverter fed from a DC link, coupled to the machine for one period.

    ``advance`` integrates the machine over one PWM period ``Ts`` (s) under the bridge's output voltage for
    the given duties and returns the new state and the period-average stator-frame voltage ``(2,)`` V. The
    averaged bridge applies the period-average voltage throughout; a switching-resolved bridge integrates
    segment by segment and must return the same average.
    """

    u_dc: eqx.AbstractVar[Array]
    n_phases: ClassVar[int] = 3
    #: The bridge integrates each constant-voltage switching segment of a period and samples the
    #: trajectory inside it with ``sample_period(machine, state, duties, load_torque, Ts, n_samples)``
    #: ([`pmsmjax.analysis.within_period`][pmsmjax.analysis.within_period]); otherwise the period-average
    #: voltage is held over it.
    switching_resolved: ClassVar[bool] = False

    def commanded_voltage(self, duties: Array) -> Array:
        """Stator-frame period-average voltage that ideal legs with ``duties`` give.

        What the controller knows it applied (``duties`` times the DC voltage), without the bridge's dead-time
        and device-drop errors.

        Args:
            duties: ``(n,)`` leg duty cycles.

        Returns:
            ``(2,)`` voltage, V.
        """
        return abc_to_alpha_beta(self.u_dc * (duties - jnp.mean(duties, axis=-1, keepdims=True)))

    def phase_voltages(self, duties: Array) -> Array:
        """Ideal period-average phase-to-neutral voltages (one star point; the multi-phase bridges override it
        for several).

        Args:
            duties: ``(..., n)`` leg duty cycles.

        Returns:
            ``(..., n)`` voltages, V.
        """
        return self.u_dc * (duties - jnp.mean(duties, axis=-1, keepdims=True))

    def check_period(self, Ts: float) -> None:
        """Refuse settings that do not fit the period.

        Called by [`pmsmjax.drive.Drive`][pmsmjax.drive.Drive] at construction (before compiling); nothing to
        check here.

        Args:
            Ts: PWM period, s.

        Raises:
            ParameterError: In the bridges that have such settings.
        """

    @abc.abstractmethod
    def advance(
        self,
        machine: AbstractMachine,
        state: MachineState,
        duties: Array,
        load_torque: Array,
        Ts: float,
        n_substeps: int,
    ) -> tuple[MachineState, Array]:
        """Integrate ``machine`` over one PWM period under the bridge's output for ``duties``.

        Args:
            machine: The machine model.
            state: The machine state at the period start.
            duties: ``(n_phases,)`` leg duty cycles in [0, 1] (or switch states in {0, 1}).
            load_torque: Load torque held over the period, N m.
            Ts: The period, s (static).
            n_substeps: RK4 steps over the period (static; a switching-resolved bridge integrates each
                constant-voltage segment with its own ``segment_substeps`` instead).

        Returns:
            The state at the period end and the period-average stator-frame voltage applied, ``(2,)`` V
            (``(2 n_planes,)`` for the multi-phase bridges).
        """
