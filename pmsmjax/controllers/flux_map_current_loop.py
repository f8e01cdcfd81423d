"""dq current PI on a flux map: internal-model gains scheduled on the incremental inductance and the
decoupling feed-forward from the map's flux (Harnefors and Nee, "Model-based current control of AC
machines using the internal model control method", IEEE Trans. Ind. Appl. 34(1), 1998,
doi:10.1109/28.658735, with the model's inductance made current-dependent).

The machine ([`pmsmjax.machines.pmsm_flux_map`][pmsmjax.machines.pmsm_flux_map]) is
``dpsi/dt = u - R i - w_e J psi(i)``, ``psi(i)`` the map. With the feed-forward ``w_e J psi(i)`` and the
voltage

    ``u = w_e J psi(i) + a_c (psi(i*) - psi(i)) + a_c R int e``,   ``e = i* - i``

the proportional action is on the flux error (flux-linkage-based current control: Awan, Saarakkala,
Hinkkanen, "Flux-linkage-based current control of saturated synchronous motors", IEEE Trans. Ind. Appl.
55(5), 2019), and the integral integrates that flux error seen as a current error through the local
incremental inductance, ``e_psi = L_inc(i)^-1 (psi(i*) - psi(i))``:

    ``u = w_e J psi(i) + a_c (psi(i*) - psi(i)) + a_c R int e_psi``.

For a small error ``psi(i*) - psi(i) = L_inc(i) e`` and ``e_psi = e``: the internal-model PI with
``k_p = a_c L_inc(i)`` scheduled on the incremental inductance (the full 2x2, cross terms included) and
``k_i = a_c R``; around an operating point (``L_inc`` frozen there) ``(s L_inc + R) i = (a_c / s)(s L_inc
+ R) e``, i.e. ``i = (a_c / s) e`` on both axes: the designed ``a_c / (s + a_c)`` whatever the saturation.
For a large step the two choices keep that exact in the flux: with ``z = a_c R int e_psi - R i``,
``dpsi/dt = a_c (psi* - psi) + z`` and ``dz/dt = -R L_inc^-1 z``, so ``z`` stays at its steady-state 0
and the flux answers a step first order with ``a_c``. Scheduling ``a_c L_inc(i) e`` on the current error
instead asks, from zero current where ``L_inc`` is largest, several times the voltage limit, and the
anti-windup parks the integral so far below that the current creeps up for tens of periods (measured on
the preset saturated-ipm map: 10 A after 20 ms of a 25 A step); a current-error integral with the flux
proportional leaves ``z`` excited and a tail with the slow pole ``R / L_inc``.

The constant-inductance design of
[`pmsmjax.controllers.design.current_loop_imc`][pmsmjax.controllers.design.current_loop_imc] built from the
zero-current inductance has ``L_0 / L_inc(i)`` times the gain where the machine saturates: faster than
designed by at least that ratio, with a slow tail where its PI zero misses the plant pole
(tests/controllers/test_flux_map_current_loop.py).

The proportional part goes through [`pi_update`][pmsmjax.controllers.pi.pi_update]'s feed-forward (it is a
flux difference, not a gain times the error), so the anti-windup is the dq PI's: the integral is reset to
the voltage limit when the command is limited. The proportional action itself is held to the voltage limit
(its direction kept): a flux step larger than ``u_max / a_c`` (a reluctance machine's q axis, 0.6 Wb on the
pm-syrm drive against 0.1 Wb at the rule's bandwidth) would otherwise have the anti-windup park the integral
at the limit less the whole proportional action, and the loop lost the current (the saturated-ipm drive's
MRAS start-up: 54.7 A against the 25 A limit, 25.4 A with the hold). Delay compensation predicts the
current one period ahead with the map's own model
([`pmsmjax.controllers.current_pi`][pmsmjax.controllers.current_pi]).
"""

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractCurrentController, CurrentLoopContext
from pmsmjax.controllers.current_pi import angle_lead
from pmsmjax.controllers.pi import clip_magnitude, pi_update
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.machines.pmsm3 import _solve2
from pmsmjax.machines.pmsm_flux_map import FluxMap
from pmsmjax.spec.validation import check_positive

__all__ = ["FluxMapCurrentLoop"]


