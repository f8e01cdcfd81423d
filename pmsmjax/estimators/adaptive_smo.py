"""Adaptive sliding-mode observer (``adaptive-smo``, the book, ch. 5): the classic SMO's low-pass
filter replaced by a back-EMF model with speed adaptation, so the back-EMF estimate has no phase lag.

Equations (Qiao, Shi, Wang, Yan, Xia, He, "New sliding-mode observer for position sensorless control of
permanent-magnet synchronous motor", IEEE TIE 60(2), 2013, doi:10.1109/TIE.2012.2206359)::

    L di^/dt = -R i^ + u - z,  z = k F(i^ - i)          (the classic SMO's current observer, smo)
    de^/dt   = w^ J e^ + l (z - e^)                     (back-EMF model, J = [[0, -1], [1, 0]])
    dw^/dt   = gamma (e^ x z) / |e^|^2                  (speed adaptation)
    th^      = atan2(-e^_a, e^_b)  (+ pi for w^ < 0)

The back-EMF model is a filter tuned to the estimated speed: for ``w^ = w`` it passes a back-EMF rotating
at ``w`` with unit gain and no phase shift, and the adaptation law (Lyapunov: ``V = |e - e^|^2/2 +
(w - w^)^2/(2 gamma)``, with the cross product ``e^ x z`` standing for ``e^ x (e - e^)``) drives ``w^`` to
``w``. The law is normalised by ``|e^|^2`` (plus ``emf_floor^2``) so the loop's bandwidth does not change
with speed.

Sampled form: the current observer as in [`smo`][pmsmjax.estimators.smo]; the model rotates ``e^`` exactly by
``w^ Ts`` and blends it towards ``z`` with ``a = 1 - exp(-l Ts)``. ``z`` sees the back-EMF through the
observer's own sampled filter (about half a period and the linear-zone pole, the first two terms of
[`smo.SlidingModeObserver.chain_lag`][pmsmjax.estimators.smo.SlidingModeObserver.chain_lag]), so ``e^`` is
turned forward by that phase at the output (outside the loop). Linearised, the angle error between ``e^`` and
``z`` obeys the sampled type-2 tracking loop of [`pll`][pmsmjax.estimators.pll] with ``a = 1 - exp(-l Ts)``,
``b = gamma Ts^2``: design rule ``l = 2 w_n``, ``gamma = w_n^2`` (double pole at ``-w_n``), and
``check_period`` refuses gains whose sampled loop is unstable.
"""

import math

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.smo import (
    SMO_K_MARGIN,
    SMO_POLE,
    AbstractSlidingModeObserver,
    check_observer_pole,
    observer_pole,
    sliding_gains,
)
from pmsmjax.estimators.stability import check_loop, concrete_values, tracking_loop_matrix
from pmsmjax.estimators.stator_model import (
    cross,
    emf_angle,
    first_order_lag,
    period_weight_phase,
    rl_coefficients,
    rotate,
)
from pmsmjax.estimators.switching import Switching
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import check_positive


class AdaptiveSMOState(eqx.Module):
    i_hat: Array  # (2,) A, observer current
    z: Array  # (2,) V, switching output of the last sampling instant
    emf: Array  # (2,) V, back-EMF model state at the last sampling instant
    omega: Array  # rad/s, adapted electrical speed


