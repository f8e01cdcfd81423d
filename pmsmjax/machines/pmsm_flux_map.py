"""A saturated three-phase PMSM in the rotor frame, from a flux map (:mod:`pmsmjax.machines.flux_map`).

Voltage equations with the flux a function of both currents (cross-saturation):
``u = R i + dpsi/dt + w_e J psi``, ``J = [[0, -1], [1, 0]]``, ``dpsi/dt = L_inc(i) di/dt`` with the
incremental inductance ``L_inc = dpsi/di`` of the map's interpolant, so

    ``di/dt = L_inc(i)^-1 (u - R i - w_e J psi(i))``   (a closed-form 2x2 solve),

and ``T_e = 1.5 p_n (psi_d i_q - psi_q i_d)``. The power balance ``1.5 u.i = 1.5 R |i|^2 + 1.5 i.dpsi/dt
+ T_e w_m`` holds by construction; ``1.5 i.dpsi/dt`` is the rate of the field energy
``W = 1.5 (psi.i - int psi.di)`` (co-energy subtracted) when the map is reciprocal.

**Current as the state, not flux.** The drive samples currents, every block reads them
(:meth:`~pmsmjax.machines.base.AbstractMachine.phase_currents`), and a measured map gives ``psi(i)``, not
``i(psi)``: a flux state would need the inverse map, either by a Newton solve at every RK4 stage or by a
second, resampled map with its own interpolation error. With current as the state one map evaluation
gives both ``psi`` and ``L_inc`` (the interpolant's gradient, analytic), and the 2x2 solve is a handful of
flops; ``L_inc`` is positive definite on and off the grid (the map's checks and the linear extension), so
the solve is always well posed.

:class:`FluxMap` is the interpolant's data as JAX leaves; :class:`PMSMFluxMapdq` is the plant. Its
``motor`` keeps ``R``, ``J``, ``B``, ``pole_pairs`` and the linear model (``L_d``, ``L_q``, ``psi_f``)
derived from the map, which the sub-step rule and a controller's design read; the electrical equations
read only the map.
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.machines.base import AbstractMachine, MachineInput, Mechanics
from pmsmjax.machines.flux_map import FluxMapGrid, excursion, flux_and_inductance
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.machines.pmsm3 import _solve2

__all__ = ["FluxMap", "PMSMFluxMapdq", "flux_map_machine"]


class FluxMap(eqx.Module):
    """The bicubic Hermite interpolant of a :class:`~pmsmjax.machines.flux_map.FluxMapGrid`.

    - `coefficients`: ``(n_d - 1, n_q - 1, 2, 4, 4)`` per-cell polynomial coefficients, Wb;
    - `lower`, `upper`, `step`: ``(2,)`` grid corners and spacing ``[i_d, i_q]``, A.
    """

    coefficients: Array = eqx.field(converter=as_float)
    lower: Array = eqx.field(converter=as_float)
    upper: Array = eqx.field(converter=as_float)
    step: Array = eqx.field(converter=as_float)

    @classmethod
    def from_grid(cls, grid: FluxMapGrid) -> "FluxMap":
        return cls(grid.coefficients(jnp), grid.lower, grid.upper, grid.step)

    def __call__(self, i_dq: Array) -> tuple[Array, Array]:
        """``(psi (2,) Wb, L_inc (2, 2) H)`` at ``i_dq (2,)`` A."""
        return flux_and_inductance(self.coefficients, self.lower, self.step, self.upper, i_dq, jnp)

    def excursion(self, i_dq) -> dict:
        """How far the currents ``i_dq (..., 2)`` (A) of a run went outside the grid
        (:func:`pmsmjax.machines.flux_map.excursion`)."""
        return excursion(self.lower, self.upper, i_dq)


class PMSMFluxMapdq(AbstractMachine):
    """PMSM in the rotor frame with a flux map; state currents ``(2,)`` = [i_d, i_q], A (module docstring).

    **Arguments:**

    - `motor`: :class:`~pmsmjax.machines.PMSMParameters`: ``R``, ``J``, ``B``, ``pole_pairs`` used;
      ``L_d``, ``L_q``, ``psi_f`` the linear model for sub-step checks and controller design only.
    - `flux_map`: :class:`FluxMap`.
    - `mechanics`: ``"dynamic"`` or ``"imposed"`` speed.
    """

    motor: PMSMParameters
    flux_map: FluxMap
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    # The equations see the angle only through the stator-frame voltage: integrate.advance's fast path.
    angle_only_in_voltage: ClassVar[bool] = True

    def flux_dq(self, currents) -> Array:
        """``(2,)`` rotor-frame flux linkage ``[psi_d, psi_q]``, Wb."""
        return self.flux_map(currents)[0]

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        psi, L = self.flux_map(currents)
        u_dq = u.dq(theta_e)
        rotation = omega_e * jnp.stack([-psi[1], psi[0]])
        return _solve2(L, u_dq - self.motor.R * currents - rotation)

    def torque(self, currents, theta_e):
        psi = self.flux_dq(currents)
        return 1.5 * self.motor.pole_pairs * (psi[0] * currents[1] - psi[1] * currents[0])

    def currents_to_dq(self, currents, theta_e):
        return currents

    def currents_from_dq(self, i_dq, theta_e):
        return i_dq


def flux_map_machine(
    grid: FluxMapGrid, R, J, B, pole_pairs: int, *, design_i_q: float = 0.0, mechanics: Mechanics = "dynamic"
) -> PMSMFluxMapdq:
    """The plant of ``grid`` with resistance ``R`` (ohm), inertia ``J`` (kg m^2), friction ``B``
    (N m s/rad); its linear model is :meth:`FluxMapGrid.linear_model` at ``i_q = design_i_q`` (A)."""
    linear = grid.linear_model(design_i_q)
    motor = PMSMParameters(R=R, J=J, B=B, pole_pairs=pole_pairs, **linear)
    return PMSMFluxMapdq(motor, FluxMap.from_grid(grid), mechanics)
