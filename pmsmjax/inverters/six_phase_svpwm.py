"""Space-vector PWM for the dual three-phase machine: two-vector and four-vector SVPWM (BOOK.md chapter 8).

Both pick the 30-degree sector ``k`` of the alpha-beta reference (:mod:`.six_phase_vectors`) and solve for
the dwell times (fractions of the period) of their active vectors; the rest of the period is shared
equally by the zero states 000000 and 111111. Leg ``x``'s duty is then ``d_x = sum_i t_i b_{i,x} + t_0/2``
and the bridge realises it by centre-aligned carrier comparison, so the period average of the applied
voltage is exactly ``sum_i t_i V_i`` (volt-second balance).

- :class:`TwoVectorSVPWM` uses only the two adjacent large vectors L_k, L_k+1:
  ``[L_k L_k+1]_ab t = u_ab / U_dc``. The z1-z2 average ``t_1 z(L_k) + t_2 z(L_k+1)`` is left uncontrolled
  (nonzero: up to 0.1725 U_dc t), and with the z1-z2 subspace's small leakage impedance it drives large 5th
  and 7th harmonic currents. Linear range: the 12-gon of L vectors' inscribed circle,
  ``|u| <= (2/3) cos^2(15 deg) U_dc = 0.6220 U_dc``.
- :class:`FourVectorSVPWM` adds the medium-large vectors collinear with them, ML_k, ML_k+1, and solves the
  4x4 system ``[L_k L_k+1 ML_k ML_k+1] t = [u_ab, u_z] / U_dc`` (Zhao & Lipo 1995), which nulls the z1-z2
  average (``u_z = 0``) or applies a commanded ``u_z``. Linear range for ``u_z = 0``: ``U_dc/sqrt(3)`` (the
  dwell times sum to one at the sector bisectors there), the same as each three-phase set's SVPWM.

Sequence. The four vectors of a sector do not form a chain of nested states (no centre-aligned order
switches them one leg at a time), so the carrier realisation passes through other intermediate states
than L_k, L_k+1, ML_k, ML_k+1 inside the period; its period average is the method's exactly. This is the
usual DSP implementation (leg compare values from the dwell times).

Over-modulation: dwell times beyond the period are scaled to it (direction kept, z1-z2 average of the
four-vector method still zero); a commanded ``u_z`` that would need a negative dwell time is not met
(the negative time is set to zero). Reference: ``(2,)`` [alpha, beta] (``u_z = 0``) or ``(4,)``
[alpha, beta, z1, z2], V.
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.checks.validation import ParameterError
from pmsmjax.inverters.base import AbstractModulator
from pmsmjax.inverters.six_phase_vectors import (
    BISECTORS,
    LARGE,
    LARGE_MAGNITUDE,
    MEDIUM_LARGE,
    STATES,
    VECTORS,
)

__all__ = ["TwoVectorSVPWM", "FourVectorSVPWM", "six_phase_reference", "sector"]


def six_phase_reference(u_ref: Array) -> Array:
    """``(4,)`` [alpha, beta, z1, z2] from a ``(2,)`` or ``(4,)`` reference (shape checked when traced)."""
    shape = jnp.shape(u_ref)
    if shape == (2,):
        return jnp.concatenate([u_ref, jnp.zeros(2, jnp.result_type(u_ref))])
    if shape == (4,):
        return u_ref
    raise ParameterError(
        "a six-phase modulator takes a (2,) [alpha, beta] or (4,) [alpha, beta, z1, z2] reference, "
        f"got {shape}."
    )


def sector(u_ab: Array) -> Array:
    """The 30-degree sector ``k`` (int, 0..11) of a ``(2,)`` alpha-beta vector: between the large vectors at
    ``15 + 30 k`` and ``45 + 30 k`` deg (0 for a zero vector)."""
    return jnp.argmax(jnp.asarray(BISECTORS, u_ab.dtype) @ u_ab)


def _tables(columns):
    """Per sector: the inverse of the vectors' matrix ``(12, m, m)`` and their states ``(12, m, 6)``."""
    m = len(columns)
    inv = np.empty((12, m, m))
    states = np.empty((12, m, 6))
    for k in range(12):
        idx = [c[k] for c in columns]
        inv[k] = np.linalg.inv(VECTORS[idx][:, :m].T)
        states[k] = STATES[idx]
    return inv, states


_next = lambda idx: np.roll(idx, -1)
_TWO_INV, _TWO_STATES = _tables([LARGE, _next(LARGE)])
_FOUR_INV, _FOUR_STATES = _tables([LARGE, _next(LARGE), MEDIUM_LARGE, _next(MEDIUM_LARGE)])


def _duties(t: Array, states: Array) -> Array:
    """Leg duties from dwell fractions ``t (m,)`` of states ``(m, 6)`` (negative times set to 0, scaled
    to the period if they exceed it), the zero states sharing the rest equally."""
    t = jnp.maximum(t, 0.0)
    total = jnp.sum(t)
    over = total > 1.0
    t = t * jnp.where(over, 1.0 / jnp.where(over, total, 1.0), 1.0)  # double-where: finite gradient
    return t @ states + 0.5 * (1.0 - jnp.sum(t))


def _select(table: np.ndarray, k: Array, dtype) -> Array:
    """``table[k]`` as a one-hot product (its reverse-mode derivative stays a product, not a scatter)."""
    one_hot = jax.nn.one_hot(k, 12, dtype=dtype)
    return jnp.tensordot(one_hot, jnp.asarray(table, dtype), axes=1)


class TwoVectorSVPWM(AbstractModulator):
    """Two-vector SVPWM (largest vectors only; z1-z2 uncontrolled). Linear to 0.6220 U_dc (peak, V)."""

    n_phases: ClassVar[int] = 6
    name: str = eqx.field(static=True, default="two-vector")

    def dwell_times(self, u_ref: Array, u_dc: Array) -> tuple[Array, Array]:
        """``(k, t (2,))``: sector and dwell fractions of L_k, L_k+1 before any scaling."""
        u = six_phase_reference(u_ref)
        k = sector(u[:2])
        return k, _select(_TWO_INV, k, u.dtype) @ (u[:2] / u_dc)

    def duties(self, u_ref, u_dc):
        k, t = self.dwell_times(u_ref, u_dc)
        return _duties(t, _select(_TWO_STATES, k, t.dtype))

    def linear_limit(self, u_dc):
        return LARGE_MAGNITUDE * np.cos(np.pi / 12) * u_dc


class FourVectorSVPWM(AbstractModulator):
    """Four-vector SVPWM (L and ML vectors; z1-z2 average zero or as commanded). Linear to U_dc/sqrt(3)."""

    n_phases: ClassVar[int] = 6
    name: str = eqx.field(static=True, default="four-vector")

    def dwell_times(self, u_ref: Array, u_dc: Array) -> tuple[Array, Array]:
        """``(k, t (4,))``: sector and dwell fractions of L_k, L_k+1, ML_k, ML_k+1 before any scaling."""
        u = six_phase_reference(u_ref)
        k = sector(u[:2])
        return k, _select(_FOUR_INV, k, u.dtype) @ (u / u_dc)

    def duties(self, u_ref, u_dc):
        k, t = self.dwell_times(u_ref, u_dc)
        return _duties(t, _select(_FOUR_STATES, k, t.dtype))

    def linear_limit(self, u_dc):
        return u_dc / np.sqrt(3.0)
