"""n-leg two-level bridges for multi-phase machines with isolated star points (six phases: two stars).

Phase-to-neutral voltage of phase ``x`` in star ``S``: ``u_xN = v_x - mean_{y in S} v_y`` with ``v`` the
pole voltages (each star's common mode does not reach its windings). The machine is driven by the
stationary VSD voltage of those phase voltages, ``(2 n_planes,)`` = [alpha, beta, z1, z2, ...]
([`pmsmjax.frames.multiphase`][pmsmjax.frames.multiphase]); the zero sequences of isolated stars are 0.

- [`MultiPhaseAveragedBridge`][pmsmjax.inverters.multiphase_bridges.MultiPhaseAveragedBridge]: the
  period-average voltage held over the period (``d`` the duties: ``v = U_dc d``).
- [`MultiPhaseSwitchingBridge`][pmsmjax.inverters.multiphase_bridges.MultiPhaseSwitchingBridge]: the period
  cut at every gate edge of centre-aligned PWM (2n edges, 2n + 1 segments; with dead time 4n + 1), the machine
  integrated over each constant-voltage segment, exactly as
  [`pmsmjax.inverters.switching.SwitchingBridge`][pmsmjax.inverters.switching.SwitchingBridge] does for three
  legs (same segment function
  [`pmsmjax.inverters.switching.pwm_segments`][pmsmjax.inverters.switching.pwm_segments], same dead-time and
  device-drop model with the exact or ``tanh`` current sign). Both return the period-average VSD voltage; they
  agree on it.

``commanded_voltage`` (what the controller knows it applied) is the alpha-beta part ``(2,)`` of the
ideal period average, the interface every controller reads.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import SIX_PHASE, PhaseLayout, vsd_matrix
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.inverters.switching import AbstractSegmentBridge, CurrentSign
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import check_positive

__all__ = [
    "AbstractMultiPhaseBridge",
    "MultiPhaseAveragedBridge",
    "MultiPhaseSwitchingBridge",
    "star_phase_voltages",
    "vsd_voltage",
]


def star_phase_voltages(pole: Array, layout: PhaseLayout = SIX_PHASE) -> Array:
    """Phase-to-neutral voltages from pole voltages: each phase less the mean of its star.

    Args:
        pole: ``(..., n)`` pole voltages, V.
        layout: The winding layout (its stars).

    Returns:
        ``(..., n)`` phase voltages, V.
    """
    out = pole
    for group in layout.neutrals:
        idx = np.asarray(group)
        mean = jnp.mean(pole[..., idx], axis=-1, keepdims=True)
        mask = np.zeros(layout.n)
        mask[idx] = 1.0
        out = out - jnp.asarray(mask, pole.dtype) * mean
    return out


def vsd_voltage(phase_voltages: Array, layout: PhaseLayout = SIX_PHASE) -> Array:
    """Stationary VSD voltage of phase voltages (the zero sequences dropped).

    Args:
        phase_voltages: ``(..., n)`` phase voltages, V.
        layout: The winding layout.

    Returns:
        ``(..., 2 n_planes)`` voltage [alpha, beta, z1, z2, ...], V.
    """
    T = vsd_matrix(layout)[: layout.n_active]
    return phase_voltages @ jnp.asarray(T.T, phase_voltages.dtype)


class AbstractMultiPhaseBridge(AbstractBridge):
    """An n-leg bridge feeding the isolated stars of ``layout``: its ideal period-average voltages (what both
    multi-phase bridges command) and the layout check. A subclass holds the DC-link voltage ``u_dc`` (V)
    and the winding ``layout`` (static).
    """

    layout: eqx.AbstractVar[PhaseLayout]

    def __check_init__(self):
        self.layout.check()

    @property
    def n_phases(self) -> int:  # type: ignore[override]
        """Number of legs, one per phase of ``layout``."""
        return self.layout.n

    def phase_voltages(self, duties: Array) -> Array:
        """Ideal period-average phase-to-neutral voltages.

        Args:
            duties: ``(..., n)`` leg duties.

        Returns:
            ``(..., n)`` voltages, V.
        """
        return star_phase_voltages(self.u_dc * duties, self.layout)

    def vsd_voltage(self, duties: Array) -> Array:
        """Ideal period-average stationary VSD voltage.

        Args:
            duties: ``(..., n)`` leg duties.

        Returns:
            ``(..., 2 n_planes)`` voltage, V.
        """
        return vsd_voltage(self.phase_voltages(duties), self.layout)

    def commanded_voltage(self, duties):
        return self.vsd_voltage(duties)[..., :2]


class MultiPhaseAveragedBridge(AbstractMultiPhaseBridge):
    """Ideal averaged n-leg inverter.

    Args:
        u_dc: DC-link voltage, V.
        layout: The winding (static).
    """

    u_dc: Array
    layout: PhaseLayout = eqx.field(static=True)

    def __init__(self, u_dc=311.0, layout: PhaseLayout = SIX_PHASE):
        self.u_dc = as_float(u_dc)
        self.layout = layout

    def __check_init__(self):
        check_positive("u_dc (DC-link voltage)", self.u_dc, "V")

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u = self.vsd_voltage(duties)
        return advance(machine, state, MachineInput(u, load_torque, "stator"), Ts, n_substeps), u


class MultiPhaseSwitchingBridge(AbstractSegmentBridge, AbstractMultiPhaseBridge):
    """n-leg inverter resolved into its switching segments (module docstring).

    The arguments are those of
    [`pmsmjax.inverters.switching.SwitchingBridge`][pmsmjax.inverters.switching.SwitchingBridge], plus
    ``layout``. ``device_drop=None`` leaves the device drop out of the program as ``dead_time=None`` does the
    dead time (``0.0`` keeps it, to vary or differentiate it). With neither, no segment's voltage depends on
    the current, so all segment voltages are computed at once before the segment loop, which then only
    integrates (docs/performance.md, "Six-phase and five-phase drives").

    Args:
        u_dc: DC-link voltage, V.
        dead_time: Blanking time per switching edge, s, or ``None``.
        device_drop: On-state voltage of a switch or diode, V, or ``None``.
        sign_smoothing: Current scale of the ``tanh`` sign surrogate, A.
        current_sign: ``"exact"`` or ``"smooth"`` (static).
        segment_substeps: RK4 steps per segment (static).
        layout: The winding (static).
    """

    layout: PhaseLayout = eqx.field(static=True)
    resolve_device_drop: bool = eqx.field(static=True)

    def __init__(
        self,
        u_dc=311.0,
        dead_time=None,
        device_drop=None,
        sign_smoothing=0.05,
        current_sign: CurrentSign = "exact",
        segment_substeps: int = 1,
        layout: PhaseLayout = SIX_PHASE,
    ):
        drop = 0.0 if device_drop is None else device_drop
        super().__init__(u_dc, dead_time, drop, sign_smoothing, current_sign, segment_substeps)
        self.resolve_device_drop = device_drop is not None
        self.layout = layout

    def _phase_currents(self, machine, state) -> Array:
        return machine.phase_currents(state)

    def _output_voltage(self, pole: Array) -> Array:
        return vsd_voltage(star_phase_voltages(pole, self.layout), self.layout)

    def _integrate(self, machine, state, times, high, dead, load_torque):
        if self.resolve_dead_time or self.resolve_device_drop:
            return super()._integrate(machine, state, times, high, dead, load_torque)
        # Ideal switches: every segment's voltage follows from the gate states alone.
        u_all = vsd_voltage(star_phase_voltages(self.u_dc * high, self.layout), self.layout)

        def ideal(s, seg):
            duration, u = seg
            s = advance(machine, s, MachineInput(u, load_torque, "stator"), duration, self.segment_substeps)
            return s, (s, u)

        final, (states, u) = jax.lax.scan(ideal, state, (jnp.diff(times), u_all))
        return final, states, u
