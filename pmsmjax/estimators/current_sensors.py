"""Phase-current sensors as the controller's hardware sees them: offset, gain, ADC quantisation and the
reconstruction of an unsensed phase.

[`IdealCurrentSensor`][pmsmjax.estimators.current_sensors.IdealCurrentSensor] (the drive's default) passes
the machine's phase currents through and adds nothing to the compiled program.

[`CurrentSensors`][pmsmjax.estimators.current_sensors.CurrentSensors] models each sensed phase ``k`` of a
three-phase drive as ``measured_k = gain_k true_k + offset_k`` (a shunt amplifier's or Hall transducer's
static error), then, with ``lsb_a``, the ADC's rounding to a multiple of one least significant bit. Two
sensors sit on phases a and b and the third current is reconstructed as ``i_c = -i_a - i_b`` from the two
measured ones, as drive firmware does (the two-sensor Clarke transform ``i_alpha = i_a``,
``i_beta = (i_a + 2 i_b) / sqrt(3)`` of TI's C2000 sensored-FOC application report SPRABZ0 and of ST's
two-shunt current reading in the STM32 FOC SDK manual UM1052), so a sensor error leaks into the unsensed
phase. Three sensors measure every phase; the
amplitude-invariant Clarke transform then drops the common part of their errors (a zero-sequence offset).

What a current error does under field-oriented control (the tests check both against the trace's spectrum):

- an offset ``o_ab`` (the Clarke transform of the sensed offsets, A) is a stationary vector: in the rotor
  frame it is ``o_ab`` rotating at ``-omega_e``, a ripple at the electrical frequency ``f_e`` in the dq
  currents the controller regulates. Inside the current loop's bandwidth the controller makes the
  *measured* current follow its reference, so the true currents carry ``-o_ab``: a ripple of magnitude
  ``|o_ab|`` at ``f_e`` in ``i_d`` and ``i_q`` and a DC error in the phase currents;
- a gain mismatch ``g_a != g_b`` scales one axis of the stationary frame more than the other: an elliptic
  distortion whose rotor-frame image is a ripple at ``2 f_e``; a common gain ``g`` scales the whole
  current (the loop regulates ``g i``, so the true current is ``i* / g``).

Quantisation (``lsb_a``) rounds each sensed channel to ``lsb_a round(x / lsb_a)`` exactly in the forward
run. Its derivative is zero almost everywhere, so by default gradients pass it as the identity (the
straight-through estimator, Bengio, Leonard and Courville, "Estimating or propagating gradients through
stochastic neurons for conditional computation", arXiv:1308.3432, 2013): the forward simulation stays
exact and a gradient sees the sensor's gain and offset through it; ``quantiser_gradient="zero"`` gives the
rounding's own derivative instead.

Limits: static errors only (no bandwidth, noise, temperature drift or sampling skew between channels);
three-phase drives only (a five- or six-phase drive is refused when it is built).
"""

import abc
import math
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, is_concrete

__all__ = ["AbstractCurrentSensor", "IdealCurrentSensor", "CurrentSensors", "quantise"]


def _optional_float(x):
    return None if x is None else as_float(x)


def quantise(x: Array, lsb: Array, gradient: str = "straight_through") -> Array:
    """``x`` rounded to a multiple of ``lsb`` (an ADC's reading).

    Args:
        x: Values to round, A.
        lsb: One least significant bit, A (> 0).
        gradient: ``"straight_through"``: the derivative is taken as 1 (the forward value is the exact
            rounding); ``"zero"``: the rounding's own derivative (0 almost everywhere).

    Returns:
        ``lsb round(x / lsb)``, same shape as ``x``.
    """
    rounded = lsb * jnp.round(x / lsb)
    if gradient == "zero":
        return rounded
    # stop_gradient(q) + (x - stop_gradient(x)): the forward value is q exactly (x - x is 0), the
    # derivative with respect to x is 1.
    return jax.lax.stop_gradient(rounded) + (x - jax.lax.stop_gradient(x))


