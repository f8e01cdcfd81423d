"""The dq equations of a PMSM in steady state, and its torque, written once for plain floats, NumPy arrays
and JAX arrays alike: operators only, and the magnitude's ``hypot`` from the caller's namespace (``math``,
``numpy`` or ``jax.numpy``). No JAX import, so the command line's checks before a run read them without
loading JAX; the machines ([`pmsm3`][pmsmjax.machines.pmsm3],
[`pmsm_flux_map`][pmsmjax.machines.pmsm_flux_map], [`saturation`][pmsmjax.machines.saturation],
[`pmsm_multiphase`][pmsmjax.machines.pmsm_multiphase]), the design rules
([`pmsmjax.spec.design_rules`][pmsmjax.spec.design_rules]), the operating-point checks
([`pmsmjax.analysis.operating_point`][pmsmjax.analysis.operating_point]) and the flux map's loci
([`pmsmjax.controllers.flux_map_loci`][pmsmjax.controllers.flux_map_loci]) use them.

Amplitude-invariant dq frame, peak phase values, electrical speed ``w_e = p w`` (the book, ch. 1). With the
flux linkage ``psi(i)`` (a linear machine's ``psi_d = L_d i_d + psi_f``, ``psi_q = L_q i_q``; or a flux
map's interpolant, [`flux_map`][pmsmjax.machines.flux_map])::

    u_d = R i_d - w_e psi_q,   u_q = R i_q + w_e psi_d          (steady state: di/dt = 0)
    T_e = (n/2) p (psi_d i_q - psi_q i_d)                        (n phases: 1.5 p for three)

For the linear machine the torque is ``(n/2) p (psi_f i_q + (L_d - L_q) i_d i_q)``, which the linear plants
integrate ([`linear_torque`][pmsmjax.machines.dq_equations.linear_torque]), or ``(n/2) p i_q psi_a`` with the
active flux ``psi_a = psi_f + (L_d - L_q) i_d``
([`active_flux_torque`][pmsmjax.machines.dq_equations.active_flux_torque]), the arrangement the design rules
evaluate and the steady-state checks solve for ``i_q``
([`q_current`][pmsmjax.machines.dq_equations.q_current]). The two are the same torque but round differently
in the last bit, so each keeps its own order of operations: the plants' compiled programs and the checks'
numbers do not depend on which caller shares the module.
"""

import math

__all__ = [
    "torque_factor",
    "linear_flux",
    "linear_current_derivative",
    "active_flux",
    "torque",
    "linear_torque",
    "active_flux_torque",
    "q_current",
    "voltage",
    "voltage_magnitude",
]


def torque_factor(pole_pairs, n_phases=3):
    """``(n/2) p``: torque per ampere of q current per weber of flux (``1.5 p`` for three phases)."""
    return 0.5 * n_phases * pole_pairs


def linear_flux(psi_f, L_d, L_q, i_d, i_q):
    """``(psi_d, psi_q)`` of the linear machine: ``(L_d i_d + psi_f, L_q i_q)``, Wb."""
    return L_d * i_d + psi_f, L_q * i_q


def linear_current_derivative(R, L_d, L_q, psi_f, omega_e, i_d, i_q, u_d, u_q):
    """``(di_d/dt, di_q/dt)`` of the linear machine, A/s: ``L_d di_d/dt = u_d - R i_d + w_e L_q i_q``,
    ``L_q di_q/dt = u_q - R i_q - w_e (L_d i_d + psi_f)`` (the book, ch. 1; ``omega_e`` electrical rad/s)."""
    did = (u_d - R * i_d + omega_e * L_q * i_q) / L_d
    diq = (u_q - R * i_q - omega_e * (L_d * i_d + psi_f)) / L_q
    return did, diq


def active_flux(psi_f, L_d, L_q, i_d):
    """The active flux ``psi_f + (L_d - L_q) i_d`` (Wb): the linear machine's torque per q ampere over
    ``(n/2) p``."""
    return psi_f + (L_d - L_q) * i_d


def torque(factor, i_d, i_q, psi_d, psi_q):
    """Air-gap torque ``factor (psi_d i_q - psi_q i_d)``, N m, of the flux linkage ``psi_d, psi_q`` (Wb) at
    the currents ``i_d, i_q`` (A); `factor`:
    [`torque_factor`][pmsmjax.machines.dq_equations.torque_factor]."""
    return factor * (psi_d * i_q - psi_q * i_d)


def linear_torque(factor, psi_f, L_d, L_q, i_d, i_q):
    """The linear machine's torque ``factor (psi_f i_q + (L_d - L_q) i_d i_q)``, N m, as its plants
    integrate it."""
    return factor * (psi_f * i_q + (L_d - L_q) * i_d * i_q)


def active_flux_torque(factor, i_q, psi_a):
    """The linear machine's torque ``factor i_q psi_a`` (N m) from its active flux ``psi_a``
    ([`active_flux`][pmsmjax.machines.dq_equations.active_flux]), as the design rules evaluate it."""
    return factor * i_q * psi_a


def q_current(factor, torque_nm, psi_a):
    """The q current (A) at which the active flux ``psi_a`` (Wb) gives ``torque_nm`` (N m): the inverse of
    [`active_flux_torque`][pmsmjax.machines.dq_equations.active_flux_torque]."""
    return torque_nm / (factor * psi_a)


def voltage(R, omega_e, i_d, i_q, psi_d, psi_q):
    """``(u_d, u_q)`` (V) in steady state at the electrical speed ``omega_e`` (rad/s), the currents
    ``i_d, i_q`` (A) and their flux linkage ``psi_d, psi_q`` (Wb): ``(R i_d - w_e psi_q, R i_q + w_e
    psi_d)``."""
    return R * i_d - omega_e * psi_q, R * i_q + omega_e * psi_d


def voltage_magnitude(R, omega_e, i_d, i_q, psi_d, psi_q, xp=math):
    """``|u_dq|`` (V) of [`voltage`][pmsmjax.machines.dq_equations.voltage], by ``xp.hypot`` (`xp`: ``math``,
    ``numpy`` or ``jax.numpy``)."""
    u_d, u_q = voltage(R, omega_e, i_d, i_q, psi_d, psi_q)
    return xp.hypot(u_d, u_q)
