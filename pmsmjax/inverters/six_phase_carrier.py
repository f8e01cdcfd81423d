"""Dual three-phase PWM built from three-phase methods, one per star (BOOK.md chapter 8).

The reference ``[alpha, beta, z1, z2]`` (z1-z2 zero for a ``(2,)`` reference) is split into the two
sets' phase references by the inverse VSD (:func:`pmsmjax.frames.multiphase.inverse_vsd`; each star's
zero sequence 0): equivalently each set's stationary vector is ``u_ab +- conj(u_z)`` in the common frame.
Each set is then modulated on its own:

- :class:`DecoupledSVPWM`: the book's three-phase SVPWM (:func:`pmsmjax.inverters.svpwm.switching_times`)
  on each set, set UVW in its own alpha-beta frame (its alpha axis is the U axis, 30 deg ahead).
- :class:`DoubleZeroSequencePWM`: carrier comparison with one min-max zero sequence per set,
  ``u_0,S = -(max_S u + min_S u)/2`` (the three-phase :class:`~pmsmjax.inverters.MinMaxPWM` twice).

Inside the linear range the two give identical duties (min-max injection is SVPWM, BOOK.md chapter 2):
tests/test_six_phase_pwm.py checks it, which tests each against an independent construction. With
``u_z = 0`` both sets carry the same vector, so each set's hexagon limits it: linear to ``U_dc/sqrt(3)``;
a commanded ``u_z`` is exact while ``|u_ab +- conj(u_z)|`` stays inside both hexagons. Beyond it, SVPWM
scales a set's dwell times to the period (direction kept), carrier PWM clips its duties.
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import SIX_PHASE, inverse_vsd
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.base import AbstractModulator
from pmsmjax.inverters.six_phase_svpwm import six_phase_reference
from pmsmjax.inverters.svpwm import switching_times

__all__ = ["DecoupledSVPWM", "DoubleZeroSequencePWM", "set_references"]


def set_references(u_ref: Array) -> Array:
    """``(6,)`` phase references (V) of a ``(2,)`` or ``(4,)`` six-phase reference."""
    return inverse_vsd(six_phase_reference(u_ref), SIX_PHASE)


class DecoupledSVPWM(AbstractModulator):
    """Two three-phase SVPWMs, one per set (module docstring). Linear to ``U_dc/sqrt(3)`` (peak, V)."""

    n_phases: ClassVar[int] = 6
    name: str = eqx.field(static=True, default="decoupled")

    def duties(self, u_ref, u_dc):
        u = set_references(u_ref)
        # abc_to_alpha_beta of a set's phases is that set's vector in its own frame (alpha on A or on U).
        t1, _, _ = switching_times(abc_to_alpha_beta(u[:3]), u_dc, 1.0)
        t2, _, _ = switching_times(abc_to_alpha_beta(u[3:]), u_dc, 1.0)
        return 1.0 - 2.0 * jnp.concatenate([t1, t2])

    def linear_limit(self, u_dc):
        return u_dc / np.sqrt(3.0)


class DoubleZeroSequencePWM(AbstractModulator):
    """Carrier PWM with a min-max zero sequence per set (module docstring). Linear to ``U_dc/sqrt(3)``."""

    n_phases: ClassVar[int] = 6
    name: str = eqx.field(static=True, default="double-zs")

    def duties(self, u_ref, u_dc):
        u = set_references(u_ref)
        u1, u2 = u[:3], u[3:]
        u_0 = jnp.concatenate(
            [
                jnp.full(3, -0.5 * (jnp.max(u1) + jnp.min(u1))),
                jnp.full(3, -0.5 * (jnp.max(u2) + jnp.min(u2))),
            ]
        )
        return jnp.clip(0.5 + (u + u_0) / u_dc, 0.0, 1.0)

    def linear_limit(self, u_dc):
        return u_dc / np.sqrt(3.0)