class AbstractCurrentSensor(eqx.Module):
    """The current-measurement block of a drive: true phase currents -> what the controller samples."""

    @abc.abstractmethod
    def measure(self, i_phase: Array, i_ab: Array) -> tuple[Array, Array]:
        """The sampled currents.

        Args:
            i_phase: ``(n,)`` true phase currents, A.
            i_ab: ``(2,)`` true alpha-beta currents, A.

        Returns:
            ``(i_phase, i_ab)`` as measured: ``(n,)`` and ``(2,)``, A.
        """

    def check_phases(self, n_phases: int) -> None:
        """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] when the sensor cannot serve a
        machine of ``n_phases`` phases; called when the drive is built."""

    @property
    def is_ideal(self) -> bool:
        """Whether the measured currents are the true ones."""
        return False


class IdealCurrentSensor(AbstractCurrentSensor):
    """The true currents, exactly (no leaves, no operations)."""

    def measure(self, i_phase: Array, i_ab: Array) -> tuple[Array, Array]:
        return i_phase, i_ab

    @property
    def is_ideal(self) -> bool:
        return True


class CurrentSensors(AbstractCurrentSensor):
    """Offset, gain and ADC quantisation of two or three phase-current sensors (module docstring).

    Args:
        offset_a: ``(k,)`` offset of each sensor, A, for phases a, b (, c); ``k`` = 2 or 3 is the
            number of sensors.
        gain: ``(k,)`` gain of each sensor (1: exact; 1.018: reads 1.8 % high).
        lsb_a: One ADC least significant bit, A (> 0); None: no quantisation.
        quantiser_gradient: How gradients pass the rounding (static): ``"straight_through"`` (default) or
            ``"zero"`` ([`quantise`][pmsmjax.estimators.current_sensors.quantise]).

    Raises:
        ParameterError: For lists of different lengths, other than 2 or 3 sensors, a gain not above 0 or
            an LSB not above 0.
    """

    offset_a: Array = eqx.field(converter=as_float)
    gain: Array = eqx.field(converter=as_float)
    lsb_a: Array | None = eqx.field(converter=_optional_float, default=None)
    quantiser_gradient: Literal["straight_through", "zero"] = eqx.field(
        static=True, default="straight_through"
    )

    def __check_init__(self):
        if self.offset_a.ndim != 1 or self.offset_a.shape != self.gain.shape:
            raise ParameterError(
                f"CurrentSensors: offset_a {tuple(self.offset_a.shape)} and gain {tuple(self.gain.shape)} "
                "must be lists of the same length, one value per sensed phase (a, b or a, b, c)."
            )
        if self.offset_a.shape[0] not in (2, 3):
            raise ParameterError(
                f"CurrentSensors: {self.offset_a.shape[0]} sensors: give 2 (phases a and b, c "
                "reconstructed) or 3 (every phase)."
            )
        if self.quantiser_gradient not in ("straight_through", "zero"):
            raise ParameterError(
                f"CurrentSensors.quantiser_gradient = {self.quantiser_gradient!r}: give "
                "'straight_through' or 'zero'."
            )
        if is_concrete(self.gain) and not bool(jnp.all(self.gain > 0)):
            raise ParameterError(f"CurrentSensors.gain = {self.gain.tolist()}: every gain must be above 0.")
        if self.lsb_a is not None and is_concrete(self.lsb_a):
            lsb = float(jnp.min(self.lsb_a))
            if not (math.isfinite(lsb) and lsb > 0):
                raise ParameterError(f"CurrentSensors.lsb_a = {lsb:g} A: give an LSB above 0 (A).")

    @property
    def n_sensors(self) -> int:
        """Number of sensed phases (2 or 3)."""
        return self.offset_a.shape[-1]

    def check_phases(self, n_phases: int) -> None:
        if n_phases != 3:
            raise ParameterError(
                f"CurrentSensors model a three-phase drive's sensors; this machine has {n_phases} phases: "
                "drop the current-sensor errors for a five- or six-phase drive."
            )

    def measure(self, i_phase: Array, i_ab: Array) -> tuple[Array, Array]:
        sensed = self.gain * i_phase[: self.n_sensors] + self.offset_a
        if self.lsb_a is not None:
            sensed = quantise(sensed, self.lsb_a, self.quantiser_gradient)
        if self.n_sensors == 2:
            sensed = jnp.concatenate([sensed, -(sensed[:1] + sensed[1:2])])
        return sensed, abc_to_alpha_beta(sensed)
