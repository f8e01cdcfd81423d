"""The six-phase (dual three-phase) PMSM in double-dq coordinates (the book, ch. 7 and 9).

Each three-phase set has its own Park transform, ABC at ``th`` and UVW at ``th - pi/6``
([`pmsmjax.frames.multiphase.double_dq`][pmsmjax.frames.multiphase.double_dq]); both dq frames lie on the
rotor. State ``[i_d1, i_q1, i_d2, i_q2]``, A. From the natural-frame inductances (``L_ls`` leakage, ``L_0m``,
``L_2m`` magnetising, [`pmsm_multiphase`][pmsmjax.machines.pmsm_multiphase]), a set's own dq inductance is
``L_ls + L_m{d,q}`` and the mutual inductance between the sets ``L_m{d,q}``, with ``L_md = 1.5 (L_0m + L_2m)``
and ``L_mq = 1.5 (L_0m - L_2m)``; each set links the magnet flux ``psi_f`` on its d axis::

    psi_d1 = (L_ls + L_md) i_d1 + L_md i_d2 + psi_f,   psi_q1 = (L_ls + L_mq) i_q1 + L_mq i_q2
    psi_d2 = (L_ls + L_md) i_d2 + L_md i_d1 + psi_f,   psi_q2 = (L_ls + L_mq) i_q2 + L_mq i_q1
    u_dk = R i_dk + dpsi_dk/dt - w_e psi_qk,            u_qk = R i_qk + dpsi_qk/dt + w_e psi_dk
    T_e = 1.5 p_n sum_k (psi_dk i_qk - psi_qk i_dk)

(``L_md = (L_d - L_ls)/2``, ``L_mq = (L_q - L_ls)/2`` in terms of the VSD inductances.) The mutual terms
couple the two sets' current loops: the cross-coupling that the double-dq controller of chapter 9
compensates ([`pmsmjax.controllers.multiphase`][pmsmjax.controllers.multiphase]).
"""

import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import SIX_PHASE, double_dq_to_vsd, vsd_to_double_dq
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm_multiphase import AbstractMultiPhaseMachine
from pmsmjax.spec.validation import ParameterError

__all__ = ["PMSM6DoubleDQ", "double_dq_flux", "double_dq_current_rate", "magnetising_inductances"]


def magnetising_inductances(m: MultiPhaseParameters):
    """``(L_md, L_mq)``, H: the mutual dq inductances between the two sets of ``m`` (module docstring)."""
    return 0.5 * (m.L_d - m.L_ls), 0.5 * (m.L_q - m.L_ls)


def double_dq_flux(m: MultiPhaseParameters, currents: Array) -> Array:
    """``(4,)`` [psi_d1, psi_q1, psi_d2, psi_q2], Wb, of the ``(4,)`` currents [i_d1, i_q1, i_d2, i_q2], A
    (module docstring)."""
    L_md, L_mq = magnetising_inductances(m)
    i_d1, i_q1, i_d2, i_q2 = currents[0], currents[1], currents[2], currents[3]
    return jnp.stack(
        [
            (m.L_ls + L_md) * i_d1 + L_md * i_d2 + m.psi_f,
            (m.L_ls + L_mq) * i_q1 + L_mq * i_q2,
            (m.L_ls + L_md) * i_d2 + L_md * i_d1 + m.psi_f,
            (m.L_ls + L_mq) * i_q2 + L_mq * i_q1,
        ]
    )


def double_dq_current_rate(m: MultiPhaseParameters, dpsi: Array) -> Array:
    """``(4,)`` current derivatives, A/s, giving the ``(4,)`` flux derivatives ``dpsi`` (Wb/s): per axis
    ``[[Ls, M], [M, Ls]] [di_1, di_2] = [dpsi_1, dpsi_2]`` with ``det = (Ls - M)(Ls + M) = L_ls L_{d,q}``."""
    L_md, L_mq = magnetising_inductances(m)
    Ls_d, Ls_q = m.L_ls + L_md, m.L_ls + L_mq
    det_d, det_q = m.L_ls * m.L_d, m.L_ls * m.L_q
    return jnp.stack(
        [
            (Ls_d * dpsi[0] - L_md * dpsi[2]) / det_d,
            (Ls_q * dpsi[1] - L_mq * dpsi[3]) / det_q,
            (Ls_d * dpsi[2] - L_md * dpsi[0]) / det_d,
            (Ls_q * dpsi[3] - L_mq * dpsi[1]) / det_q,
        ]
    )


class PMSM6DoubleDQ(AbstractMultiPhaseMachine):
    """Six-phase PMSM in double-dq coordinates; state ``(4,)`` [i_d1, i_q1, i_d2, i_q2], A.

    Its fields are those of
    [`AbstractMultiPhaseMachine`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine]; the layout
    can only be the dual three-phase ``SIX_PHASE``.
    """

    def __check_init__(self):
        if self.layout != SIX_PHASE:
            raise ParameterError("PMSM6DoubleDQ models the dual three-phase winding only (layout SIX_PHASE).")

    def magnetising(self):
        """The mutual dq inductances between the sets.

        Returns:
            ``(L_md, L_mq)``, H.
        """
        return magnetising_inductances(self.motor)

    def flux(self, currents: Array) -> Array:
        """Flux linkages of both sets.

        Args:
            currents: ``(4,)`` [i_d1, i_q1, i_d2, i_q2], A.

        Returns:
            ``(4,)`` [psi_d1, psi_q1, psi_d2, psi_q2], Wb.
        """
        return double_dq_flux(self.motor, currents)

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        m = self.motor
        u_vsd = u.alpha_beta(theta_e)
        u_dd = vsd_to_double_dq(jnp.concatenate([park(u_vsd[:2], theta_e), u_vsd[2:]]), theta_e)
        if self.resistance_scale is None:
            r = m.R * currents
        else:
            r_vsd = self.resistive_voltage_vsd(self.currents_to_vsd(currents, theta_e))
            r = vsd_to_double_dq(jnp.concatenate([park(r_vsd[:2], theta_e), r_vsd[2:]]), theta_e)
        psi = self.flux(currents)
        # dpsi/dt = u - R i - w_e J psi, per set; J psi = [-psi_q, psi_d].
        rotational = jnp.stack([-psi[1], psi[0], -psi[3], psi[2]])
        dpsi = u_dd - r - omega_e * rotational
        return double_dq_current_rate(self.motor, dpsi)

    def torque(self, currents, theta_e):
        psi = self.flux(currents)
        return (
            1.5
            * self.motor.pole_pairs
            * (psi[0] * currents[1] - psi[1] * currents[0] + psi[2] * currents[3] - psi[3] * currents[2])
        )

    def currents_to_vsd(self, currents, theta_e):
        x = double_dq_to_vsd(currents, theta_e)
        return jnp.concatenate([inverse_park(x[:2], theta_e), x[2:]])

    def currents_from_vsd(self, i_vsd, theta_e):
        return vsd_to_double_dq(jnp.concatenate([park(i_vsd[:2], theta_e), i_vsd[2:]]), theta_e)
