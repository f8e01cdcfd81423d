"""Fixed-step integration of a machine over an interval with a held input.

A rotor-frame (dq) machine fed by a voltage held in the stator frame sees that voltage rotate backwards
as the rotor turns: at an RK4 stage whose angle is ``theta_n + delta`` it is ``R(-delta) u_dq(theta_n)``.
[`advance`][pmsmjax.machines.integrate.advance] evaluates that rotation by a short Taylor series of
``cos delta`` and ``sin delta`` (``|delta|`` is at most one sub-step's electrical angle, <= 0.5 rad under the
sub-step check of [`max_stable_substep`][pmsmjax.machines.integrate.max_stable_substep], where the series is
exact to float64 rounding) instead of a cosine and a sine of the absolute angle at every stage: the same
equations without the 80 transcendental evaluations per period, which dominate a drive step's cost on CPU
(docs/performance.md, "Engine").
"""

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.base import AbstractMachine, MachineInput, MachineState
from pmsmjax.spec.validation import is_concrete


def rk4_step(machine: AbstractMachine, state: MachineState, inputs: MachineInput, h) -> MachineState:
    """One classical Runge-Kutta step.

    Args:
        machine: The machine model.
        state: The state at the step's start.
        inputs: The input held over the step.
        h: Step length, s.

    Returns:
        The state after ``h``.
    """
    f = lambda x: machine.vector_field(None, x, inputs)
    add = lambda x, k, a: jax.tree.map(lambda xi, ki: xi + a * ki, x, k)
    k1 = f(state)
    k2 = f(add(state, k1, 0.5 * h))
    k3 = f(add(state, k2, 0.5 * h))
    k4 = f(add(state, k3, h))
    return jax.tree.map(
        lambda x, a, b, c, d: x + (h / 6.0) * (a + 2.0 * b + 2.0 * c + d), state, k1, k2, k3, k4
    )


# Denominators of the nested Taylor series: cos d = 1 - d^2/2 (1 - d^2/12 (1 - ...)), (2k-1) 2k, and
# sin d = d (1 - d^2/6 (1 - d^2/20 (1 - ...))), 2k (2k+1). Multiplied as reciprocals: a division per term
# cost 17 % of a Monte Carlo run (measured), and the results were bitwise the same.
_COS_DENOMINATORS = (2.0, 12.0, 30.0, 56.0, 90.0, 132.0, 182.0)
_SIN_DENOMINATORS = (6.0, 20.0, 42.0, 72.0, 110.0, 156.0)


def rotate_back(x_dq, delta):
    """``x_dq`` seen from a rotor frame advanced by ``delta``: ``R(-delta) x_dq``.

    Taylor series of cos and sin. In float64 to ``delta^14`` (truncation below 1e-16 for
    ``|delta| <= 0.5``, 1e-12 at 1 rad); in float32 to ``delta^9`` (below 3e-10 at 0.5 rad, far under
    float32's 6e-8 resolution).

    Args:
        x_dq: ``(2,)`` rotor-frame vector; a longer vector (a multi-phase machine's ``[d, q, z1, z2, ...]``)
            has only its first two components rotated.
        delta: Angle the frame advanced, rad.
    """
    d2 = delta * delta
    short = jnp.finfo(jnp.result_type(d2)).eps > 1e-10
    n_cos, n_sin = (4, 4) if short else (7, 6)
    c = 1.0
    for a in reversed(_COS_DENOMINATORS[:n_cos]):
        c = 1.0 - d2 * (1.0 / a) * c
    s = 1.0
    for a in reversed(_SIN_DENOMINATORS[:n_sin]):
        s = 1.0 - d2 * (1.0 / a) * s
    s = delta * s
    rotated = jnp.stack([x_dq[0] * c + x_dq[1] * s, -x_dq[0] * s + x_dq[1] * c])
    # Multi-phase machines: the planes after the fundamental are stationary, they pass unrotated.
    return rotated if x_dq.shape[0] == 2 else jnp.concatenate([rotated, x_dq[2:]])


