"""Model-reference adaptive system (``mras``, the book, ch. 5): the machine is the reference model, the
current model with the estimated speed the adjustable one, and a Popov-hyperstable PI law adapts the speed.

Equations (book; the PMSM form of Schauder's speed MRAS, Schauder, "Adaptive speed identification for
vector control of induction motors without rotational transducers", IEEE TIA 28(5), 1992,
doi:10.1109/28.158829; Popov's hyperstability: Landau, *Adaptive Control: The Model Reference
Approach*, 1979), surface machine, in the estimated frame with ``i'_d = i_d + psi_f/L``::

    di'^_d/dt = -(R/L) i'^_d + w^ i^_q + u'_d/L,      u'_d = u_d + R psi_f / L
    di^_q/dt  = -w^ i'^_d - (R/L) i^_q + u_q/L
    w^ = (Kp + Ki/s) [i_d i^_q - i^_d i_q - (psi_f/L)(i_q - i^_q)],      th^ = integral of w^.

The adjustable model is the same machine in the stationary frame, ``L di^/dt = u - R i^ - w^ psi_f
[-sin th^, cos th^]``, so it is propagated there exactly over each period (with the back-EMF of the
period's weighted middle, [`stator_model`][pmsmjax.estimators.stator_model]), and the adaptation error is
evaluated there: the first two terms are the cross product ``i x i^`` (rotation invariant), the third the
current error along the estimated q axis. ``L`` is the model's ``L_q`` (active flux,
[`stator_model`][pmsmjax.estimators.stator_model]).

Design rule ([`mras_design`][pmsmjax.estimators.mras.mras_design]): linearised about a tracked rotor with
``R << w L``, a speed error ``dw`` makes the q-current error grow as ``L d(i - i^)_q/dt = psi_f dw`` and the
adaptation error is ``-(psi_f/L)(i - i^)_q``: the loop is ``s^2 + Kp (psi_f/L)^2 s + Ki (psi_f/L)^2``. A
double pole at ``-bandwidth`` gives ``Kp = 2 bw (L/psi_f)^2``, ``Ki = bw^2 (L/psi_f)^2``. ``check_period``
refuses gains whose sampled version of that loop (the winding discretised exactly, resistance included, one
period of delay in the model: [`mras_loop_matrix`][pmsmjax.estimators.mras.mras_loop_matrix]) is unstable.

The angle is corrected only through the coupling of the two axes at speed (the ``w L`` terms), so near
standstill the MRAS estimates speed but lets the angle drift: a known limit of the method.
"""

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractModelObserver
from pmsmjax.estimators.stability import check_loop, concrete_values
from pmsmjax.estimators.stator_model import cross, emf_direction, period_weight_phase, rl_coefficients
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import check_positive


class MRASState(eqx.Module):
    i_hat: Array  # (2,) A, adjustable model current (stationary frame)
    theta: Array  # rad, estimated electrical angle at the last sampling instant
    omega: Array  # rad/s, estimated electrical speed (the PI's output)
    integral: Array  # rad/s, the PI's integral part


def mras_loop_matrix(kp: float, ki: float, psi_f: float, L: float, R: float, Ts: float) -> np.ndarray:
    """One period of the linearised MRAS loop (module docstring), state ``[(psi_f/L) q-current error A,
    integral deviation rad/s]``: ``y_k = Phi y + Gamma (psi_f^2/L) dw``, ``dw = x - Kp y``,
    ``x_k = x - Ts Ki y_k``."""
    phi = math.exp(-R * Ts / L)
    g = -math.expm1(-R * Ts / L) / R * psi_f**2 / L
    m11 = phi - g * kp
    return np.array([[m11, g], [-Ts * ki * m11, 1.0 - Ts * ki * g]])


class MRAS(AbstractModelObserver):
    """Speed MRAS with the current model as adjustable model (see the module docstring).

    **Arguments:**

    - `model`: the observer's motor model (``R``, ``L_q`` as ``L``, ``psi_f``, ``pole_pairs``).
    - `kp`: proportional adaptation gain, (rad/s)/A^2. `ki`: integral gain, (rad/s^2)/A^2.
    """

    model: PMSMParameters
    kp: Array = eqx.field(converter=as_float)
    ki: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("MRAS.kp (proportional adaptation gain)", self.kp, "(rad/s)/A^2")
        check_positive("MRAS.ki (integral adaptation gain)", self.ki, "(rad/s^2)/A^2")

    def check_period(self, Ts: float) -> None:
        m = self.model
        values = concrete_values(self.kp, self.ki, m.psi_f, m.L_q, m.R)
        if values is None:
            return
        check_loop(
            f"MRAS adaptation (kp = {values[0].max():g}, ki = {values[1].max():g})",
            lambda p, i, f, ell, r: mras_loop_matrix(p, i, f, ell, r, Ts),
            values,
            f"lower the gains: with kp = 2 bw (L/psi_f)^2, ki = bw^2 (L/psi_f)^2 keep bw well below "
            f"{1.0 / Ts:g} rad/s (1/Ts)",
        )

    def init(self, sample: Sample) -> MRASState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        return MRASState(sample.i_ab, zero, zero, zero)

    def step(self, state: MRASState, sample: Sample, Ts: float):
        m = self.model
        phi, gamma = rl_coefficients(m.R, m.L_q, Ts)
        w, th = state.omega, state.theta
        theta_pred = th + w * Ts
        e_model = w * m.psi_f * emf_direction(theta_pred - period_weight_phase(w, m.R, m.L_q, Ts))
        i_hat = phi * state.i_hat + gamma * (sample.u_ab_last - e_model)
        i = sample.i_ab
        error = cross(i, i_hat) - (m.psi_f / m.L_q) * jnp.dot(i - i_hat, emf_direction(theta_pred))
        integral = state.integral + Ts * self.ki * error
        omega = integral + self.kp * error
        theta = wrap_angle(theta_pred)
        emf = omega * m.psi_f * emf_direction(theta)
        return MRASState(i_hat, theta, omega, integral), Estimate(
            theta, omega / m.pole_pairs, back_emf_ab=emf
        )


#: Design-rule default of [`mras_design`][pmsmjax.estimators.mras.mras_design], rad/s.
MRAS_BANDWIDTH = 1000.0


def mras_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    bandwidth: float = MRAS_BANDWIDTH,
    model: PMSMParameters | None = None,
) -> MRAS:
    """The MRAS with a double pole of the linearised adaptation loop at ``-bandwidth`` (rad/s):
    ``Kp = 2 bw (L/psi_f)^2``, ``Ki = bw^2 (L/psi_f)^2`` (module docstring). ``Ts`` (s) is checked by
    [`MRAS.check_period`][pmsmjax.estimators.mras.MRAS]."""
    check_positive("Ts (control period)", Ts, "s")
    check_positive("bandwidth (MRAS adaptation)", bandwidth, "rad/s")
    model = motor if model is None else model
    bw = as_float(bandwidth)
    scale = (model.L_q / model.psi_f) ** 2
    return MRAS(model, 2.0 * bw * scale, bw * bw * scale)
