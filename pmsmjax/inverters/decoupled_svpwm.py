"""Decoupled SVPWM for the dual three-phase machine: the book's three-phase SVPWM on each set (the
book, ch. 8.4).

The reference ``[alpha, beta, z1, z2]`` (z1-z2 zero for a ``(2,)`` reference) is split into the two
sets' phase references by the inverse VSD
([`pmsmjax.frames.multiphase.inverse_vsd`][pmsmjax.frames.multiphase.inverse_vsd]; each star's zero
sequence 0): equivalently each set's stationary vector is ``u_ab +- conj(u_z)`` in the common frame. Each set
is then modulated on its own by
[`pmsmjax.inverters.svpwm.switching_times`][pmsmjax.inverters.svpwm.switching_times], set UVW in its own
alpha-beta frame (its alpha axis is the U axis, 30 deg ahead).

Inside the linear range this gives the duties of carrier PWM with one min-max zero sequence per set
([`ZeroSequencePWM`][pmsmjax.inverters.multiphase_carrier.ZeroSequencePWM] on the six-phase layout, preset
name ``double-zs``; min-max injection is SVPWM, the book, ch. 2). With ``u_z = 0`` both sets carry the same
vector, so each set's hexagon limits it: linear to ``U_dc/sqrt(3)``; a commanded ``u_z`` is exact while
``|u_ab +- conj(u_z)|`` stays inside both hexagons. Beyond it SVPWM scales a set's dwell times to the
period (direction kept), where carrier PWM clips its duties.
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax.frames.multiphase import SIX_PHASE, inverse_vsd
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.base import AbstractModulator
from pmsmjax.inverters.multiphase_svpwm import padded_reference
from pmsmjax.inverters.svpwm import switching_times

__all__ = ["DecoupledSVPWM"]


class DecoupledSVPWM(AbstractModulator):
    """Two three-phase SVPWMs, one per set (module docstring). Reference ``(2,)`` or ``(4,)`` V; linear to
    ``U_dc/sqrt(3)`` (peak, V).

    Args:
        name: The modulator's name in tables and figures (static).
    """

    n_phases: ClassVar[int] = 6
    name: str = eqx.field(static=True, default="decoupled")

    def duties(self, u_ref, u_dc):
        u = inverse_vsd(padded_reference(u_ref, SIX_PHASE.n_active), SIX_PHASE)
        # abc_to_alpha_beta of a set's phases is that set's vector in its own frame (alpha on A or on U).
        t1, _, _ = switching_times(abc_to_alpha_beta(u[:3]), u_dc, 1.0)
        t2, _, _ = switching_times(abc_to_alpha_beta(u[3:]), u_dc, 1.0)
        return 1.0 - 2.0 * jnp.concatenate([t1, t2])

    def linear_limit(self, u_dc):
        return u_dc / np.sqrt(3.0)
