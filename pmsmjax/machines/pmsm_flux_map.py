"""A saturated three-phase PMSM in the rotor frame, from a flux map
([`pmsmjax.machines.flux_map`][pmsmjax.machines.flux_map]).

Voltage equations with the flux a function of both currents (cross-saturation):
``u = R i + dpsi/dt + w_e J psi``, ``J = [[0, -1], [1, 0]]``, ``dpsi/dt = L_inc(i) di/dt`` with the
incremental inductance ``L_inc = dpsi/di`` of the map's interpolant, so

    ``di/dt = L_inc(i)^-1 (u - R i - w_e J psi(i))``   (a closed-form 2x2 solve),

and ``T_e = 1.5 p_n (psi_d i_q - psi_q i_d)``. The power balance ``1.5 u.i = 1.5 R |i|^2 + 1.5 i.dpsi/dt
+ T_e w_m`` holds by construction; ``1.5 i.dpsi/dt`` is the rate of the field energy
``W = 1.5 (psi.i - int psi.di)`` (co-energy subtracted) when the map is reciprocal.

**Current as the state, not flux.** The drive samples currents, every block reads them
([`phase_currents`][pmsmjax.machines.base.AbstractMachine.phase_currents]), and a measured map gives
``psi(i)``, not ``i(psi)``: a flux state would need the inverse map, either by a Newton solve at every RK4
stage or by a second, resampled map with its own interpolation error. With current as the state one map
evaluation gives both ``psi`` and ``L_inc`` (the interpolant's gradient, analytic), and the 2x2 solve is a
handful of flops; ``L_inc`` is positive definite on and off the grid (the map's checks and the linear
extension), so the solve is always well posed.

**Integration.** [`PMSMFluxMapdq.split_advance`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq.split_advance]
runs the same classical RK4 as the linear plant
([`pmsmjax.machines.integrate.rk4_step_rotating_hold`][pmsmjax.machines.integrate.rk4_step_rotating_hold]) on
a packed state (`advance_packed`, which says why), with the map evaluated once per stage for both the current
derivative and the torque.

[`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap] is the interpolant's data as JAX leaves;
[`PMSMFluxMapdq`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq] is the plant. Its ``motor`` keeps ``R``,
``J``, ``B``, ``pole_pairs`` and the linear model (``L_d``, ``L_q``, ``psi_f``) derived from the map, which
the sub-step rule and a controller's design read; the electrical equations read only the map.

With ``harmonics`` ([`MagnetHarmonics`][pmsmjax.machines.harmonics.MagnetHarmonics]) the voltage equations
gain the harmonics' rotor-frame EMF ``w_e eps_dq(th)`` and the torque ``1.5 p i . eps_dq`` plus the cogging
torque, as in the linear dq model; the harmonics add to the map's flux and do not saturate.
"""

import dataclasses
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines import dq_equations as dq
from pmsmjax.machines.base import AbstractMachine, MachineInput, MachineState, Mechanics
from pmsmjax.machines.flux_map import FluxMapGrid, excursion, flux_and_inductance
from pmsmjax.machines.harmonics import MagnetHarmonics, stator_axis
from pmsmjax.machines.integrate import rotate_back
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.machines.pmsm3 import _solve2
from pmsmjax.machines.shaft import two_mass_derivative

__all__ = ["FluxMap", "PMSMFluxMapdq", "flux_map_machine"]


class FluxMap(eqx.Module):
    """The bicubic Hermite interpolant of a [`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid].

    Args:
        coefficients: ``(n_d - 1, n_q - 1, 2, 4, 4)`` per-cell polynomial coefficients, Wb.
        lower: ``(2,)`` lowest grid corner ``[i_d, i_q]``, A.
        upper: ``(2,)`` highest grid corner, A.
        step: ``(2,)`` grid spacing, A.
    """

    coefficients: Array = eqx.field(converter=as_float)
    lower: Array = eqx.field(converter=as_float)
    upper: Array = eqx.field(converter=as_float)
    step: Array = eqx.field(converter=as_float)

    @classmethod
    def from_grid(cls, grid: FluxMapGrid) -> "FluxMap":
        """The interpolant of a checked map: its coefficients computed once in float64 NumPy (the ones the
        pre-run checks evaluate), then held as JAX arrays of the default float type."""
        return cls(grid.numpy_coefficients, grid.lower, grid.upper, grid.step)

    def __call__(self, i_dq: Array) -> tuple[Array, Array]:
        """``(psi (2,) Wb, L_inc (2, 2) H)`` at ``i_dq (2,)`` A."""
        return flux_and_inductance(self.coefficients, self.lower, self.step, self.upper, i_dq, jnp)

    def excursion(self, i_dq) -> dict:
        """How far the currents of a run went outside the grid
        ([`pmsmjax.machines.flux_map.excursion`][pmsmjax.machines.flux_map.excursion]).

        Args:
            i_dq: ``(..., 2)`` currents, A.
        """
        return excursion(self.lower, self.upper, i_dq)


