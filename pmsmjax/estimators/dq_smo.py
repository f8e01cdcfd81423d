"""Sliding-mode observer in the estimated rotating frame on the extended EMF (``dq-smo``, the book,
ch. 5.3), for salient machines; a PLL drives the estimated EEMF's d component to zero.

Extended EMF model (Chen, Tomita, Doki, Okuma, "An extended electromotive force model for sensorless
control of interior permanent-magnet synchronous motors", IEEE TIE 50(2), 2003,
doi:10.1109/TIE.2003.809391). Written with ``L_d`` on both axes, the dq voltage equation holds the rotor
position only in one vector::

    u_dq = (R + L_d d/dt) i_dq + w L_q J i_dq + E_ex [0, 1],   J = [[0, -1], [1, 0]],
    E_ex = w ((L_d - L_q) i_d + psi_f) - (L_d - L_q) di_q/dt.

In a frame at an estimated angle ``th^`` turning at ``w^`` (angle error ``dth = th - th^``) the same
equation reads, up to a term ``(w^ - w)(L_d - L_q) J i`` that is small when the speed is tracked,
``u = (R + L_d d/dt) i + w^ L_q J i + E_ex [-sin dth, cos dth]``. The observer copies it with a switching
term in place of the EEMF::

    L_d di^/dt = -R i^ + u - w^ L_q J i - z,    z = k F(i^ - i)      (i, u: measured, in the frame)
    E^ = LPF(z),     PLL on  -E^_gamma / |E^|  ~  sin(dth)           (pll)

Because the EEMF is constant in a frame that turns with the rotor, the low-pass filter adds no lag at
steady state (unlike the stationary-frame SMO, whose back-EMF is a sinusoid); it is inside the PLL's loop
instead.

Sampled form: over ``[t_{k-1}, t_k)`` the frame turns at the PLL speed; the held voltage and the mean of
the two sampled currents are turned into the frame at the period's middle angle, the measured current at
``t_k`` at the end angle, and the observer is propagated exactly per axis with ``L_d``. When the PLL
corrects the frame angle the observer's vectors are re-expressed in the corrected frame. Like the other
PLLs here, the loop tracks the EEMF's direction, i.e. the rotor angle for ``w >= 0`` and the rotor angle
plus pi below (the model is the same in both frames;
[`stator_model.rotor_angle`][pmsmjax.estimators.stator_model.rotor_angle]).

Design rule ([`dq_smo_design`][pmsmjax.estimators.dq_smo.dq_smo_design]): ``k``, ``width`` as
[`smo.smo_design`][pmsmjax.estimators.smo.smo_design] with ``L_d``; the PLL at ``pll_bandwidth``
([`pll.pll_design`][pmsmjax.estimators.pll.pll_design]), the low-pass cut-off ``omega_c`` above it.
``check_period`` refuses an unstable linear zone, and PLL gains whose loop through the observer and the filter
is unstable ([`dq_loop_matrix`][pmsmjax.estimators.dq_smo.dq_loop_matrix]).
"""

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.estimators.pll import PLL, PLLState, pll_design
from pmsmjax.estimators.smo import (
    SMO_K_MARGIN,
    SMO_POLE,
    AbstractSlidingModeObserver,
    check_observer_pole,
    sliding_gains,
)
from pmsmjax.estimators.stability import check_loop, concrete_values
from pmsmjax.estimators.stator_model import rl_coefficients, rotate, rotor_angle
from pmsmjax.estimators.switching import Switching
from pmsmjax.frames.three_phase import inverse_park, park, wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import check_positive


def dq_loop_matrix(a: float, b: float, p: float, f: float) -> np.ndarray:
    """One period of the linearised loop, state ``[frame angle error, observer output angle, filtered
    angle, Ts x speed error]`` (in-frame angles, after the frame correction): the frame drifts by the speed
    error, the observer (pole ``p``) and the low-pass filter (pole ``f``) follow the in-frame angle, the
    PLL (``a = Ts kp``, ``b = Ts^2 ki``) corrects the frame by ``a e`` and turns every vector with it."""
    m = np.zeros((4, 4))
    for j in range(4):
        d, s1, s2, w = np.eye(4)[j]
        delta = d - w
        s1 = p * s1 + (1.0 - p) * delta
        s2 = f * s2 + (1.0 - f) * s1
        m[:, j] = [delta - a * s2, s1 - a * s2, s2 - a * s2, w + b * s2]
    return m


class DQSMOState(eqx.Module):
    i_hat: Array  # (2,) A, observer current in the estimated frame
    z: Array  # (2,) V, switching output (estimated frame)
    emf: Array  # (2,) V, low-pass filtered extended EMF (estimated frame)
    i_last: Array  # (2,) A, measured stationary-frame current of the last sampling instant
    theta: Array  # rad, frame angle (the EEMF's direction), wrapped
    omega: Array  # rad/s, PLL electrical speed


