"""The trajectory inside control periods: uniform samples between the period starts a Trace records.

A Trace holds the state at each period start only. With centre-aligned PWM those instants sit at the
middle of the current ripple, so ripple, spectra and torque ripple need the trajectory in between. It is
recomputed here from each period's recorded start state and applied duties (the same model, so the same
trajectory the simulation followed): segment by segment for the switching-resolved bridges (their
``sample_period``, [`switching_resolved`][pmsmjax.inverters.base.AbstractBridge.switching_resolved]), in equal
held-voltage steps for the averaged ones.
"""

import equinox as eqx
import jax
import numpy as np

from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.machines.base import MachineInput, MachineState
from pmsmjax.machines.integrate import advance
from pmsmjax.trace import Trace


@eqx.filter_jit
def _dense_switching(drive: Drive, states: MachineState, duties, load, n_samples: int):
    sample = lambda s, d, L: drive.bridge.sample_period(drive.machine, s, d, L, drive.Ts, n_samples)
    return jax.vmap(sample)(states, duties, load)


@eqx.filter_jit
def _dense_averaged(drive: Drive, states: MachineState, duties, load, n_samples: int):
    def one(s, d, L):
        if drive.machine.n_phases == 3:
            u_ab = abc_to_alpha_beta(phase_voltages(d, drive.bridge.u_dc))
        else:  # a multi-phase bridge: the stationary VSD voltage [alpha, beta, z1, z2, ...]
            u_ab = drive.bridge.vsd_voltage(d)
        step = lambda x, _: (advance(drive.machine, x, MachineInput(u_ab, L), drive.Ts / n_samples, 1),) * 2
        return jax.lax.scan(step, s, None, length=n_samples)[1], u_ab

    return jax.vmap(one)(states, duties, load)


def dense_window(drive: Drive, window: Trace, n_samples: int):
    """Sample each recorded period of a window at ``t_k + j Ts / n_samples``, j = 1..n_samples.

    Args:
        drive: The drive the trace was simulated with.
        window: An undecimated slice of a trace of ``drive``.
        n_samples: Samples per period.

    Returns:
        ``(states, t_u, u_ab)``: a [`MachineState`][pmsmjax.machines.base.MachineState] of ``(N, n_samples)``
        leaves; the bounds ``(K+1,)`` s (from the window start) and ``(K, 2)`` stator voltages V of the
        piecewise-constant applied voltage (one interval per period for the averaged bridge, the switching
        segments otherwise; ``(K, 2 n_planes)`` stationary VSD voltages for a multi-phase machine, whose
        period-start states are rebuilt from the recorded phase currents).
    """
    machine, Ts = drive.machine, drive.Ts
    n = window.t.shape[0]
    if machine.n_phases == 3:
        currents = jax.vmap(machine.currents_from_dq)(window.i_dq, window.theta_e)
    else:
        from pmsmjax.frames.multiphase import vsd

        i_vsd = vsd(window.i_abc, machine.layout)[:, : machine.layout.n_active]
        currents = jax.vmap(machine.currents_from_vsd)(i_vsd, window.theta_e)
    states = MachineState(currents, window.omega_m, window.theta_e)
    if drive.bridge.switching_resolved:
        dense, times, u_ab = _dense_switching(drive, states, window.duties, window.load_torque, n_samples)
        t_u = (np.arange(n)[:, None] * Ts + np.asarray(times)[:, :-1]).ravel()
        u_ab = np.asarray(u_ab).reshape(-1, np.shape(u_ab)[-1])
    else:
        dense, u_ab = _dense_averaged(drive, states, window.duties, window.load_torque, n_samples)
        t_u, u_ab = np.arange(n) * Ts, np.asarray(u_ab)
    return dense, np.append(t_u, n * Ts), u_ab
