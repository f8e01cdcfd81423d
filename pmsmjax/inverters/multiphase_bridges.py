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

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import SIX_PHASE, PhaseLayout, vsd_matrix
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.inverters.switching import CurrentSign, pwm_segments
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_nonnegative, check_positive, is_concrete

__all__ = [
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


class MultiPhaseAveragedBridge(AbstractBridge):
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
        self.layout.check()

    @property
    def n_phases(self) -> int:
        return self.layout.n

    def phase_voltages(self, duties: Array) -> Array:
        """Period-average phase-to-neutral voltages.

        Args:
            duties: ``(..., n)`` leg duties.

        Returns:
            ``(..., n)`` voltages, V.
        """
        return star_phase_voltages(self.u_dc * duties, self.layout)

    def vsd_voltage(self, duties: Array) -> Array:
        """Period-average stationary VSD voltage.

        Args:
            duties: ``(..., n)`` leg duties.

        Returns:
            ``(..., 2 n_planes)`` voltage, V.
        """
        return vsd_voltage(self.phase_voltages(duties), self.layout)

    def commanded_voltage(self, duties):
        return self.vsd_voltage(duties)[..., :2]

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u = self.vsd_voltage(duties)
        return advance(machine, state, MachineInput(u, load_torque, "stator"), Ts, n_substeps), u


class MultiPhaseSwitchingBridge(AbstractBridge):
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

    u_dc: Array
    dead_time: Array
    device_drop: Array
    sign_smoothing: Array
    layout: PhaseLayout = eqx.field(static=True)
    current_sign: CurrentSign = eqx.field(static=True)
    segment_substeps: int = eqx.field(static=True)
    resolve_dead_time: bool = eqx.field(static=True)
    resolve_device_drop: bool = eqx.field(static=True)
    switching_resolved: ClassVar[bool] = True

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
        self.u_dc = as_float(u_dc)
        self.resolve_dead_time = dead_time is not None
        self.dead_time = as_float(0.0 if dead_time is None else dead_time)
        self.resolve_device_drop = device_drop is not None
        self.device_drop = as_float(0.0 if device_drop is None else device_drop)
        self.sign_smoothing = as_float(sign_smoothing)
        self.current_sign = current_sign
        self.segment_substeps = segment_substeps
        self.layout = layout

    def __check_init__(self):
        self.layout.check()
        check_positive("MultiPhaseSwitchingBridge.u_dc (DC-link voltage)", self.u_dc, "V")
        check_nonnegative("MultiPhaseSwitchingBridge.dead_time", self.dead_time, "s")
        check_nonnegative("MultiPhaseSwitchingBridge.device_drop", self.device_drop, "V")
        check_positive("MultiPhaseSwitchingBridge.sign_smoothing", self.sign_smoothing, "A")
        if self.current_sign not in ("exact", "smooth"):
            raise ParameterError(f"current_sign must be 'exact' or 'smooth', got {self.current_sign!r}.")
        if not isinstance(self.segment_substeps, int) or self.segment_substeps < 1:
            raise ParameterError(f"segment_substeps must be an int >= 1, got {self.segment_substeps!r}.")

    @property
    def n_phases(self) -> int:
        return self.layout.n

    def check_period(self, Ts: float) -> None:
        """Refuse a dead time that does not fit the PWM period: ``t_d < Ts/2``.

        Args:
            Ts: PWM period, s.

        Raises:
            ParameterError: For a dead time of half the period or more.
        """
        if not is_concrete(self.dead_time):
            return
        t_d = float(np.max(np.asarray(jax.device_get(self.dead_time))))
        if t_d >= 0.5 * Ts:
            raise ParameterError(
                f"MultiPhaseSwitchingBridge.dead_time = {t_d:g} s is not below half the PWM period Ts/2 = "
                f"{0.5 * Ts:g} s: a typical dead time is 0.5-3 us."
            )

    def phase_voltages(self, duties: Array) -> Array:
        """Ideal period-average phase-to-neutral voltages.

        Args:
            duties: ``(..., n)`` leg duties.

        Returns:
            ``(..., n)`` voltages, V.
        """
        return star_phase_voltages(self.u_dc * duties, self.layout)

    def commanded_voltage(self, duties):
        return vsd_voltage(self.phase_voltages(duties), self.layout)[..., :2]

    def phase_current_sign(self, i_phase: Array) -> Array:
        """Sign of each phase current, which sets the dead-time and device-drop voltage error: exact
        (``sign``) or smooth (``tanh(i / sign_smoothing)``, for gradients).

        Args:
            i_phase: ``(n,)`` phase currents, A.
        """
        if self.current_sign == "exact":
            return jnp.sign(i_phase)
        return jnp.tanh(i_phase / self.sign_smoothing)

    def segments(self, duties: Array, Ts, extra_times: Array | None = None):
        """[`pmsmjax.inverters.switching.pwm_segments`][pmsmjax.inverters.switching.pwm_segments] with this
        bridge's dead time.

        Args:
            duties: ``(n,)`` upper-switch duties.
            Ts: PWM period, s.
            extra_times: Optional ``(M,)`` further cut points in [0, Ts], s.
        """
        return pwm_segments(duties, Ts, self.dead_time, self.resolve_dead_time, extra_times)

    def _integrate(self, machine, state, times, high, dead, load_torque):
        if not (self.resolve_dead_time or self.resolve_device_drop):
            # Ideal switches: every segment's voltage follows from the gate states alone.
            u_all = vsd_voltage(star_phase_voltages(self.u_dc * high, self.layout), self.layout)

            def ideal(s, seg):
                duration, u = seg
                s = advance(
                    machine, s, MachineInput(u, load_torque, "stator"), duration, self.segment_substeps
                )
                return s, (s, u)

            final, (states, u) = jax.lax.scan(ideal, state, (jnp.diff(times), u_all))
            return final, states, u

        def body(s, seg):
            duration, high_k, dead_k = seg
            sign = self.phase_current_sign(machine.phase_currents(s))
            freewheel = 0.5 * (1.0 - sign)  # both off: upper diode (high) for i < 0, lower for i > 0
            pole = self.u_dc * ((1.0 - dead_k) * high_k + dead_k * freewheel) - self.device_drop * sign
            u = vsd_voltage(star_phase_voltages(pole, self.layout), self.layout)
            s = advance(machine, s, MachineInput(u, load_torque, "stator"), duration, self.segment_substeps)
            return s, (s, u)

        final, (states, u) = jax.lax.scan(body, state, (jnp.diff(times), high, dead))
        return final, states, u

    def _checked(self, duties, Ts):
        if jnp.shape(duties) != (self.layout.n,):
            raise ParameterError(
                f"duties must have shape ({self.layout.n},) (one per leg), got {jnp.shape(duties)}."
            )
        self.check_period(Ts)

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        self._checked(duties, Ts)
        times, high, dead, _ = self.segments(duties, Ts)
        new_state, _, u = self._integrate(machine, state, times, high, dead, load_torque)
        return new_state, jnp.diff(times) @ u / Ts

    def sample_period(self, machine, state, duties, load_torque, Ts, n_samples: int):
        """States at ``t_j = j Ts / n_samples``, j = 1..n_samples, within one period (as
        [`pmsmjax.inverters.switching.SwitchingBridge.sample_period`][pmsmjax.inverters.switching.SwitchingBridge.sample_period]).

        Args:
            machine: The machine model.
            state: The machine state at the period start.
            duties: ``(n,)`` leg duty cycles.
            load_torque: Load torque, N m.
            Ts: PWM period, s.
            n_samples: Number of sample instants.

        Returns:
            ``(MachineState of (n_samples,) leaves, (K+1,) interval bounds s, (K, 2 n_planes) VSD voltage of
            each interval V)``.
        """
        self._checked(duties, Ts)
        samples = Ts * jnp.arange(1, n_samples + 1, dtype=state.omega_m.dtype) / n_samples
        times, high, dead, order = self.segments(duties, Ts, samples)
        _, states, u = self._integrate(machine, state, times, high, dead, load_torque)
        pick = jnp.argsort(order)[-n_samples:]
        return jax.tree.map(lambda x: x[pick], states), times, u