def rk4_step_rotating_hold(
    machine: AbstractMachine, state: MachineState, u_dq, load_torque, h, stator_axis=None
):  # fmt: skip
    """One RK4 step of a dq machine under a voltage held in the stator frame.

    Each stage's voltage is ``u_dq`` rotated back by the stage's angle increment
    ([`rotate_back`][pmsmjax.machines.integrate.rotate_back]), so no absolute-angle trigonometry is evaluated.
    A carried ``stator_axis`` is rotated the same way (the same series of the same increment).

    Args:
        machine: A dq machine model.
        state: The state at the step's start.
        u_dq: ``(2,)`` the held voltage as read at the step's start angle, V.
        load_torque: Load torque, N m.
        h: Step length, s.
        stator_axis: ``(2,)`` ``[cos theta_e, -sin theta_e]`` at the step's start angle for a machine that
            reads it ([`MachineInput.stator_axis`][pmsmjax.machines.base.MachineInput]), or ``None``.

    Returns:
        ``(state after h, the voltage read at the end angle)``, and the stator axis at the end angle as a
        third element when ``stator_axis`` is given.
    """
    carried = stator_axis is not None

    def inputs(delta):
        if delta is None:
            return MachineInput(u_dq, load_torque, "rotor", stator_axis)
        axis = rotate_back(stator_axis, delta) if carried else None
        return MachineInput(rotate_back(u_dq, delta), load_torque, "rotor", axis)

    if not carried:
        # Without position-dependent terms the stages stay on the state's leaves: the compiled program is
        # then the same for every batch width, so Monte Carlo results are bitwise equal across chunk sizes
        # and device counts (docs/scaling.md); on the packed vector below they differ in the last bit.
        f = lambda x, delta: machine.vector_field(None, x, inputs(delta))
        add = lambda x, k, a: jax.tree.map(lambda xi, ki: xi + a * ki, x, k)
        k1 = f(state, None)
        k2 = f(add(state, k1, 0.5 * h), 0.5 * h * k1.theta_e)
        k3 = f(add(state, k2, 0.5 * h), 0.5 * h * k2.theta_e)
        k4 = f(add(state, k3, h), h * k3.theta_e)
        increment = jax.tree.map(lambda a, b, c, d: (h / 6.0) * (a + 2.0 * b + 2.0 * c + d), k1, k2, k3, k4)
        new_state = jax.tree.map(lambda x, dx: x + dx, state, increment)
        return new_state, rotate_back(u_dq, increment.theta_e)
    # With harmonics, the stages' arithmetic on the state packed into one vector (ravel order: currents,
    # omega_m, theta_e, shaft): XLA:CPU then computes a stage's derivative in one fused kernel, where on the
    # separate leaves it copied the derivative's whole chain (the harmonics' terms) into every kernel that
    # read one of them (docs/performance.md, "Ripple"). The same operations per component; XLA compiles them
    # into other kernels, so results agree with the leaf-by-leaf form to float rounding (1e-14 relative in
    # float64).
    x0, unravel = ravel_pytree(state)
    angle = state.currents.size + state.omega_m.size
    f = lambda x, delta: ravel_pytree(machine.vector_field(None, unravel(x), inputs(delta)))[0]
    k1 = f(x0, None)
    k2 = f(x0 + (0.5 * h) * k1, 0.5 * h * k1[angle])
    k3 = f(x0 + (0.5 * h) * k2, 0.5 * h * k2[angle])
    k4 = f(x0 + h * k3, h * k3[angle])
    increment = (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    new_state = unravel(x0 + increment)
    return new_state, rotate_back(u_dq, increment[angle]), rotate_back(stator_axis, increment[angle])


def advance(
    machine: AbstractMachine,
    state: MachineState,
    inputs: MachineInput,
    duration,
    n_substeps: int,
    unroll: bool = False,
) -> MachineState:
    """Integrate over ``duration`` with ``n_substeps`` RK4 steps; the angle is wrapped at the end.

    Wrapping only at the interval end keeps every RK4 stage on a continuous angle. Machines whose
    equations depend on the angle only through a stator-frame held voltage (``angle_only_in_voltage``,
    the dq model) take [`rk4_step_rotating_hold`][pmsmjax.machines.integrate.rk4_step_rotating_hold] (see the
    module docstring), carrying the machine's
    [`stator_axis`][pmsmjax.machines.base.AbstractMachine.stator_axis] with the voltage when it has one. A
    machine with a [`split_advance`][pmsmjax.machines.base.AbstractMachine.split_advance] (the flux-map
    model, the balanced multi-phase dq model) integrates itself.

    Args:
        machine: The machine model.
        state: The state at the interval's start.
        inputs: The input held over the interval.
        duration: Length of the interval, s.
        n_substeps: RK4 steps over the interval.
        unroll: Write the sub-steps out instead of looping over them (static): the same arithmetic, one
            larger fused program per period. It pays on GPUs, hardly on CPU, and compiles longer, so it is
            off by default (docs/performance.md, "Engine").

    Returns:
        The state at the interval's end, angle wrapped to one turn.
    """
    split = machine.split_advance
    if split is not None:  # a multi-phase model whose planes integrate separately (pmsm_multiphase.py)
        return split(state, inputs, duration, n_substeps)
    h = duration / n_substeps
    loop = lambda body, carry: jax.lax.fori_loop(0, n_substeps, body, carry, unroll=bool(unroll))
    if inputs.frame == "stator" and machine.angle_only_in_voltage:
        # a machine that reads the angle's cosine and sine (harmonics) gets them carried with the voltage:
        # one evaluation per interval instead of one per stage (docs/performance.md, "Ripple")
        axis = machine.stator_axis(state.theta_e)
        carry = (state, inputs.dq(state.theta_e)) + (() if axis is None else (axis,))
        step = lambda _, c: rk4_step_rotating_hold(machine, c[0], c[1], inputs.load_torque, h, *c[2:])
        state = step(0, carry)[0] if n_substeps == 1 else loop(step, carry)[0]
        return MachineState(state.currents, state.omega_m, wrap_angle(state.theta_e), state.shaft)
    body = lambda _, x: rk4_step(machine, x, inputs, h)
    if n_substeps == 1:
        state = body(0, state)
    else:
        state = loop(body, state)
    return MachineState(state.currents, state.omega_m, wrap_angle(state.theta_e), state.shaft)


def max_stable_substep(motor_or_machine, max_speed_m) -> float:
    """Longest RK4 sub-step we accept: 0.5 / (fastest electrical rate), from concrete values.

    The electrical rates are ``R/L`` (the current's own pole; L the smallest inductance, the leakage for a
    multi-phase machine) and ``omega_e`` (rotation of the flux), with a compliant shaft also its resonance
    and its damper's rate; RK4 is stable to about 2.8 on both axes and
    accurate to 1e-4 per period at 0.5. Used by the input checks, so it works on NumPy values (it must not
    create JAX tracers inside a jit).

    Args:
        motor_or_machine: Motor parameters, or a machine (its ``motor`` is read).
        max_speed_m: Largest mechanical speed, rad/s.

    Returns:
        The sub-step, s.
    """
    motor = motor_or_machine.motor if isinstance(motor_or_machine, AbstractMachine) else motor_or_machine
    R, L_d, L_q = (np.asarray(jax.device_get(x), dtype=float) for x in (motor.R, motor.L_d, motor.L_q))
    L_min = np.minimum(L_d, L_q)
    for name in motor.leakage_fields:  # multi-phase: the leakage-only planes (z1-z2, x-y) are the fastest
        L_leak = getattr(motor, name)
        if is_concrete(L_leak):
            L_min = np.minimum(L_min, np.asarray(jax.device_get(L_leak), dtype=float))
    rate = np.maximum(R / L_min, motor.pole_pairs * np.abs(max_speed_m))
    shaft = (getattr(motor, "load_inertia", None), getattr(motor, "shaft_stiffness", None))
    if shaft[0] is not None and all(is_concrete(x) for x in shaft):
        # a compliant shaft: its resonance and its damper's rate (pmsmjax/machines/shaft.py)
        J, J_L, K, D = (np.asarray(jax.device_get(x), float) for x in (motor.J, *shaft, motor.shaft_damping))
        inverse_inertia = (J + J_L) / (J * J_L)
        rate = np.maximum(rate, np.maximum(np.sqrt(K * inverse_inertia), D * inverse_inertia))
    return float(np.min(0.5 / rate))
