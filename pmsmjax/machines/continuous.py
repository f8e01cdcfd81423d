"""The machine's continuous-time vector field used outside the fixed-step scan.

- [`solve_adaptive`][pmsmjax.machines.continuous.solve_adaptive]: a diffrax adaptive solve over an interval
  with a held input (reference accuracy, identification), using the same ``vector_field`` the scan integrates
  with RK4.
- [`linearise`][pmsmjax.machines.continuous.linearise]: the Jacobians ``A = df/dx``, ``B = df/du`` at an
  operating point, for small-signal analysis and controller design. State order
  ``[currents..., omega_m, theta_e]``, input order ``[u_1, u_2, load_torque]`` (the held voltage in its hold
  frame, then the load; a multi-phase machine's ``[u_1, ..., u_m, load_torque]`` with its ``m`` VSD voltage
  components).
"""

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from pmsmjax._types import Array
from pmsmjax.machines.base import AbstractMachine, MachineInput, MachineState


def solve_adaptive(
    machine: AbstractMachine,
    state: MachineState,
    inputs: MachineInput,
    duration,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_steps: int = 100_000,
) -> MachineState:
    """Integrate ``machine`` over ``duration`` with diffrax's Dopri8 and a PID step controller.

    Args:
        machine: The machine model.
        state: The state at the interval's start.
        inputs: The input held over the interval.
        duration: Length of the interval, s.
        rtol: Relative tolerance of the step controller.
        atol: Absolute tolerance of the step controller.
        max_steps: Most steps diffrax may take.

    Returns:
        The state at the interval's end.
    """
    # Imported here: diffrax takes a quarter of a second to import, and only reference solves need it,
    # not the commands that import the machines package.
    import diffrax

    term = diffrax.ODETerm(machine.vector_field)
    sol = diffrax.diffeqsolve(
        term,
        diffrax.Dopri8(),
        t0=0.0,
        t1=duration,
        dt0=None,
        y0=state,
        args=inputs,
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps,
    )
    return jax.tree.map(lambda x: x[-1], sol.ys)


def linearise(machine: AbstractMachine, state: MachineState, inputs: MachineInput) -> tuple[Array, Array]:
    """Jacobians of the vector field at an operating point.

    Args:
        machine: The machine model.
        state: The operating point's state.
        inputs: The operating point's input.

    Returns:
        ``(A, B)``: ``A (n, n)`` with ``n = len(currents) + 2`` (state order ``[currents..., omega_m,
        theta_e]``) and ``B (n, m + 1)`` for ``[u_1, ..., u_m, load_torque]`` (``m = 2`` for three phases).
    """
    x0, unravel_x = ravel_pytree(state)
    u0 = jnp.concatenate([inputs.u, jnp.atleast_1d(inputs.load_torque)])
    m = inputs.u.shape[0]

    def f(x, u):
        dx = machine.vector_field(None, unravel_x(x), MachineInput(u[:m], u[m], inputs.frame))
        return ravel_pytree(dx)[0]

    return jax.jacfwd(f, 0)(x0, u0), jax.jacfwd(f, 1)(x0, u0)
