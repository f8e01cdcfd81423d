"""The machine interface shared by every plant model.

A machine is a continuous-time system ``dx/dt = f(t, x, inputs)`` whose state is a
[`MachineState`][pmsmjax.machines.base.MachineState] (frame-specific currents, mechanical speed, electrical
angle). The same vector field serves the fixed-step scan
([`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance]), diffrax adaptive solves and
linearisation (``jax.jacfwd`` of
[`AbstractMachine.vector_field`][pmsmjax.machines.base.AbstractMachine.vector_field]).
"""

import abc
import dataclasses
from collections.abc import Callable
from typing import ClassVar, Literal

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import dq_to_abc, inverse_park, park
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.machines.shaft import has_shaft, initial_shaft_state, two_mass_derivative

Mechanics = Literal["dynamic", "imposed"]
HoldFrame = Literal["stator", "rotor"]


class MachineState(eqx.Module):
    """State of a machine model.

    Attributes:
        currents: ``(n,)`` stator currents in the model's own frame (dq, alpha-beta or abc), A.
        omega_m: Mechanical speed, rad/s.
        theta_e: Electrical rotor angle (d axis from the A axis), rad; wrapped once per control period.
        shaft: ``(2,)`` a compliant shaft's twist (rad) and load speed (rad/s)
            ([`pmsmjax.machines.shaft`][pmsmjax.machines.shaft]); ``None`` for a rigid shaft.
    """

    currents: Array
    omega_m: Array
    theta_e: Array
    shaft: Array | None = None


class MachineInput(eqx.Module):
    """What drives the machine over an interval: a held voltage and a load torque.

    A real inverter holds its voltage in the stator frame; a log replayed from another simulator's dq model
    usually held it in the rotor frame.

    Attributes:
        u: ``(2,)`` held voltage, V; alpha-beta if ``frame == "stator"``, dq if ``frame == "rotor"``.
            Multi-phase machines take ``(2 n_planes,)``: the fundamental plane first (alpha-beta or dq by
            ``frame``), then the other VSD planes (z1-z2, ...), which are always stationary.
        load_torque: Load torque opposing motion, N m.
        frame: Which frame the voltage is held in (static): ``"stator"`` or ``"rotor"``.
        stator_axis: ``(2,)`` the stator's alpha axis seen from the rotor frame, ``[cos theta_e, -sin
            theta_e]``, where the integrator carries it through the RK4 stages as it carries the held
            voltage ([`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance]; for the
            machines whose [`stator_axis`][pmsmjax.machines.base.AbstractMachine.stator_axis] is not
            ``None``); ``None``: the machine evaluates what it needs from the angle.
    """

    u: Array
    load_torque: Array
    frame: HoldFrame = eqx.field(static=True, default="stator")
    stator_axis: Array | None = None

    def angle_cos_sin(self) -> tuple[Array, Array] | None:
        """``(cos theta_e, sin theta_e)`` from the carried
        [`stator_axis`][pmsmjax.machines.base.MachineInput], or ``None`` when none is carried."""
        return None if self.stator_axis is None else (self.stator_axis[0], -self.stator_axis[1])

    def alpha_beta(self, theta_e: Array) -> Array:
        """The held voltage seen in the stator frame.

        Args:
            theta_e: Electrical rotor angle, rad.
        """
        return self.u if self.frame == "stator" else _first_plane(inverse_park, self.u, theta_e)

    def dq(self, theta_e: Array) -> Array:
        """The held voltage seen in the rotor frame.

        Args:
            theta_e: Electrical rotor angle, rad.
        """
        return _first_plane(park, self.u, theta_e) if self.frame == "stator" else self.u


def _first_plane(rotate, u: Array, theta_e: Array) -> Array:
    """``rotate`` applied to the fundamental plane ``u[:2]``; further planes (multi-phase) pass unchanged."""
    if u.shape[-1] == 2:
        return rotate(u, theta_e)
    return jnp.concatenate([rotate(u[..., :2], theta_e), u[..., 2:]], axis=-1)


