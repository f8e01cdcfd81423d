"""Extended Kalman filter (``ekf``, the book, ch. 5): state ``[i_a, i_b, w_e, th_e]``, measurements
``[i_a, i_b]``, inputs ``[u_a, u_b]``; ``Q``, ``R`` and ``P0`` are the tuning knobs.

Model (Bolognani, Oboe, Zigliotto, "Sensorless full-digital PMSM drive with EKF estimation of speed and
rotor position", IEEE TIE 46(1), 1999, doi:10.1109/41.744410): the surface machine in the stationary
frame, ``L di/dt = u - R i - w psi_f [-sin th, cos th]``, speed constant over a period (its changes are
process noise), ``dth/dt = w``. Sampled exactly over the period as in
[`stator_model`][pmsmjax.estimators.stator_model]::

    i_k  = Phi i + Gamma (u_{k-1} - w psi_f [-sin th_w, cos th_w]),   th_w = th + w Ts - lag_W(w)
    w_k  = w,     th_k = th + w Ts

(``th_w``: the angle of the period's weighted back-EMF, about the period's middle). The filter predicts
with this model and its Jacobian (``jax.jacfwd``: exact for the model as written), then corrects with the
sampled current; the covariance update is Joseph's form (stays symmetric positive definite in float32).
``L`` is the model's ``L_q`` and ``psi_f`` is the active flux ``psi_f + (L_d - L_q) i_d`` with ``i_d`` the
state's current in the state's rotor frame ([`active_flux`][pmsmjax.estimators.ekf.active_flux];
[`stator_model`][pmsmjax.estimators.stator_model]): the salient machine's EMF in steady state (the transient
term ``(L_d - L_q) di_d/dt`` is left to the process noise).

Design rule ([`ekf_design`][pmsmjax.estimators.ekf.ekf_design], following the physical reading of Bolognani,
Tubiana, Zigliotto, "Extended Kalman filter tuning in sensorless PMSM drives", IEEE TIA 39(6), 2003,
doi:10.1109/TIA.2003.818991): ``R = sigma_i^2`` (current-sensor noise), ``Q_i = (Gamma sigma_u)^2`` (the
current a voltage error ``sigma_u`` makes in a period), ``Q_w = (Ts a_w)^2`` (the speed change of a period
at the acceleration ``a_w`` the filter must follow), ``Q_th`` a small angle random walk, and ``P0`` the
variance of a machine at rest in an unknown position.

There is no sampled loop gain to refuse: the Kalman gain is computed online and is stable for positive
definite ``Q``, ``R``, ``P0``, which ``__check_init__`` requires (diagonals > 0).
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractModelObserver
from pmsmjax.estimators.stator_model import emf_direction, period_weight_phase, rl_coefficients
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_positive
from pmsmjax.units import rpm_to_rad_s


class EKFState(eqx.Module):
    x: Array  # (4,) [i_a A, i_b A, w_e rad/s, th_e rad], after the last correction
    P: Array  # (4, 4) its covariance


class EKF(AbstractModelObserver):
    """Extended Kalman filter on the stationary-frame model (see the module docstring).

    **Arguments:**

    - `model`: the filter's motor model (``R``, ``L_q`` as ``L``, ``psi_f``, ``pole_pairs``).
    - `q`: ``(4,)`` diagonal of the process noise covariance per period: A^2, A^2, (rad/s)^2, rad^2.
    - `r`: ``(2,)`` diagonal of the measurement noise covariance, A^2.
    - `p0`: ``(4,)`` diagonal of the initial covariance: A^2, A^2, (rad/s)^2, rad^2.
    """

    model: PMSMParameters
    q: Array = eqx.field(converter=as_float)
    r: Array = eqx.field(converter=as_float)
    p0: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        for name, value, n, unit in (
            ("EKF.q (process noise diagonal)", self.q, 4, "A^2, A^2, (rad/s)^2, rad^2"),
            ("EKF.r (measurement noise diagonal)", self.r, 2, "A^2"),
            ("EKF.p0 (initial covariance diagonal)", self.p0, 4, "A^2, A^2, (rad/s)^2, rad^2"),
        ):
            if jnp.shape(value)[-1:] != (n,):
                raise ParameterError(f"{name} must have {n} entries ({unit}), got shape {jnp.shape(value)}.")
            check_positive(name, value, unit, "every variance must be > 0 (a positive definite matrix)")

    def transition(self, x, u_ab, Ts: float):
        """The model over one period: ``(4,)`` state and ``(2,)`` held voltage (V) -> ``(4,)`` state."""
        m = self.model
        phi, gamma = rl_coefficients(m.R, m.L_q, Ts)
        i, w, th = x[:2], x[2], x[3]
        e = w * active_flux(m, i, th) * emf_direction(th + w * Ts - period_weight_phase(w, m.R, m.L_q, Ts))
        i_next = phi * i + gamma * (u_ab - e)
        return jnp.concatenate([i_next, jnp.stack([w, th + w * Ts])])

    def init(self, sample: Sample) -> EKFState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        x = jnp.concatenate([sample.i_ab, jnp.stack([zero, zero])])
        return EKFState(x, jnp.diag(self.p0).astype(x.dtype))

    def step(self, state: EKFState, sample: Sample, Ts: float):
        m = self.model
        x_pred = self.transition(state.x, sample.u_ab_last, Ts)
        F = jax.jacfwd(self.transition)(state.x, sample.u_ab_last, Ts)
        P = _mm(_mm(F, state.P), F.T) + jnp.diag(self.q)
        S = P[:2, :2] + jnp.diag(self.r)
        # K = P H^T S^-1 with the 2x2 inverse written out (a LAPACK call per period costs more than the rest).
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        S_inv = jnp.stack([jnp.stack([S[1, 1], -S[0, 1]]), jnp.stack([-S[1, 0], S[0, 0]])]) / det
        K = _mm(P[:, :2], S_inv)
        x = x_pred + jnp.sum(K * (sample.i_ab - x_pred[:2]), axis=-1)
        IKH = jnp.eye(4, dtype=P.dtype).at[:, :2].add(-K)
        P = _mm(_mm(IKH, P), IKH.T) + _mm(K * self.r, K.T)
        P = 0.5 * (P + P.T)
        theta = wrap_angle(x[3])
        x = x.at[3].set(theta)
        w = x[2]
        emf = w * active_flux(m, x[:2], theta) * emf_direction(theta)
        return EKFState(x, P), Estimate(theta, w / m.pole_pairs, back_emf_ab=emf)

    def pull(self, state: EKFState, estimate: Estimate, theta_e, omega_m, strength) -> EKFState:
        """The state's speed and angle (``x[2]``, ``x[3]``) moved by the estimate's distance to the target."""
        d_theta = strength * wrap_angle(theta_e - estimate.theta_e)
        d_omega = strength * (omega_m - estimate.omega_m)
        x = state.x
        x = x.at[2].add(self.model.pole_pairs * d_omega).at[3].set(wrap_angle(x[3] + d_theta))
        return dataclasses.replace(state, x=x)


def active_flux(model: PMSMParameters, i_ab, theta) -> Array:
    """The active flux ``psi_f + (L_d - L_q) i_d`` (Wb) of ``model`` for the stationary-frame current
    ``i_ab (2,)`` (A) seen in a rotor frame at angle ``theta`` (rad): the flux whose rotation drives the
    back-EMF of the salient machine written with ``L = L_q``
    ([`stator_model`][pmsmjax.estimators.stator_model]; Boldea et al. 2008). ``psi_f`` exactly for
    ``L_d = L_q``.

    Why it is in the filter's model and not taken as ``psi_f``: ``i_d = 0`` is held in the *estimated*
    frame, so an angle error ``d`` gives the machine ``i_d = -i_q sin d`` and an EMF ``w (L_d - L_q) i_d``
    the ``psi_f`` model does not have. The filter reads that EMF as a speed and angle error, which moves
    ``d`` further: a loop whose gain grows with ``w i_q (L_q - L_d) / psi_f``. On the salient book motor
    (L_d 5.25, L_q 12 mH) it went unstable at 2000 r/min under 2 N m (a growing ~30 Hz oscillation of
    the speed loop, lock lost; README.md); the non-salient motor holds that point."""
    i_d = i_ab[0] * jnp.cos(theta) + i_ab[1] * jnp.sin(theta)
    return model.psi_f + (model.L_d - model.L_q) * i_d


def _mm(a, b):
    """``a @ b`` for the filter's 4x4 (and smaller) matrices as broadcast products: inside the period scan
    XLA:CPU fuses these, while each ``dot`` is a separate call (with dots the filter alone cost 5.1 us per
    sample offline, with these 1.1; benchmarks/bench_observers.py measures it)."""
    return jnp.sum(a[:, :, None] * b[None, :, :], axis=1)


#: Design-rule defaults of [`ekf_design`][pmsmjax.estimators.ekf.ekf_design].
EKF_CURRENT_NOISE_A = 0.05
EKF_VOLTAGE_ERROR_V = 1.0
EKF_ACCELERATION_TORQUE_NM = 10.0
EKF_ANGLE_WALK_RAD = 1e-4
EKF_MAX_SPEED_RPM = 3000.0


def ekf_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    current_noise_a: float = EKF_CURRENT_NOISE_A,
    voltage_error_v: float = EKF_VOLTAGE_ERROR_V,
    acceleration_torque_nm: float = EKF_ACCELERATION_TORQUE_NM,
    angle_walk_rad: float = EKF_ANGLE_WALK_RAD,
    max_speed_rpm: float = EKF_MAX_SPEED_RPM,
    model: PMSMParameters | None = None,
) -> EKF:
    """The EKF with design-rule covariances for ``motor`` at period ``Ts`` (s) (module docstring):

    - ``r = current_noise_a^2`` (A^2; 0.05 A is 0.5 % of the book drive's 10 A);
    - ``q_i = (Gamma voltage_error_v)^2`` (A^2), ``q_w = (Ts p_n acceleration_torque_nm / J)^2`` ((rad/s)^2:
      the speed change a torque of that size makes in a period), ``q_th = angle_walk_rad^2`` (rad^2);
    - ``p0 = [r, r, (p_n w_max)^2, pi^2]``: currents as measured, speed and angle unknown.
    """
    check_positive("Ts (control period)", Ts, "s")
    check_positive("current_noise_a", current_noise_a, "A")
    check_positive("voltage_error_v", voltage_error_v, "V")
    check_positive("acceleration_torque_nm", acceleration_torque_nm, "N m")
    check_positive("angle_walk_rad", angle_walk_rad, "rad")
    model = motor if model is None else model
    _, gamma = rl_coefficients(model.R, model.L_q, Ts)
    q_i = (gamma * voltage_error_v) ** 2
    q_w = (Ts * model.pole_pairs * acceleration_torque_nm / model.J) ** 2
    r = as_float(current_noise_a) ** 2
    w_max = model.pole_pairs * rpm_to_rad_s(max_speed_rpm)
    q = jnp.stack([q_i, q_i, q_w, as_float(angle_walk_rad) ** 2])
    p0 = jnp.stack([r, r, as_float(w_max) ** 2, as_float(jnp.pi) ** 2])
    return EKF(model, q, jnp.stack([r, r]), p0)
