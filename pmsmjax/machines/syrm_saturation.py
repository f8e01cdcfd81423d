"""The power-law saturation model of a synchronous reluctance machine, with a permanent-magnet MMF, sampled
into a flux map (NumPy, for drive files and as an independent reference in tests).

**Model** (M. Hinkkanen, P. Pescetto, E. Molsa, S. E. Saarakkala, G. Pellegrino, R. Bojoi, "Sensorless
self-commissioning of synchronous reluctance motors at standstill without rotor locking", IEEE Trans. Ind.
Appl. 53(3), 2017, doi:10.1109/TIA.2016.2644624): the current as a function of the flux,

    i_x = (a_x0 + a_xx |psi_x|^S + a_xy/(V+2) |psi_x|^U |psi_y|^(V+2)) psi_x       (high-permeance axis x)
    i_y = (a_y0 + a_yy |psi_y|^T + a_xy/(U+2) |psi_x|^(U+2) |psi_y|^V) psi_y       (flux-barrier axis y)

(self-saturation of each axis, and cross-saturation through ``a_xy``, which comes from one co-energy so the
model is reciprocal). The paper writes it in the reluctance machine's convention (``x`` = its d axis). This
project's convention puts the magnet on the d axis and the high-permeance path on q, so here ``x = q`` and
``y = d``; the magnets sit in the flux barriers, an MMF in series with the d-axis current (a constant
current source ``i_f`` on d: ``i_d = i_y(psi) - i_f``, the PM-assisted machine: ``psi_d(0, 0) > 0``, a
small magnet flux against the large q inductance). A magnet modelled instead as a flux ``psi_f`` in
series with the iron (``y = psi_d - psi_f``, the flux at zero current exactly ``psi_f``) is the other
common PM-assisted form (``tuning/identify/reluctance_reference_log.py`` makes its logs with it); both
default to zero, the pure reluctance machine. The flux map is the inverse, ``psi(i)``, found by Newton's
method at every grid point (the current map is the gradient of a strictly convex co-energy, so the
inverse is unique).
"""

import dataclasses

import numpy as np

from pmsmjax.machines.flux_map import FluxMapGrid

__all__ = ["PowerLawSaturation", "sample_flux_map"]


@dataclasses.dataclass(frozen=True)
class PowerLawSaturation:
    """Coefficients of the power-law model (module docstring); ``x``: high-permeance axis (this project's
    q), ``y``: flux-barrier axis (d). Inverse inductances in 1/H, exponents dimensionless, ``i_f`` in A (the
    magnets' MMF), ``psi_f`` in Wb (the magnets as a flux in series; module docstring).

    Defaults: the 6.7 kW reluctance machine's fit published with the model (Hinkkanen et al. 2017:
    ``a_d0 = 17.4``, ``a_dd = 373``, ``S = 5``, ``a_q0 = 52.1``, ``a_qq = 658``, ``T = 1``, ``a_dq = 1120``,
    ``U = 1``, ``V = 0`` in its axes; the same values motulator's examples use), with ``i_f`` the magnets.
    """

    a_x0: float = 17.4
    a_xx: float = 373.0
    S: float = 5.0
    a_y0: float = 52.1
    a_yy: float = 658.0
    T: float = 1.0
    a_xy: float = 1120.0
    U: float = 1.0
    V: float = 0.0
    i_f: float = 0.0
    psi_f: float = 0.0

    def current(self, psi_d, psi_q) -> tuple[np.ndarray, np.ndarray]:
        """``(i_d, i_q)`` A at the flux ``(psi_d, psi_q)`` Wb (arrays broadcast)."""
        y_signed = np.asarray(psi_d) - self.psi_f
        x, y = np.abs(psi_q), np.abs(y_signed)
        g_x = self.a_x0 + self.a_xx * x**self.S + self.a_xy / (self.V + 2) * x**self.U * y ** (self.V + 2)
        g_y = self.a_y0 + self.a_yy * y**self.T + self.a_xy / (self.U + 2) * x ** (self.U + 2) * y**self.V
        return g_y * y_signed - self.i_f, g_x * psi_q

    def flux(self, i_d: float, i_q: float, iterations: int = 60) -> np.ndarray:
        """``(2,)`` Wb: the flux whose current is ``(i_d, i_q)`` A (Newton, central-difference Jacobian)."""
        target = np.array([i_d, i_q], dtype=float)
        psi = target / np.array([self.a_y0, self.a_x0]) + np.array([self.i_f / self.a_y0 + self.psi_f, 0.0])
        h = 1e-7
        for _ in range(iterations):
            r = np.array(self.current(*psi)) - target
            if np.max(np.abs(r)) < 1e-11:
                break
            jac = np.empty((2, 2))
            for k in range(2):
                dp = np.zeros(2)
                dp[k] = h
                jac[:, k] = np.array(self.current(*(psi + dp))) - np.array(self.current(*(psi - dp)))
                jac[:, k] /= 2 * h
            step = np.linalg.solve(jac, r)
            psi = psi - step / max(1.0, float(np.max(np.abs(step))) / 0.05)  # damped far from the root
        return psi


def sample_flux_map(
    model: PowerLawSaturation, i_max: float, step: float, source: str = "power-law"
) -> FluxMapGrid:
    """``model``'s flux map on the square grid ``[-i_max, i_max]^2`` A with spacing ``step`` A."""
    axis = np.arange(-i_max, i_max + 0.5 * step, step)
    psi = np.array([[model.flux(i_d, i_q) for i_q in axis] for i_d in axis])
    return FluxMapGrid(axis, axis, psi[..., 0], psi[..., 1], source=source)
