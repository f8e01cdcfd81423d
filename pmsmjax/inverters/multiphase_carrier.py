"""Carrier PWM with zero-sequence injection for any multi-phase layout (the book, ch. 8: six phases, one
min-max zero sequence per three-phase set, preset name ``double-zs``; chapter 10: five phases).

The VSD reference (``(2,)`` alpha-beta, the other planes 0, or the full ``(2 n_planes,)``) becomes phase
references by the inverse VSD
([`pmsmjax.frames.multiphase.inverse_vsd`][pmsmjax.frames.multiphase.inverse_vsd], each star's zero sequence
0; six phases: each set's stationary vector is ``u_ab +- conj(u_z)`` in the common frame); each star then gets
one zero sequence, which its isolated neutral removes from the windings, and each leg is compared with the
centre-aligned carrier: ``d_x = 1/2 + (u_x + u_0,S)/U_dc``, clipped to [0, 1].

- ``injection="min-max"`` (default): ``u_0,S = -(max_S u + min_S u)/2`` centres each star's references
  in the DC link. For a balanced star of ``m`` phases (``m`` odd) the spread ``max - min`` of a set of
  amplitude ``U`` peaks at ``2 U cos(pi/(2m))``, so the linear range is ``U_dc / (2 cos(pi/(2m)))``:
  five phases ``0.5257 U_dc`` (5.15 % above sinusoidal PWM), three-phase stars ``U_dc/sqrt(3)``. On a
  three-phase star min-max injection is the three-phase [`MinMaxPWM`][pmsmjax.inverters.spwm.MinMaxPWM], which
  is SVPWM inside the linear range (the book, ch. 2): for six phases these duties equal those of
  [`DecoupledSVPWM`][pmsmjax.inverters.decoupled_svpwm.DecoupledSVPWM] (one book SVPWM per set), two different
  constructions checked against each other in the tests.
- ``injection="none"``: sinusoidal PWM, linear to ``U_dc/2``.

With a nonzero second-plane reference the phase references are no longer one balanced set and the limit
applies to their actual spread (duties clip beyond it; six phases: a commanded ``u_z`` is exact while
``|u_ab +- conj(u_z)|`` stays inside both hexagons).
"""

import math
from typing import Literal

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import FIVE_PHASE, PhaseLayout, inverse_vsd
from pmsmjax.inverters.base import AbstractModulator
from pmsmjax.inverters.multiphase_svpwm import padded_reference
from pmsmjax.spec.validation import ParameterError, check_choice

__all__ = ["ZeroSequencePWM"]

Injection = Literal["min-max", "none"]


class ZeroSequencePWM(AbstractModulator):
    """Carrier PWM with one zero sequence per star (module docstring).

    Args:
        layout: The winding (static, default five phases).
        injection: ``"min-max"`` or ``"none"`` (static).
        name: The modulator's name in tables and figures (static).
    """

    layout: PhaseLayout = eqx.field(static=True, default=FIVE_PHASE)
    injection: Injection = eqx.field(static=True, default="min-max")
    name: str = eqx.field(static=True, default="carrier")

    def __check_init__(self):
        self.layout.check()
        check_choice("injection", self.injection, ("min-max", "none"))
        if self.injection == "min-max":
            for group in self.layout.neutrals:
                m = len(group)
                g = np.sort(
                    np.mod(
                        np.asarray(self.layout.angles)[list(group)] - self.layout.angles[group[0]], 2 * np.pi
                    )
                )
                if m % 2 == 0 or not np.allclose(g, 2 * np.pi * np.arange(m) / m, atol=1e-9):
                    raise ParameterError(
                        f"ZeroSequencePWM min-max: each star must be a symmetrical set of an odd number of "
                        f"phases for the stated linear range; layout {self.layout.name!r} has {group}."
                    )

    @property
    def n_phases(self) -> int:  # type: ignore[override]
        return self.layout.n

    def phase_references(self, u_ref: Array) -> Array:
        """Phase references of a reference voltage.

        Args:
            u_ref: ``(2,)`` alpha-beta or full VSD reference, V.

        Returns:
            ``(n,)`` phase references, V.
        """
        return inverse_vsd(padded_reference(u_ref, self.layout.n_active), self.layout)

    def duties(self, u_ref, u_dc):
        u = self.phase_references(u_ref)
        if self.injection == "none":
            return jnp.clip(0.5 + u / u_dc, 0.0, 1.0)
        u_0 = jnp.zeros_like(u)
        for group in self.layout.neutrals:
            idx = np.asarray(group)
            mask = np.zeros(self.layout.n)
            mask[idx] = 1.0
            zs = -0.5 * (jnp.max(u[idx]) + jnp.min(u[idx]))
            u_0 = u_0 + jnp.asarray(mask, u.dtype) * zs
        return jnp.clip(0.5 + (u + u_0) / u_dc, 0.0, 1.0)

    def linear_limit(self, u_dc):
        if self.injection == "none":
            return 0.5 * u_dc
        m = max(len(g) for g in self.layout.neutrals)
        if m == 3:
            # The three-phase hexagon's U_dc/sqrt(3), written as MinMaxPWM and SVPWM write it
            # (2 cos(pi/6) rounds one ulp above sqrt(3)).
            return u_dc / np.sqrt(3.0)
        return u_dc / (2.0 * math.cos(math.pi / (2 * m)))
