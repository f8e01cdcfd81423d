"""Brute-force carrier-comparison inverter: the reference the switching-segment bridge is validated against.

It exists only for tests and benchmarks (never in the library's hot path) and shares none of the segment
model's switching logic: every period is cut into ``n_fine`` equal RK4 steps, and in each step the gate of
leg x is the comparison of a centre-aligned triangular carrier ``c(t) = |2 (t mod Ts)/Ts - 1|`` with the
duty (``g_x = c < d_x`` at the step's midpoint). Dead time is modelled as a real gate driver does it: a
switch turns on only when its gate has been on for ``t_d`` (``g(t)`` and ``g(t - t_d)``); while both
switches are off the diode picked by the *instantaneous* phase-current sign sets the pole voltage; a
conducting device drops ``sign(i) U_f``. The machine model is the library's (validated against scipy in
tests/machines/test_machines.py); what is under test is the switching.

Accuracy: an edge falls inside a step, so up to half a step of the wrong voltage is applied per edge: a
current error of at most ``U_dc h / (2 L)`` per edge (1.5 mA at h = 50 ns for the book drive), halving
with each doubling of ``n_fine``.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta, dq_to_abc, wrap_angle
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.machines.base import MachineInput, MachineState
from pmsmjax.machines.integrate import rk4_step
from pmsmjax.machines.motor import as_float
from pmsmjax.presets.book_constants import BOOK_DC_LINK

__all__ = ["CarrierReferenceBridge", "dense_phase_currents"]


class CarrierReferenceBridge(AbstractBridge):
    """Fine-step carrier comparison. `u_dc` V, `dead_time` s, `device_drop` V; `n_fine`: steps per period."""

    u_dc: Array
    dead_time: Array
    device_drop: Array
    n_fine: int = eqx.field(static=True)

    def __init__(self, u_dc=BOOK_DC_LINK, dead_time=0.0, device_drop=0.0, n_fine: int = 2000):
        self.u_dc = as_float(u_dc)
        self.dead_time = as_float(dead_time)
        self.device_drop = as_float(device_drop)
        self.n_fine = n_fine

    def _step(self, machine, duties, load_torque, Ts, j, state):
        h = Ts / self.n_fine
        t = (j + 0.5) * h
        carrier = lambda tt: jnp.abs(2.0 * jnp.mod(tt, Ts) / Ts - 1.0)
        gate_now = carrier(t) < duties
        gate_before = carrier(t - self.dead_time) < duties
        upper = gate_now & gate_before
        lower = ~gate_now & ~gate_before
        i_abc = dq_to_abc(machine.currents_dq(state), state.theta_e)
        freewheel = i_abc < 0.0  # both off: the upper diode conducts a current flowing into the leg
        high = jnp.where(upper, True, jnp.where(lower, False, freewheel))
        pole = self.u_dc * high.astype(i_abc.dtype) - self.device_drop * jnp.sign(i_abc)
        u_ab = abc_to_alpha_beta(pole - jnp.mean(pole))
        return rk4_step(machine, state, MachineInput(u_ab, load_torque, "stator"), h), u_ab

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        def body(j, carry):
            s, u_sum = carry
            s, u = self._step(machine, duties, load_torque, Ts, j, s)
            return s, u_sum + u

        zero = jnp.zeros(2, state.omega_m.dtype)
        state, u_sum = jax.lax.fori_loop(0, self.n_fine, body, (state, zero))
        wrapped = MachineState(state.currents, state.omega_m, wrap_angle(state.theta_e))
        return wrapped, u_sum / self.n_fine

    def sample_period(self, machine, state, duties, load_torque, Ts, n_samples: int):
        """States at ``t_j = j Ts/n_samples``, j = 1..n_samples (``n_fine`` must be a multiple)."""
        per = self.n_fine // n_samples
        if per * n_samples != self.n_fine:
            raise ValueError(f"n_fine = {self.n_fine} is not a multiple of n_samples = {n_samples}.")

        def outer(s, k):
            s = jax.lax.fori_loop(
                k * per, (k + 1) * per, lambda j, x: self._step(machine, duties, load_torque, Ts, j, x)[0], s
            )
            return s, s

        _, states = jax.lax.scan(outer, state, jnp.arange(n_samples))
        return states


def dense_phase_currents(drive, trace, n_samples: int):
    """``(N * n_samples, 3)`` phase currents (A) at ``t = k Ts + j Ts/n_samples`` (j = 1..n_samples) of a
    run of ``drive``: each period re-integrated from its recorded start state and duties with the bridge's
    own ``sample_period`` (the trajectory the run followed)."""
    m = drive.machine
    states = MachineState(
        jax.vmap(m.currents_from_dq)(trace.i_dq, trace.theta_e), trace.omega_m, trace.theta_e
    )

    @jax.jit
    def run(states, duties, load):
        def one(s, d, L):
            out = drive.bridge.sample_period(m, s, d, L, drive.Ts, n_samples)
            return out[0] if isinstance(out, tuple) else out

        dense = jax.vmap(one)(states, duties, load)
        return dq_to_abc(jax.vmap(jax.vmap(m.currents_dq))(dense), dense.theta_e)

    return np.asarray(run(states, trace.duties, trace.load_torque)).reshape(-1, 3)
