"""Carrier-based sinusoidal PWM and its zero-sequence-injection variants (the book, ch. 2).

All three compare each phase's reference plus a common zero-sequence voltage ``u_0`` with a centre-aligned
carrier sampled once per period (regular sampling): leg duty ``d_x = 1/2 + (u_x + u_0)/U_dc`` with
``u_abc`` the inverse Clarke of the ``(2,)`` reference. The zero sequence does not reach the windings of an
isolated-neutral machine, so it only moves the references away from the carrier's limits:

- [`SinusoidalPWM`][pmsmjax.inverters.spwm.SinusoidalPWM]: ``u_0 = 0``; linear while every phase fits in
  ``+-U_dc/2``: ``|u| <= U_dc/2``.
- [`ThirdHarmonicPWM`][pmsmjax.inverters.spwm.ThirdHarmonicPWM]: ``u_0 = -(|u|/6) cos(3 theta)`` with
  ``theta`` the reference angle (1/6 of the fundamental at three times its frequency); the phase peak falls to
  ``(sqrt3/2)|u|``, linear to ``|u| <= U_dc/sqrt3``. Computed without an angle: ``|u|^3 cos 3theta = Re((u_a +
  j u_b)^3) = u_a^3 - 3 u_a u_b^2``, so ``u_0 = -(u_a^3 - 3 u_a u_b^2) / (6 |u|^2)`` (0 at ``u = 0``).
- [`MinMaxPWM`][pmsmjax.inverters.spwm.MinMaxPWM]: ``u_0 = -(max_x u_x + min_x u_x)/2`` (centres the
  references in the carrier); linear to ``U_dc/sqrt3`` and identical to SVPWM there.

Saturation. Beyond the linear range the duties are clipped to [0, 1] (a leg stays on or off the whole
period); the period average then falls short of the reference and is distorted (low-order harmonics). This
is what a carrier comparison does by itself, so it is the defined behaviour, not an error.
"""

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import alpha_beta_to_abc
from pmsmjax.inverters.base import AbstractModulator
from pmsmjax.spec.validation import ParameterError

SQRT3 = 3.0**0.5


def _phase_references(u_ab_ref: Array) -> Array:
    """``(3,)`` phase references (V) of a ``(2,)`` alpha-beta reference (shape checked when traced)."""
    if jnp.shape(u_ab_ref) != (2,):
        raise ParameterError(f"u_ab_ref must have shape (2,) (alpha, beta), got {jnp.shape(u_ab_ref)}.")
    return alpha_beta_to_abc(u_ab_ref)


def _duties(u_abc: Array, u_0: Array, u_dc: Array) -> Array:
    """Leg duties ``(3,)`` from phase references ``(3,)`` V and a zero sequence V, clipped to [0, 1]."""
    return jnp.clip(0.5 + (u_abc + u_0) / u_dc, 0.0, 1.0)


class SinusoidalPWM(AbstractModulator):
    """Regular-sampled sinusoidal PWM: no zero sequence; linear up to ``U_dc/2`` (phase peak, V).

    Args:
        name: The modulator's name in tables and figures (static).
    """

    name: str = eqx.field(static=True, default="sinusoidal")

    def duties(self, u_ab_ref, u_dc):
        return _duties(_phase_references(u_ab_ref), 0.0, u_dc)

    def linear_limit(self, u_dc):
        return 0.5 * u_dc


def third_harmonic(u_ab: Array) -> Array:
    """Zero-sequence voltage ``-(|u|/6) cos(3 theta)`` of a reference, 0 at the origin.

    Double-where: the division by ``|u|^2`` is only evaluated away from zero, so gradients stay finite there
    (the value tends to 0 as ``|u|``, it is continuous).

    Args:
        u_ab: ``(2,)`` alpha-beta reference, V.

    Returns:
        The zero-sequence voltage, V.
    """
    u_a, u_b = u_ab[0], u_ab[1]
    mag2 = u_a * u_a + u_b * u_b
    nonzero = mag2 > 0
    safe = jnp.where(nonzero, mag2, 1.0)
    return jnp.where(nonzero, -(u_a**3 - 3.0 * u_a * u_b * u_b) / (6.0 * safe), 0.0)


class ThirdHarmonicPWM(AbstractModulator):
    """Sinusoidal PWM with 1/6 third-harmonic injection; linear up to ``U_dc/sqrt3`` (phase peak, V).

    Args:
        name: The modulator's name in tables and figures (static).
    """

    name: str = eqx.field(static=True, default="third_harmonic")

    def duties(self, u_ab_ref, u_dc):
        return _duties(_phase_references(u_ab_ref), third_harmonic(u_ab_ref), u_dc)

    def linear_limit(self, u_dc):
        return u_dc / SQRT3


class MinMaxPWM(AbstractModulator):
    """Min-max zero-sequence injection (carrier-based SVPWM); linear up to ``U_dc/sqrt3`` (V).

    Args:
        name: The modulator's name in tables and figures (static).
    """

    name: str = eqx.field(static=True, default="min_max")

    def duties(self, u_ab_ref, u_dc):
        u = _phase_references(u_ab_ref)
        return _duties(u, -0.5 * (jnp.max(u) + jnp.min(u)), u_dc)

    def linear_limit(self, u_dc):
        return u_dc / SQRT3
