"""Switching-resolved two-level bridge: the machine integrated over the constant-voltage segments of a period.

Instead of searching for carrier crossings with a fine time step, the switching instants are computed
from the duties (as motulator does). Centre-aligned PWM turns leg x's upper switch on for ``d_x Ts``
centred in the period: gate on at ``a_x = (1 - d_x) Ts/2``, off at ``b_x = (1 + d_x) Ts/2``. The six
edges, sorted, cut the period into 7 segments (some of zero length) in each of which every leg is
constant; the machine is integrated over each with ``segment_substeps`` RK4 steps. The program shape is
fixed, so it jits, vmaps and differentiates: the derivative with respect to the duties flows through the
segment durations (differences of sorted edge times; sorting is a permutation, its derivative exact).

Non-idealities (both off by default):

- **Dead time** ``t_d`` (s): each switch turns on ``t_d`` after its gate edge, so after every edge of a
  switching leg (``0 < d_x < 1``) both switches are off for ``t_d`` and the freewheeling diode chosen by
  the phase current sets the pole voltage: high for a current flowing into the leg (``i_x < 0``), low for
  ``i_x > 0``. The six dead windows ``[a_x, a_x + t_d)``, ``[b_x, b_x + t_d)`` add six cut points (13
  segments). For a current of constant sign the leg loses ``sign(i_x) U_dc t_d / Ts`` of average pole
  voltage per period. A pulse narrower than ``t_d`` vanishes (its windows overlap), and a window running
  past the period end is cut there (it loses less than ``t_d`` only for duties within ``t_d/Ts`` of 1).
- **Device voltage drop** ``U_f`` (V): the conducting switch or diode lowers the pole voltage by
  ``sign(i_x) U_f``.

Current sign. Both use the phase current at the start of each segment, carried through the segment loop:
for a dead window that is the current at the gate edge, as in the real circuit (a zero crossing inside
the ``t_d`` window itself is neglected). ``current_sign="exact"`` (default) uses ``sign(i)``; ``"smooth"``
the surrogate ``tanh(i/eps)`` (``eps = sign_smoothing``, A), which blends the two diode states near zero
current and makes the model differentiable with respect to the current there.
At exactly zero current the exact sign is 0 and a dead window puts the pole at ``U_dc/2`` (the real
voltage is set by the machine then; the window lasts a few microseconds).

Output voltage: phase-to-neutral of a star, isolated-neutral machine, ``u_xN = v_x - mean(v)`` from the
pole voltages ``v``; [`SwitchingBridge.advance`][pmsmjax.inverters.switching.SwitchingBridge] returns its
exact period average in the stator frame.
"""

import abc
from typing import ClassVar, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta, dq_to_abc
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import (
    ParameterError,
    check_choice,
    check_nonnegative,
    check_positive,
    is_concrete,
)

CurrentSign = Literal["exact", "smooth"]