class PMSMFluxMapdq(AbstractMachine):
    """PMSM in the rotor frame with a flux map; state currents ``(2,)`` = [i_d, i_q], A (module docstring).

    Args:
        motor: The motor's parameters ([`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters]): ``R``,
            ``J``, ``B``, ``pole_pairs`` used; ``L_d``, ``L_q``, ``psi_f`` the linear model for sub-step
            checks and controller design only.
        flux_map: The map's interpolant.
        mechanics: ``"dynamic"`` or ``"imposed"`` speed.
        magnet_flux_offset: Added to the map's ``psi_d``, Wb: a warm magnet's change of flux
            ([`at_temperature`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq.at_temperature]); ``None``
            (default): the map as measured.
        harmonics: Magnet flux harmonics and cogging torque, or ``None`` (module docstring).
    """

    motor: PMSMParameters
    flux_map: FluxMap
    mechanics: Mechanics = eqx.field(static=True, default="dynamic")
    magnet_flux_offset: Array | None = None
    harmonics: MagnetHarmonics | None = None
    # The equations see the angle only through the stator-frame voltage: integrate.advance's fast path.
    angle_only_in_voltage: ClassVar[bool] = True

    def flux_and_inductance(self, currents) -> tuple[Array, Array]:
        """``(psi (2,) Wb, L_inc (2, 2) H)`` at the dq currents ``currents`` (A): the map's, with the
        warm magnet's ``magnet_flux_offset`` (Wb) added to ``psi_d`` when there is one."""
        psi, L = self.flux_map(currents)
        if self.magnet_flux_offset is not None:
            psi = psi.at[0].add(self.magnet_flux_offset)
        return psi, L

    def at_temperature(self, resistance_factor, flux_factor) -> "PMSMFluxMapdq":
        """The map's machine warm: ``R`` scaled, and the magnet's share of the flux, ``psi_d(0, 0)`` of the
        map, scaled by ``flux_factor`` (``psi_d(i) + (flux_factor - 1) psi_d(0, 0)``; the change of
        saturation with the magnet's flux is not modelled:
        [`pmsmjax.machines.thermal`][pmsmjax.machines.thermal]).

        Args:
            resistance_factor: ``R(T) / R``, dimensionless.
            flux_factor: ``psi_f(T) / psi_f``, dimensionless.
        """
        m = self.motor
        magnet = self.flux_map(jnp.zeros(2, m.R.dtype))[0][0]
        offset = (flux_factor - 1.0) * magnet
        if self.magnet_flux_offset is not None:
            offset = offset + self.magnet_flux_offset
        warm = dataclasses.replace(m, R=m.R * resistance_factor, psi_f=m.psi_f * flux_factor)
        return PMSMFluxMapdq(warm, self.flux_map, self.mechanics, offset, self.harmonics)

    def flux_dq(self, currents) -> Array:
        """Rotor-frame flux linkage ``[psi_d, psi_q]``.

        Args:
            currents: ``(2,)`` dq currents, A.

        Returns:
            ``(2,)`` flux linkage, Wb.
        """
        return self.flux_and_inductance(currents)[0]

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        psi, L = self.flux_and_inductance(currents)
        u_dq = u.dq(theta_e)
        if self.harmonics is not None and self.harmonics.has_flux:
            u_dq = u_dq - omega_e * self.harmonics.emf_dq(theta_e)
        rotation = omega_e * jnp.stack([-psi[1], psi[0]])
        return _solve2(L, u_dq - self.motor.R * currents - rotation)

    def torque(self, currents, theta_e):
        psi = self.flux_dq(currents)
        p = self.motor.pole_pairs
        torque = dq.torque(dq.torque_factor(p), currents[0], currents[1], psi[0], psi[1])
        if self.harmonics is not None:
            torque = torque + self.harmonics.dq_torque(currents, theta_e, p)
        return torque

    def currents_to_dq(self, currents, theta_e):
        return currents

    def currents_from_dq(self, i_dq, theta_e):
        return i_dq

    def stator_axis(self, theta_e):
        """``[cos theta_e, -sin theta_e]`` with harmonics, ``None`` without
        ([`PMSMdq.stator_axis`][pmsmjax.machines.pmsm3.PMSMdq.stator_axis])."""
        return None if self.harmonics is None else stator_axis(theta_e)

    def packed_derivative(self, x, u_dq, load_torque, unit=None) -> Array:
        """Time derivative of the packed state, from one evaluation of the map (the current derivative and
        the torque share its flux).

        Args:
            x: ``(4,)`` packed state ``[i_d, i_q, omega_m, theta_e]``, or ``(6,)`` with a compliant shaft's
                twist (rad) and load speed (rad/s) after them.
            u_dq: ``(2,)`` rotor-frame voltage, V.
            load_torque: Load torque, N m.
            unit: ``(cos theta_e, sin theta_e)`` where the integrator carries them (with harmonics:
                [`MagnetHarmonics.rotor_terms`][pmsmjax.machines.harmonics.MagnetHarmonics.rotor_terms]),
                or ``None``.

        Returns:
            The derivative of ``x``, its shape.
        """
        m = self.motor
        i = x[:2]
        psi, L = self.flux_and_inductance(i)
        omega_e = m.pole_pairs * x[2]
        # the 2x2 solve written out on scalars: one fused expression
        h = self.harmonics
        u_d, u_q = u_dq[0], u_dq[1]
        if h is not None:  # the harmonics' rotor-frame EMF, on scalars (docs/performance.md, "Ripple")
            e_d, e_q, cogging = h.rotor_terms(x[3], unit)
            if h.has_flux:
                u_d, u_q = u_d - omega_e * e_d, u_q - omega_e * e_q
        b_d = u_d - m.R * i[0] + omega_e * psi[1]
        b_q = u_q - m.R * i[1] - omega_e * psi[0]
        inverse_det = 1.0 / (L[0, 0] * L[1, 1] - L[0, 1] * L[1, 0])  # one division on the critical path
        di_d = (L[1, 1] * b_d - L[0, 1] * b_q) * inverse_det
        di_q = (L[0, 0] * b_q - L[1, 0] * b_d) * inverse_det
        dshaft = ()
        if self.mechanics == "dynamic":
            torque = dq.torque(dq.torque_factor(m.pole_pairs), i[0], i[1], psi[0], psi[1])
            if h is not None:
                torque = torque + cogging
                if h.has_flux:
                    torque = torque + 1.5 * m.pole_pairs * (i[0] * e_d + i[1] * e_q)
            if x.shape[0] == 4:
                domega = (torque - load_torque - m.B * x[2]) / m.J
            else:
                domega, d = two_mass_derivative(m, torque, x[2], x[4:], load_torque)
                dshaft = (d[0], d[1])
        else:  # a dynamometer holds the motor's speed; a compliant shaft's load still swings on it
            domega = jnp.zeros_like(x[2])
            if x.shape[0] == 6:
                d = two_mass_derivative(m, 0.0, x[2], x[4:], load_torque)[1]
                dshaft = (d[0], d[1])
        return jnp.stack([di_d, di_q, domega, omega_e, *dshaft])

    def vector_field(self, t, state: MachineState, inputs: MachineInput) -> MachineState:
        """Continuous-time dynamics (diffrax signature), with the map evaluated once.

        Args:
            t: Time (unused).
            state: The state.
            inputs: The held voltage and load torque.
        """
        del t
        x = _packed(state)
        dx = self.packed_derivative(x, inputs.dq(state.theta_e), inputs.load_torque)
        return MachineState(dx[:2], dx[2], dx[3], None if state.shaft is None else dx[4:])

    @property
    def split_advance(self):
        """``(state, inputs, duration, n_substeps) -> state``: `advance_packed`."""
        return lambda state, inputs, duration, n_substeps: advance_packed(
            self, state, inputs, duration, n_substeps
        )


