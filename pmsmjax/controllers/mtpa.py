"""Maximum torque per ampere (MTPA) d-axis reference (the book, ch. 3, "MTPA for salient machines").

Torque (magnet flux on d, amplitude-invariant dq): ``T_e = 1.5 p_n [psi_f i_q + (L_d - L_q) i_d i_q]``.
With ``dL = L_q - L_d`` the torque at a fixed current magnitude ``I`` is largest where the gradient of
``T_e`` is parallel to ``i_dq`` (Lagrange): ``dL i_d^2 - psi_f i_d - dL i_q^2 = 0``, i.e.

    i_d = (psi_f - sqrt(psi_f^2 + 4 dL^2 i_q^2)) / (2 dL)            (in terms of i_q)
    i_d = (psi_f - sqrt(psi_f^2 + 8 dL^2 I^2)) / (4 dL)               (in terms of I = |i_dq|)

(Morimoto, Takeda, Hirasa, Taniguchi, "Expansion of operating limits for permanent magnet motor by
current vector control considering inverter capacity", IEEE Trans. Ind. Appl. 26(5), 1990,
doi:10.1109/28.60058). The second, ``I`` form is the one usually printed; the cascade knows ``i_q*``, so
the block uses the first. Both are evaluated in the rationalised form

    i_d = -2 dL i_q^2 / (psi_f + sqrt(psi_f^2 + 4 dL^2 i_q^2))

which has no division by ``dL``: it is exactly 0 for a surface machine (``L_d = L_q``), has no
cancellation for a slightly salient one, and gives the positive ``i_d`` of a reverse-salient machine
(``L_d > L_q``). The only remaining 0/0 is a magnet-free machine (``psi_f = 0``) at zero current; it is
guarded with the double-where pattern so the gradient stays finite there.
"""

import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractDAxisReference, CurrentLoopContext
from pmsmjax.machines.motor import PMSMParameters


def _rationalised(psi_f, dL, c, current):
    """``-2 dL x^2 / (psi_f + sqrt(psi_f^2 + c dL^2 x^2))`` with ``x`` = `current`, 0/0-guarded."""
    arg = psi_f**2 + c * dL**2 * current**2
    positive = arg > 0
    root = jnp.sqrt(jnp.where(positive, arg, 1.0))
    den = psi_f + jnp.where(positive, root, 0.0)
    safe = den > 0
    return jnp.where(safe, -2.0 * dL * current**2 / jnp.where(safe, den, 1.0), 0.0)


def mtpa_id_from_iq(model: PMSMParameters, iq) -> Array:
    """MTPA d-axis current (A) for the q-axis current ``iq`` (A, any sign, any shape)."""
    return _rationalised(model.psi_f, model.L_q - model.L_d, 4.0, iq)


def mtpa_id_from_magnitude(model: PMSMParameters, i_s) -> Array:
    """MTPA d-axis current (A) for the current magnitude ``i_s = |i_dq|`` (A, >= 0, any shape)."""
    return _rationalised(model.psi_f, model.L_q - model.L_d, 8.0, i_s)


class MTPA(AbstractDAxisReference):
    """d-axis reference on the MTPA locus of the controller's motor model, from last period's ``i_q*``.

    Replaces the scenario's ``i_d*``. Stateless. For a surface machine it is i_d = 0 control.
    """

    def init(self, dtype):
        return None

    def step(self, state, id_ref, iq_ref_prev, omega_e, ctx: CurrentLoopContext, current_limit):
        return state, mtpa_id_from_iq(ctx.model, iq_ref_prev)


__all__ = ["MTPA", "mtpa_id_from_iq", "mtpa_id_from_magnitude"]