class AbstractSegmentBridge(AbstractBridge):
    """A two-level bridge of n legs resolved into its switching segments: what the three-phase
    [`SwitchingBridge`][pmsmjax.inverters.switching.SwitchingBridge] and the n-leg
    [`MultiPhaseSwitchingBridge`][pmsmjax.inverters.multiphase_bridges.MultiPhaseSwitchingBridge] share (the
    segments, the dead-time and device-drop model, the checks, ``advance`` and ``sample_period``).

    A subclass gives the phase currents the diodes see and the machine's voltage from the pole voltages
    (``_phase_currents``, ``_output_voltage``).

    Args:
        u_dc: DC-link voltage, V.
        dead_time: Blanking time per switching edge, s (0 <= t_d < Ts/2, checked against the drive's Ts).
            ``None``: no dead time, and the dead-window cuts are left out of the program (2n + 1 segments
            instead of 4n + 1); ``0.0`` keeps them (to vary or differentiate ``t_d`` from 0).
        device_drop: Constant on-state voltage of a switch or diode, V (>= 0).
        sign_smoothing: Current scale ``eps`` of the ``tanh(i/eps)`` sign surrogate, A (used when
            ``current_sign="smooth"``).
        current_sign: ``"exact"`` or ``"smooth"`` (static).
        segment_substeps: RK4 steps per segment (static).
    """

    u_dc: Array
    dead_time: Array
    device_drop: Array
    sign_smoothing: Array
    current_sign: CurrentSign = eqx.field(static=True)
    segment_substeps: int = eqx.field(static=True)
    resolve_dead_time: bool = eqx.field(static=True)
    switching_resolved: ClassVar[bool] = True

    def __init__(
        self,
        u_dc=311.0,
        dead_time=None,
        device_drop=0.0,
        sign_smoothing=0.05,
        current_sign: CurrentSign = "exact",
        segment_substeps: int = 1,
    ):
        self.u_dc = as_float(u_dc)
        self.resolve_dead_time = dead_time is not None
        self.dead_time = as_float(0.0 if dead_time is None else dead_time)
        self.device_drop = as_float(device_drop)
        self.sign_smoothing = as_float(sign_smoothing)
        self.current_sign = current_sign
        self.segment_substeps = segment_substeps

    def __check_init__(self):
        name = type(self).__name__
        check_positive(f"{name}.u_dc (DC-link voltage)", self.u_dc, "V")
        check_nonnegative(f"{name}.dead_time", self.dead_time, "s")
        check_nonnegative(f"{name}.device_drop", self.device_drop, "V")
        check_positive(f"{name}.sign_smoothing", self.sign_smoothing, "A")
        check_choice("current_sign", self.current_sign, ("exact", "smooth"))
        if not isinstance(self.segment_substeps, int) or self.segment_substeps < 1:
            raise ParameterError(f"segment_substeps must be an int >= 1, got {self.segment_substeps!r}.")

    def check_period(self, Ts: float) -> None:
        """Refuse a dead time that does not fit the PWM period: ``t_d < Ts/2`` (both edges of one pulse).

        Args:
            Ts: PWM period, s.

        Raises:
            ParameterError: For a dead time of half the period or more.
        """
        if not is_concrete(self.dead_time):
            return
        t_d = float(np.max(np.asarray(jax.device_get(self.dead_time))))  # NumPy: no tracer inside a jit
        if t_d >= 0.5 * Ts:
            raise ParameterError(
                f"{type(self).__name__}.dead_time = {t_d:g} s is not below half the PWM period Ts/2 = "
                f"{0.5 * Ts:g} s: a typical dead time is 0.5-3 us."
            )

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
        """The period cut at every gate edge, the end of every dead window, and ``extra_times``
        ([`pwm_segments`][pmsmjax.inverters.switching.pwm_segments] with this bridge's dead time).

        Args:
            duties: ``(n,)`` upper-switch duties.
            Ts: PWM period, s.
            extra_times: Optional ``(M,)`` further cut points in [0, Ts], s.
        """
        return pwm_segments(duties, Ts, self.dead_time, self.resolve_dead_time, extra_times)

    @abc.abstractmethod
    def _phase_currents(self, machine, state) -> Array:
        """``(n,)`` phase currents of the machine in ``state``, A: the ones whose signs pick the diodes."""

    @abc.abstractmethod
    def _output_voltage(self, pole: Array) -> Array:
        """The stationary-frame voltage the machine gets from the ``(n,)`` pole voltages ``pole``, V."""

    def _integrate(self, machine, state, times, high, dead, load_torque):
        """Integrate interval by interval; the pole voltages use the current at each interval start.

        Returns the final state, the ``(K,)``-stacked states at interval ends, and the ``(K, m)`` voltages
        of ``_output_voltage``, V. A rolled loop: unrolled, the 7-13 segments of three legs compile and run
        slower on CPU.
        """

        def body(s, seg):
            duration, high_k, dead_k = seg
            sign = self.phase_current_sign(self._phase_currents(machine, s))
            freewheel = 0.5 * (1.0 - sign)  # both off: upper diode (high) for i < 0, lower for i > 0
            pole = self.u_dc * ((1.0 - dead_k) * high_k + dead_k * freewheel) - self.device_drop * sign
            u = self._output_voltage(pole)
            s = advance(machine, s, MachineInput(u, load_torque, "stator"), duration, self.segment_substeps)
            return s, (s, u)

        final, (states, u) = jax.lax.scan(body, state, (jnp.diff(times), high, dead))
        return final, states, u

    def _checked(self, duties, Ts):
        if jnp.shape(duties) != (self.n_phases,):
            raise ParameterError(
                f"duties must have shape ({self.n_phases},) (one per leg), got {jnp.shape(duties)}."
            )
        self.check_period(Ts)

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        self._checked(duties, Ts)
        times, high, dead, _ = self.segments(duties, Ts)
        new_state, _, u = self._integrate(machine, state, times, high, dead, load_torque)
        return new_state, jnp.diff(times) @ u / Ts

    def sample_period(self, machine, state, duties, load_torque, Ts, n_samples: int):
        """The states at ``t_j = j Ts / n_samples``, j = 1..n_samples, within one period (ripple plots and
        spectra).

        The period is also cut at the sample instants, so the trajectory is the one ``advance`` follows.

        Args:
            machine: The machine model.
            state: The machine state at the period start.
            duties: ``(n,)`` leg duty cycles.
            load_torque: Load torque, N m.
            Ts: PWM period, s.
            n_samples: Number of sample instants.

        Returns:
            ``(MachineState of (n_samples,) leaves, (K+1,) interval bounds s, (K, m) voltage of each interval
            V)``: ``m = 2`` (stator frame) for three legs, ``2 n_planes`` (VSD) for more.
        """
        self._checked(duties, Ts)
        samples = Ts * jnp.arange(1, n_samples + 1, dtype=state.omega_m.dtype) / n_samples
        times, high, dead, order = self.segments(duties, Ts, samples)
        _, states, u = self._integrate(machine, state, times, high, dead, load_torque)
        # Cut point c (sorted position rank(c)) ends interval rank(c); the samples are the last M cuts.
        pick = jnp.argsort(order)[-n_samples:]
        return jax.tree.map(lambda x: x[pick], states), times, u