class AdaptiveSMO(AbstractSlidingModeObserver):
    """SMO with an adaptive back-EMF model (see the module docstring).

    **Arguments:**

    - `model`: the observer's motor model (``R``, ``L_q`` as ``L``, ``psi_f``, ``pole_pairs``).
    - `k`: switching amplitude, V. `width`: switching-function width, A.
    - `l`: back-EMF model gain, rad/s. `gamma`: normalised speed-adaptation gain, 1/s^2.
    - `emf_floor`: back-EMF floor of the adaptation law's normalisation, V.
    - `switching`: ``"sigmoid"`` (default), ``"saturation"`` or ``"sign"`` (static).
    """

    model: PMSMParameters
    k: Array = eqx.field(converter=as_float)
    width: Array = eqx.field(converter=as_float)
    l: Array = eqx.field(converter=as_float)  # noqa: E741 (the book's symbol)
    gamma: Array = eqx.field(converter=as_float)
    emf_floor: Array = eqx.field(converter=as_float)
    switching: Switching = eqx.field(static=True, default="sigmoid")

    def __check_init__(self):
        self.check_switching()
        check_positive("AdaptiveSMO.l (back-EMF model gain)", self.l, "rad/s")
        check_positive("AdaptiveSMO.gamma (speed-adaptation gain)", self.gamma, "1/s^2")
        check_positive("AdaptiveSMO.emf_floor", self.emf_floor, "V")

    def check_period(self, Ts: float) -> None:
        m = self.model
        check_observer_pole("AdaptiveSMO", m.R, m.L_q, self.k, self.width, self.switching, Ts)
        values = concrete_values(self.l, self.gamma)
        if values is not None:
            check_loop(
                f"AdaptiveSMO speed adaptation (l = {values[0].max():g} rad/s, "
                f"gamma = {values[1].max():g} 1/s^2)",
                lambda ll, g: tracking_loop_matrix(-math.expm1(-ll * Ts), g * Ts * Ts),
                values,
                f"lower l and gamma: the rule l = 2 w_n, gamma = w_n^2 is stable for w_n below about "
                f"{(8**0.5 - 2) / Ts:.4g} rad/s",
            )

    def init(self, sample: Sample) -> AdaptiveSMOState:
        zero2 = jnp.zeros_like(sample.i_ab)
        return AdaptiveSMOState(sample.i_ab, zero2, zero2, jnp.zeros((), sample.i_ab.dtype))

    def step(self, state: AdaptiveSMOState, sample: Sample, Ts: float):
        m = self.model
        i_hat, z = self.sliding_update(state, sample.i_ab, sample.u_ab_last, m.L_q, Ts)
        w = state.omega
        e_pred = rotate(state.emf, w * Ts)
        error = cross(e_pred, z) / (jnp.dot(e_pred, e_pred) + self.emf_floor**2)
        emf = e_pred - jnp.expm1(-self.l * Ts) * (z - e_pred)
        omega = w + Ts * self.gamma * error
        # z, hence the model, sees the back-EMF through the observer's own filter (about half a period and
        # the linear-zone pole p): its phase is added to the output, outside the adaptation loop.
        p = observer_pole(*rl_coefficients(m.R, m.L_q, Ts), self.k, self.width, self.switching)
        emf_now = rotate(emf, period_weight_phase(omega, m.R, m.L_q, Ts) + first_order_lag(omega, p, Ts))
        theta = wrap_angle(emf_angle(emf_now, omega))
        new_state = AdaptiveSMOState(i_hat, z, emf, omega)
        return new_state, Estimate(theta, omega / m.pole_pairs, back_emf_ab=emf_now)


#: Design-rule defaults of [`adaptive_smo_design`][pmsmjax.estimators.adaptive_smo.adaptive_smo_design].
ADAPTIVE_SMO_BANDWIDTH = 1000.0


def adaptive_smo_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    switching: Switching = "sigmoid",
    max_speed_rpm: float = 3000.0,
    k_margin: float = SMO_K_MARGIN,
    pole: float = SMO_POLE,
    bandwidth: float = ADAPTIVE_SMO_BANDWIDTH,
    emf_floor_fraction: float = 0.02,
    model: PMSMParameters | None = None,
) -> AdaptiveSMO:
    """The adaptive SMO with design-rule gains for ``motor`` at period ``Ts`` (s).

    Current observer as [`pmsmjax.estimators.smo.smo_design`][pmsmjax.estimators.smo.smo_design] (``k``,
    ``width`` from ``k_margin``, ``pole``, ``max_speed_rpm``); back-EMF model and adaptation with a double
    pole at ``-bandwidth`` (rad/s): ``l = 2 bandwidth``, ``gamma = bandwidth^2``;
    ``emf_floor = emf_floor_fraction psi_f w_max``.
    """
    check_positive("bandwidth (back-EMF model and speed adaptation)", bandwidth, "rad/s")
    model = motor if model is None else model
    k, width, w_max = sliding_gains(model, model.L_q, Ts, max_speed_rpm, k_margin, pole)
    bw = as_float(bandwidth)
    return AdaptiveSMO(
        model, k, width, 2.0 * bw, bw * bw, emf_floor_fraction * model.psi_f * w_max, switching
    )