class FluxMapCurrentLoop(AbstractCurrentController):
    """dq current PI scheduled on the flux map (module docstring); state ``(2,)`` integral, V.

    The gains are those of [`CurrentLoopGains`][pmsmjax.controllers.current_pi.CurrentLoopGains] (same names,
    so tuning and gains files treat both alike), stated at the design inductances `L_design`: the
    proportional action is ``diag(kp / L_design) (psi(i*) - psi(i))``, which is ``a_c (psi(i*) - psi(i))``
    for the internal-model gains ``kp = a_c L_design``
    ([`imc`][pmsmjax.controllers.flux_map_current_loop.FluxMapCurrentLoop.imc]).

    - `flux_map`: the controller's [`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap] (may differ from the
      plant's);
    - `kp_d`, `kp_q`: proportional gains at `L_design`, V/A; `ki_d`, `ki_q`: integral gains, V/(A s);
    - `L_design`: ``(2,)`` the inductances ``[L_d, L_q]`` the proportional gains refer to, H.
    """

    flux_map: FluxMap
    kp_d: Array = eqx.field(converter=as_float)
    kp_q: Array = eqx.field(converter=as_float)
    ki_d: Array = eqx.field(converter=as_float)
    ki_q: Array = eqx.field(converter=as_float)
    L_design: Array = eqx.field(converter=as_float)

    @classmethod
    def imc(cls, flux_map: FluxMap, model: PMSMParameters, bandwidth_rad_s) -> "FluxMapCurrentLoop":
        """Internal-model gains for the closed-loop bandwidth ``a_c`` (rad/s), stated at the linear
        ``model``'s ``L_d``, ``L_q`` (so ``kp``, ``ki`` equal
        [`current_loop_imc`][pmsmjax.controllers.design.current_loop_imc]'s on that model) with its resistance
        ``R``."""
        check_positive("current-loop bandwidth a_c", bandwidth_rad_s, "rad/s")
        a = jnp.asarray(bandwidth_rad_s, model.R.dtype)
        L = jnp.stack([model.L_d, model.L_q])
        return cls(flux_map, a * model.L_d, a * model.L_q, a * model.R, a * model.R, L)

    def init(self, dtype):
        return jnp.zeros(2, dtype)

    def derivative(self, R, i_dq, u_dq, omega_e) -> Array:
        """``di_dq/dt`` (A/s) of the map's model under ``u_dq`` (V) at ``omega_e`` (rad/s)."""
        psi, L = self.flux_map(i_dq)
        return _solve2(L, u_dq - R * i_dq - omega_e * jnp.stack([-psi[1], psi[0]]))

    def step(self, state, i_dq_ref, i_ab, theta_e, omega_e, ctx: CurrentLoopContext):
        R = ctx.model.R
        i_dq = park(i_ab, theta_e)
        if ctx.delayed and ctx.delay_compensation:
            i_ctrl = i_dq + ctx.Ts * self.derivative(R, i_dq, ctx.u_dq_prev, omega_e)
        else:
            i_ctrl = i_dq
        psi, L = self.flux_map(i_ctrl)
        psi_ref, _ = self.flux_map(i_dq_ref)
        flux_error = psi_ref - psi
        bandwidths = jnp.stack([self.kp_d, self.kp_q]) / self.L_design  # rad/s per axis
        # = bandwidths * L_inc e for a small error e; held to the voltage limit, so that a flux step of
        # more than u_max / a_c (a reluctance machine's q axis) does not make the anti-windup park the
        # integral at the limit less the whole proportional action
        proportional = clip_magnitude(ctx.u_max)(bandwidths * flux_error)
        # the integral sees the flux error as a current error through the local inductance (module
        # docstring): for a small error it is e itself
        error = _solve2(L, flux_error)
        ff = omega_e * jnp.stack([-psi[1], psi[0]]) if ctx.decoupling else jnp.zeros(2, i_dq.dtype)
        integral, u_dq = pi_update(
            0.0,
            jnp.stack([self.ki_d, self.ki_q]),
            state,
            error,
            ctx.Ts,
            clip_magnitude(ctx.u_max),
            feedforward=ff + proportional,
        )
        u_ab = inverse_park(u_dq, theta_e + omega_e * angle_lead(ctx.Ts, ctx.delayed))
        return integral, u_ab, u_dq
