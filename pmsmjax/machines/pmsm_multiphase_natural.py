"""The n-phase PMSM in phase quantities: ``n`` phase currents, the full ``n x n`` inductance matrix."""

import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import inverse_vsd_matrix, vsd_matrix
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.pmsm_multiphase import AbstractMultiPhaseMachine


class MultiPhasePMSMNatural(AbstractMultiPhaseMachine):
    """n-phase PMSM in the natural frame; state currents ``(n,)`` phase currents, A (module docstring).

    Its fields are those of
    [`AbstractMultiPhaseMachine`][pmsmjax.machines.pmsm_multiphase.AbstractMultiPhaseMachine].
    """

    def _axes(self, dtype):
        return jnp.asarray(np.asarray(self.layout.angles), dtype)

    def inductance(self, theta_e) -> Array:
        """Phase inductance matrix at an electrical angle.

        Args:
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(n, n)`` inductances, H.
        """
        m = self.motor
        n = self.layout.n
        L_0m = (m.L_d + m.L_q - 2.0 * m.L_ls) / n
        L_2m = (m.L_d - m.L_q) / n
        g = self._axes(jnp.result_type(theta_e, m.R))
        gx, gy = g[:, None], g[None, :]
        return m.L_ls * jnp.eye(n) + L_0m * jnp.cos(gx - gy) + L_2m * jnp.cos(2.0 * theta_e - gx - gy)

    def magnet_flux(self, theta_e) -> Array:
        """PM flux linked by each phase (with the third harmonic if ``psi_f3`` is given).

        Args:
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(n,)`` flux linkages, Wb.
        """
        angle = theta_e - self._axes(jnp.result_type(theta_e, self.motor.R))
        flux = self.motor.psi_f * jnp.cos(angle)
        if self.motor.psi_f3 is not None:
            flux = flux + self.motor.psi_f3 * jnp.cos(3.0 * angle)
        return flux

    def flux(self, currents, theta_e) -> Array:
        """Phase flux linkages.

        Args:
            currents: ``(n,)`` phase currents, A.
            theta_e: Electrical rotor angle, rad.

        Returns:
            ``(n,)`` flux linkages, Wb.
        """
        return self.inductance(theta_e) @ currents + self.magnet_flux(theta_e)

    def current_derivative(self, currents, theta_e, omega_e, u: MachineInput):
        n = self.layout.n
        m = self.layout.n_active
        _, dflux_dtheta = jax.jvp(lambda th: self.flux(currents, th), (theta_e,), (jnp.ones_like(theta_e),))
        T_inv = jnp.asarray(inverse_vsd_matrix(self.layout)[:, :m], currents.dtype)
        u_phase = T_inv @ u.alpha_beta(theta_e)
        R = self.motor.R if self.resistance_scale is None else self.motor.R * self.resistance_scale
        rhs = u_phase - R * currents - omega_e * dflux_dtheta
        L = self.inductance(theta_e)
        # Isolated stars: add the star-point voltages v (one per star, on its phases: G v) for which every
        # star's current sum stays constant, G^T L^-1 (rhs - G v) = 0.
        G = np.zeros((n, len(self.layout.neutrals)))
        for k, group in enumerate(self.layout.neutrals):
            G[list(group), k] = 1.0
        G = jnp.asarray(G, currents.dtype)
        sol = jnp.linalg.solve(L, jnp.concatenate([rhs[:, None], G], axis=1))
        a, B = sol[:, 0], sol[:, 1:]
        v = jnp.linalg.solve(G.T @ B, G.T @ a)
        return a - B @ v

    def torque(self, currents, theta_e):
        def coenergy(th):
            return 0.5 * currents @ self.inductance(th) @ currents + currents @ self.magnet_flux(th)

        return self.motor.pole_pairs * jax.grad(coenergy)(theta_e)

    def currents_to_vsd(self, currents, theta_e):
        m = self.layout.n_active
        return jnp.asarray(vsd_matrix(self.layout)[:m], currents.dtype) @ currents

    def currents_from_vsd(self, i_vsd, theta_e):
        m = self.layout.n_active
        return jnp.asarray(inverse_vsd_matrix(self.layout)[:, :m], i_vsd.dtype) @ i_vsd

    def phase_currents(self, state):
        return state.currents