def advance_packed(
    machine: PMSMFluxMapdq, state: MachineState, inputs: MachineInput, duration, n_substeps: int
) -> MachineState:
    """Classical RK4 over ``duration`` in ``n_substeps`` steps on the packed state.

    The same arithmetic as
    [`pmsmjax.machines.integrate.rk4_step_rotating_hold`][pmsmjax.machines.integrate.rk4_step_rotating_hold]
    (a stator-frame held voltage rotated back by each stage's angle increment), on the packed state
    ``[i_d, i_q, omega_m, theta_e]`` with the held voltage, the map evaluated once per stage
    ([`PMSMFluxMapdq.packed_derivative`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq.packed_derivative]).
    Packed rather than the generic integrator on [`MachineState`][pmsmjax.machines.base.MachineState] because
    it is the fastest of the forms timed (docs/performance.md, "Saturated machines").

    Args:
        machine: The flux-map machine.
        state: The state at the interval's start.
        inputs: The input held over the interval.
        duration: Length of the interval, s.
        n_substeps: RK4 steps over the interval.

    Returns:
        The state at the interval's end, angle wrapped to one turn.
    """
    h = duration / n_substeps
    rotating = inputs.frame == "stator"
    turn = (lambda u, delta: rotate_back(u, delta)) if rotating else (lambda u, delta: u)
    # with harmonics and a stator-frame hold, [cos th, -sin th] is carried after the voltage and rotated
    # back with it ([`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance])
    axis = machine.stator_axis(state.theta_e) if rotating else None
    unit = lambda u: None if axis is None else (u[2], -u[3])
    f = lambda x, u: machine.packed_derivative(x, u, inputs.load_torque, unit(u))

    n = 4 if state.shaft is None else 6  # [i_d, i_q, omega_m, theta_e (, twist, load speed)]

    def turns(held, delta):  # the voltage and the carried axis rotated back by the same increment
        if axis is None:
            return turn(held, delta)
        return jnp.concatenate([turn(held[:2], delta), turn(held[2:], delta)])

    def substep(_, c):
        x, u = c[:n], c[n:]
        k1 = f(x, u)
        k2 = f(x + (0.5 * h) * k1, turns(u, (0.5 * h) * k1[3]))
        k3 = f(x + (0.5 * h) * k2, turns(u, (0.5 * h) * k2[3]))
        k4 = f(x + h * k3, turns(u, h * k3[3]))
        increment = (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return jnp.concatenate([x + increment, turns(u, increment[3])])

    x0 = _packed(state)
    held = inputs.dq(state.theta_e)[:2]
    held = held if axis is None else jnp.concatenate([held, axis])
    c = jax.lax.fori_loop(0, n_substeps, substep, jnp.concatenate([x0, held]))
    return MachineState(c[:2], c[2], wrap_angle(c[3]), None if state.shaft is None else c[4:6])


def _packed(state: MachineState) -> Array:
    """``[i_d, i_q, omega_m, theta_e]`` (and a compliant shaft's ``[twist, load speed]``) in one vector."""
    dtype = state.currents.dtype
    parts = [state.currents, jnp.stack([state.omega_m, state.theta_e]).astype(dtype)]
    return jnp.concatenate(parts if state.shaft is None else parts + [state.shaft.astype(dtype)])


def flux_map_machine(
    grid: FluxMapGrid, R, J, B, pole_pairs: int, *, design_i_q: float = 0.0, mechanics: Mechanics = "dynamic"
) -> PMSMFluxMapdq:
    """The plant of a flux map.

    Its linear model (for sub-step checks and controller design) is
    [`FluxMapGrid.linear_model`][pmsmjax.machines.flux_map.FluxMapGrid.linear_model] at ``i_q = design_i_q``.

    Args:
        grid: The checked flux map.
        R: Phase resistance, ohm.
        J: Inertia, kg m^2.
        B: Viscous friction, N m s/rad.
        pole_pairs: Number of pole pairs.
        design_i_q: q current of the linear model's inductances, A.
        mechanics: ``"dynamic"`` or ``"imposed"`` speed.

    Returns:
        The [`PMSMFluxMapdq`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq].
    """
    linear = grid.linear_model(design_i_q)
    motor = PMSMParameters(R=R, J=J, B=B, pole_pairs=pole_pairs, **linear)
    return PMSMFluxMapdq(motor, FluxMap.from_grid(grid), mechanics)