class AbstractMachine(eqx.Module):
    """A PMSM model in one reference frame.

    ``n_phases`` (class constant) is the number of stator phases, i.e. of inverter legs: 3 here; the
    multi-phase machines override it and
    [`phase_currents`][pmsmjax.machines.base.AbstractMachine.phase_currents] /
    [`stationary_currents`][pmsmjax.machines.base.AbstractMachine.stationary_currents]. Subclasses implement
    the electrical part in their frame; the mechanics are shared: ``J dw_m/dt = T_e - T_L - B w_m``
    (``mechanics="dynamic"``; with a compliant shaft in the motor's parameters, the two-mass mechanics of
    [`pmsmjax.machines.shaft`][pmsmjax.machines.shaft], the load torque on the load side, and under an
    imposed speed the load swinging on the held motor) or ``dw_m/dt = 0`` with the speed set from outside
    each period (``mechanics="imposed"``, a dynamometer); ``dth_e/dt = p_n w_m``.
    """

    motor: eqx.AbstractVar[PMSMParameters]
    mechanics: eqx.AbstractVar[Mechanics]
    n_phases: ClassVar[int] = 3
    #: The equations see the rotor angle only through a stator-frame held voltage read in the rotor frame
    #: (the dq models): [`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance] then
    #: rotates that voltage by each RK4 stage's angle increment instead of evaluating trigonometry of the
    #: absolute angle.
    angle_only_in_voltage: ClassVar[bool] = False

    @property
    def split_advance(self) -> Callable[[MachineState, MachineInput, float, int], MachineState] | None:
        """``(state, inputs, duration, n_substeps) -> state``: this machine's own integrator over an
        interval, which [`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance] uses in
        place of its RK4 (the flux-map model's packed state, the balanced multi-phase model's separately
        integrated planes); ``None`` (here): the generic RK4."""
        return None

    def stator_axis(self, theta_e: Array) -> Array | None:
        """``(2,)`` ``[cos theta_e, -sin theta_e]`` for the integrator to carry through the RK4 stages
        ([`MachineInput.stator_axis`][pmsmjax.machines.base.MachineInput]), for a machine whose equations
        read trigonometry of the angle besides the held voltage (the dq models with magnet harmonics);
        ``None`` (here): nothing to carry.

        Args:
            theta_e: Electrical rotor angle, rad.
        """
        return None

    def stage_torque(self, currents: Array, theta_e: Array, inputs: MachineInput) -> Array:
        """The torque at an RK4 stage, N m: [`torque`][pmsmjax.machines.base.AbstractMachine.torque]
        here; a machine that reads what the integrator carries in ``inputs`` (its
        [`stator_axis`][pmsmjax.machines.base.MachineInput]) overrides it.

        Args:
            currents: Currents in the model's frame, A.
            theta_e: Electrical rotor angle, rad.
            inputs: The stage's input.
        """
        return self.torque(currents, theta_e)

    # --- frame-specific part -------------------------------------------------------------------
    @abc.abstractmethod
    def current_derivative(self, currents: Array, theta_e: Array, omega_e: Array, u: MachineInput):
        """d(currents)/dt in the model's frame, A/s."""

    @abc.abstractmethod
    def torque(self, currents: Array, theta_e: Array) -> Array:
        """Electromagnetic torque, N m."""

    @abc.abstractmethod
    def currents_to_dq(self, currents: Array, theta_e: Array) -> Array:
        """Model-frame currents -> ``(2,)`` dq currents, A."""

    @abc.abstractmethod
    def currents_from_dq(self, i_dq: Array, theta_e: Array) -> Array:
        """``(2,)`` dq currents -> model-frame currents (zero sequence 0), A."""

    # --- shared ----------------------------------------------------------------------------------
    def at_temperature(self, resistance_factor: Array, flux_factor: Array) -> "AbstractMachine":
        """This machine with its stator resistance and magnet flux scaled (a warm motor,
        [`pmsmjax.machines.thermal`][pmsmjax.machines.thermal]): ``R resistance_factor`` and
        ``psi_f flux_factor``; every other parameter unchanged.

        Here the motor's ``R`` and ``psi_f`` (every model whose equations read them: dq, alpha-beta, abc,
        d-axis saturation); the flux-map model overrides it.

        Args:
            resistance_factor: ``R(T) / R``, dimensionless.
            flux_factor: ``psi_f(T) / psi_f``, dimensionless.
        """
        m = self.motor
        warm = dataclasses.replace(m, R=m.R * resistance_factor, psi_f=m.psi_f * flux_factor)
        return dataclasses.replace(self, motor=warm)

    def initial_state(self, i_dq=(0.0, 0.0), omega_m=0.0, theta_e=0.0) -> MachineState:
        """State with the given dq currents, speed and angle.

        Args:
            i_dq: ``(2,)`` dq currents, A.
            omega_m: Mechanical speed, rad/s.
            theta_e: Electrical rotor angle, rad.
        """
        dtype = self.motor.R.dtype
        theta = jnp.asarray(theta_e, dtype)
        i_dq = jnp.asarray(i_dq, dtype)
        omega = jnp.asarray(omega_m, dtype)
        shaft = initial_shaft_state(omega, dtype) if has_shaft(self.motor) else None
        return MachineState(self.currents_from_dq(i_dq, theta), omega, theta, shaft)

    def vector_field(self, t, state: MachineState, inputs: MachineInput) -> MachineState:
        """Continuous-time dynamics ``dx/dt`` (diffrax signature ``f(t, y, args)``).

        Args:
            t: Time (unused: the dynamics are autonomous under a held input).
            state: The state ``x``.
            inputs: The held voltage and load torque.

        Returns:
            ``dx/dt`` as a [`MachineState`][pmsmjax.machines.base.MachineState] (current derivatives A/s,
            angular acceleration rad/s^2, electrical speed rad/s).
        """
        del t
        m = self.motor
        omega_e = m.pole_pairs * state.omega_m
        di = self.current_derivative(state.currents, state.theta_e, omega_e, inputs)
        dshaft = None
        if self.mechanics == "dynamic":
            torque = self.stage_torque(state.currents, state.theta_e, inputs)
            if state.shaft is None:
                domega = (torque - inputs.load_torque - m.B * state.omega_m) / m.J
            else:
                domega, dshaft = two_mass_derivative(
                    m, torque, state.omega_m, state.shaft, inputs.load_torque
                )
        else:  # a dynamometer holds the motor's speed; a compliant shaft's load still swings on it
            domega = jnp.zeros_like(state.omega_m)
            if state.shaft is not None:
                dshaft = two_mass_derivative(m, 0.0, state.omega_m, state.shaft, inputs.load_torque)[1]
        return MachineState(di, domega, omega_e, dshaft)

    def currents_dq(self, state: MachineState) -> Array:
        """dq currents of ``state`` (fundamental plane, at the state's rotor angle).

        Args:
            state: The machine's state.

        Returns:
            ``(2,)`` dq currents, A.
        """
        return self.currents_to_dq(state.currents, state.theta_e)

    def electromagnetic_torque(self, state: MachineState) -> Array:
        """Electromagnetic torque of ``state``, N m (positive accelerates positive rotation).

        Args:
            state: The machine's state.
        """
        return self.torque(state.currents, state.theta_e)

    def phase_currents(self, state: MachineState) -> Array:
        """Phase currents, what the drive's current sensors measure.

        Args:
            state: The machine's state.

        Returns:
            ``(n,)`` phase currents, A.
        """
        return dq_to_abc(self.currents_dq(state), state.theta_e)

    def stationary_currents(self, state: MachineState) -> Array:
        """Alpha-beta (fundamental-plane) currents.

        Args:
            state: The machine's state.

        Returns:
            ``(2,)`` alpha-beta currents, A.
        """
        return inverse_park(self.currents_dq(state), state.theta_e)