class SwitchingBridge(AbstractSegmentBridge):
    """Two-level inverter resolved into its switching segments (see the module docstring).

    Args:
        u_dc: DC-link voltage, V.
        dead_time: Blanking time per switching edge, s (0 <= t_d < Ts/2, checked against the drive's Ts).
            ``None``: no dead time, and the 6 dead-window cuts are left out of the program (7 segments
            instead of 13); ``0.0`` keeps them (to vary or differentiate ``t_d`` from 0).
        device_drop: Constant on-state voltage of a switch or diode, V (>= 0).
        sign_smoothing: Current scale ``eps`` of the ``tanh(i/eps)`` sign surrogate, A (used when
            ``current_sign="smooth"``).
        current_sign: ``"exact"`` or ``"smooth"`` (static).
        segment_substeps: RK4 steps per segment (static). Segments are at most one period long, so one step
            is as accurate as the averaged bridge with one sub-step per period (4e-7 of the peak current on
            the book drive); the drive's ``n_substeps`` is not used by this bridge.
    """

    def _phase_currents(self, machine, state) -> Array:
        return dq_to_abc(machine.currents_dq(state), state.theta_e)

    def _output_voltage(self, pole: Array) -> Array:
        return abc_to_alpha_beta(pole - jnp.mean(pole))


def pwm_segments(duties: Array, Ts, dead_time, resolve_dead_time: bool, extra_times: Array | None = None):
    """The period cut at every gate edge of centre-aligned PWM, the end of every dead window, and
    ``extra_times``; for any number of legs.

    Args:
        duties: ``(n,)`` upper-switch duties.
        Ts: PWM period, s.
        dead_time: Dead time, s (used when ``resolve_dead_time``).
        resolve_dead_time: Whether to cut the dead windows (static).
        extra_times: Optional ``(M,)`` further cut points in [0, Ts], s (sampling instants).

    Returns:
        ``(times, high, dead, order)``: ``(K+1,)`` sorted bounds from 0 to Ts; ``(K, n)`` gate state
        (1 = upper gate on) and ``(K, n)`` dead-window indicator of every leg in every interval; and the
        argsort that put the cut points in order (edges and window ends first, ``extra_times`` last).
        K = 2n + 1 + M without dead time, 4n + 1 + M with it (7 and 13 for three legs).
    """
    on = 0.5 * Ts * (1.0 - duties)
    off = 0.5 * Ts * (1.0 + duties)
    cuts = [on, off]
    if resolve_dead_time:
        t_d = jnp.where((duties > 0.0) & (duties < 1.0), dead_time, 0.0)  # idle legs: no edges
        on_end, off_end = jnp.minimum(on + t_d, Ts), jnp.minimum(off + t_d, Ts)
        cuts += [on_end, off_end]
    if extra_times is not None:
        cuts.append(extra_times)
    cuts = jnp.concatenate(cuts)
    order = jnp.argsort(cuts)
    zero = jnp.zeros((1,), cuts.dtype)
    times = jnp.concatenate([zero, jnp.sort(cuts), zero + Ts])
    mid = 0.5 * (times[1:] + times[:-1])[:, None]
    inside = lambda lo, hi: (lo[None, :] <= mid) & (mid < hi[None, :])
    high = inside(on, off).astype(cuts.dtype)
    if resolve_dead_time:
        dead = (inside(on, on_end) | inside(off, off_end)).astype(cuts.dtype)
    else:
        dead = jnp.zeros_like(high)
    return times, high, dead, order