class DQSlidingModeObserver(AbstractSlidingModeObserver):
    """Rotating-frame SMO on the extended EMF with a PLL (see the module docstring).

    **Arguments:**

    - `model`: the observer's motor model (``R``, ``L_d``, ``L_q``, ``pole_pairs``; ``psi_f`` is not used).
    - `k`: switching amplitude, V. `width`: switching-function width, A.
    - `omega_c`: low-pass cut-off of the EEMF estimate, rad/s.
    - `pll`: the PLL. `emf_floor`: EEMF floor of the phase-detector normalisation, V.
    - `switching`: ``"sigmoid"`` (default), ``"saturation"`` or ``"sign"`` (static).
    """

    model: PMSMParameters
    k: Array = eqx.field(converter=as_float)
    width: Array = eqx.field(converter=as_float)
    omega_c: Array = eqx.field(converter=as_float)
    pll: PLL
    emf_floor: Array = eqx.field(converter=as_float)
    switching: Switching = eqx.field(static=True, default="sigmoid")

    def __check_init__(self):
        self.check_switching()
        check_positive("DQSlidingModeObserver.omega_c (EEMF low-pass cut-off)", self.omega_c, "rad/s")
        check_positive("DQSlidingModeObserver.emf_floor", self.emf_floor, "V")

    def check_period(self, Ts: float) -> None:
        m = self.model
        check_observer_pole("DQSlidingModeObserver", m.R, m.L_d, self.k, self.width, self.switching, Ts)
        values = concrete_values(self.pll.kp, self.pll.ki, m.R, m.L_d, self.k, self.width, self.omega_c)
        if values is None:
            return

        def loop(kp, ki, r, ell, kk, w, wc):
            phi, gamma = (float(x) for x in rl_coefficients(r, ell, Ts))
            p = 0.0 if self.switching == "sign" else phi - gamma * kk / w
            return dq_loop_matrix(Ts * kp, Ts * Ts * ki, p, math.exp(-wc * Ts))

        check_loop(
            f"DQSlidingModeObserver PLL through the observer and its low-pass filter (kp = "
            f"{values[0].max():g} 1/s, ki = {values[1].max():g} 1/s^2, omega_c = {values[6].max():g} rad/s)",
            loop,
            values,
            "lower the PLL bandwidth or raise omega_c (the filter sits inside the PLL's loop)",
        )

    def init(self, sample: Sample) -> DQSMOState:
        zero2 = jnp.zeros_like(sample.i_ab)
        zero = jnp.zeros((), sample.i_ab.dtype)
        return DQSMOState(park(sample.i_ab, zero), zero2, zero2, sample.i_ab, zero, zero)

    def step(self, state: DQSMOState, sample: Sample, Ts: float):
        m = self.model
        w = state.omega
        theta_pred = PLL.predict(PLLState(state.theta, w), Ts)
        theta_mid = state.theta + 0.5 * Ts * w
        u = park(sample.u_ab_last, theta_mid)
        i_mid = park(0.5 * (state.i_last + sample.i_ab), theta_mid)
        coupling = w * m.L_q * jnp.stack([-i_mid[1], i_mid[0]])
        i_hat, z = self.sliding_update(state, park(sample.i_ab, theta_pred), u - coupling, m.L_d, Ts)
        emf = state.emf - jnp.expm1(-self.omega_c * Ts) * (z - state.emf)
        error = -emf[0] / jnp.sqrt(jnp.dot(emf, emf) + self.emf_floor**2)
        pll = self.pll.correct(PLLState(state.theta, w), theta_pred, error, Ts)
        # Re-express the observer's vectors in the corrected frame (turned by the PLL's correction).
        turn = -Ts * self.pll.kp * error
        i_hat, z, emf = rotate(i_hat, turn), rotate(z, turn), rotate(emf, turn)
        new_state = DQSMOState(i_hat, z, emf, sample.i_ab, pll.theta, pll.omega)
        estimate = Estimate(
            wrap_angle(rotor_angle(pll.theta, pll.omega)),
            pll.omega / m.pole_pairs,
            back_emf_ab=inverse_park(emf, pll.theta),
        )
        return new_state, estimate


#: Design-rule defaults of [`dq_smo_design`][pmsmjax.estimators.dq_smo.dq_smo_design].
DQ_SMO_OMEGA_C = 2000.0
DQ_SMO_PLL_BANDWIDTH = 1000.0


def dq_smo_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    switching: Switching = "sigmoid",
    max_speed_rpm: float = 3000.0,
    k_margin: float = SMO_K_MARGIN,
    pole: float = SMO_POLE,
    omega_c: float = DQ_SMO_OMEGA_C,
    pll_bandwidth: float = DQ_SMO_PLL_BANDWIDTH,
    emf_floor_fraction: float = 0.02,
    model: PMSMParameters | None = None,
) -> DQSlidingModeObserver:
    """The rotating-frame EEMF SMO with design-rule gains for ``motor`` at period ``Ts`` (s).

    ``k = k_margin psi_f p_n w_max`` (V); ``width = k Gamma_d / (Phi_d - pole)`` (A) with the winding
    coefficients of ``L_d``; PLL [`pmsmjax.estimators.pll.pll_design`][pmsmjax.estimators.pll.pll_design] at
    ``pll_bandwidth`` (rad/s); low-pass cut-off ``omega_c`` (rad/s), above the PLL's bandwidth since it sits
    inside the loop; ``emf_floor = emf_floor_fraction psi_f w_max``.
    """
    model = motor if model is None else model
    k, width, w_max = sliding_gains(model, model.L_d, Ts, max_speed_rpm, k_margin, pole)
    return DQSlidingModeObserver(
        model,
        k,
        width,
        omega_c,
        pll_design(pll_bandwidth),
        emf_floor_fraction * model.psi_f * w_max,
        switching,
    )
