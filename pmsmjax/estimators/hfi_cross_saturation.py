"""The cross-saturation angle error of HF injection on a saturated machine, predicted from its flux map and
taken out of the estimate.

**Where HF injection locks.** The carrier sees the incremental inductance ``L_inc = dpsi/di`` at the
operating point (the small-signal flux ``psi_h = L_inc i_h``; resistance and back-EMF neglected as in
[`hfi_signal`][pmsmjax.estimators.hfi_signal]). With cross-saturation ``L_inc = [[L_dd, L_dq], [L_qd, L_qq]]``
has off-diagonal terms; with its symmetric part ``L_s`` (``M = (L_dq + L_qd) / 2``) and the admittance ``G =
L_s^-1 = [[L_qq, -M], [-M, L_dd]] / det``, a d-axis flux in a frame ``dth = th - th^`` behind the rotor gives
the q-axis current (frame rotation of a symmetric matrix)

    i_qh^ / psi_dh = (G_dd - G_qq) / 2 sin(2 dth) + G_dq cos(2 dth)
                   = [(L_qq - L_dd) / 2 sin(2 dth) - M cos(2 dth)] / det,

the pulsating method's error signal; the rotating method's negative sequence ``(G_dd - G_qq) / 2 + j G_dq``
turned by ``2 th`` carries the same angle. Both vanish, on the stable branch, at

    th^ - th = theta_err = -1/2 atan2(2 M, L_qq - L_dd),

the axis of the smallest incremental inductance (an eigenvector of ``L_s``): with ``M = 0`` it is the d
axis; where saturation makes ``L_qq < L_dd`` it swings to the q axis (``theta_err -> -90`` degrees) and the
estimate no longer knows d. References: P. Guglielmi, M. Pastorelli, A. Vagati, "Cross-saturation
effects in IPM motors and related impact on sensorless control", IEEE TIA 42(6), 2006,
doi:10.1109/TIA.2006.882646 (the angle); Z. Q. Zhu, Y. Li, D. Howe, C. M. Bingham, "Compensation for rotor
position estimation error due to cross-coupling magnetic saturation in signal injection based sensorless
control of PM brushless AC motors", IEMDC 2007, doi:10.1109/IEMDC.2007.383578 (its compensation).

**The operating point.** The controller regulates its reference ``i_ref`` in the estimated frame, so the
machine carries ``i = R(theta_err) i_ref`` (``R`` the rotation) and the lock angle is the fixed point
``theta_err = f(R(theta_err) i_ref)``
([`predicted_angle_error`][pmsmjax.estimators.hfi_cross_saturation.predicted_angle_error]). The rotation feeds
back: on the saturated-ipm map with ``i_d < 0`` a negative error turns the current towards the q axis, which
saturates it further and turns the saliency axis further; beyond a few amperes of ``i_q`` there is no lock
near d.

**Compensation**
([`CrossSaturationCompensated`][pmsmjax.estimators.hfi_cross_saturation.CrossSaturationCompensated]): wraps a
rotating or pulsating injection estimator, which keeps injecting and demodulating on the axis it locks to;
each sample the fundamental current in the corrected frame ``th^ - theta_err`` (the true rotor frame once
converged), low-passed as slowly as the estimator's PLL follows, gives ``L_inc`` from the map and
``theta_err``, and the estimate handed to the controller is ``th^ - theta_err``.
"""

import dataclasses
import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.estimators import hfi_signal as hs
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.hfi_pulsating import HFIPulsating
from pmsmjax.estimators.hfi_rotating import HFIRotating
from pmsmjax.frames.three_phase import park, wrap_angle
from pmsmjax.machines.flux_map import FluxMapGrid, flux_and_inductance
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.machines.pmsm_flux_map import FluxMap
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_positive

__all__ = [
    "saliency_angle",
    "predicted_angle_error",
    "CrossSaturationCompensated",
    "CrossSaturationState",
    "cross_saturation_compensated",
    "injection_model",
]


def saliency_angle(L_inc, xp=jnp):
    """Angle of the smallest-incremental-inductance axis from d, rad: ``-1/2 atan2(L_dq + L_qd, L_qq -
    L_dd)`` (module docstring) for ``L_inc (..., 2, 2)`` H; where HF injection locks, ``th^ - th``."""
    L = xp.asarray(L_inc)
    return -0.5 * xp.arctan2(L[..., 0, 1] + L[..., 1, 0], L[..., 1, 1] - L[..., 0, 0])


def _rotate(angle: float, x: np.ndarray) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * x[0] - s * x[1], s * x[0] + c * x[1]])


def predicted_angle_error(grid: FluxMapGrid, i_dq_ref, step_deg: float = 0.1) -> tuple[float, np.ndarray]:
    """Steady angle error ``th^ - th`` (rad) of uncompensated HF injection when the controller holds
    ``i_dq_ref (2,)`` (A) in the estimated frame, and the machine's current ``(2,)`` A then (NumPy).

    The lock is a root of ``h(e) = f(R(e) i_ref) - e`` (module docstring, angles modulo pi). Locked on d
    before the load comes, the estimate drifts the way ``h(0)`` points until ``h`` changes sign: that
    root, found by walking in ``step_deg`` steps and bisecting. Where there is none within 90 degrees
    (the error feeds on itself into the saturated q axis) the error is ``nan``.
    """
    i_ref = np.asarray(i_dq_ref, dtype=float)
    coefficients = grid.coefficients()  # once, not per grid.at call

    def h(e):
        _, L = flux_and_inductance(coefficients, grid.lower, grid.step, grid.upper, _rotate(e, i_ref), np)
        drift = float(saliency_angle(L, np)) - e
        return (drift + 0.5 * math.pi) % math.pi - 0.5 * math.pi

    h0 = h(0.0)
    if h0 == 0.0:
        return 0.0, i_ref
    direction = math.copysign(1.0, h0)
    a, h_a = 0.0, h0
    for k in range(1, int(90.0 / step_deg) + 1):
        b = direction * math.radians(k * step_deg)
        h_b = h(b)
        if h_b * h_a <= 0.0 and abs(h_b - h_a) < 0.5 * math.pi:  # a root, not the modulo-pi wrap
            for _ in range(50):
                m = 0.5 * (a + b)
                h_m = h(m)
                a, h_a, b = (m, h_m, b) if h_m * h_a > 0.0 else (a, h_a, m)
            error = 0.5 * (a + b)
            return error, _rotate(error, i_ref)
        a, h_a = b, h_b
    return math.nan, np.full(2, math.nan)


def injection_model(grid: FluxMapGrid, motor: PMSMParameters, i_dq) -> PMSMParameters:
    """``motor`` with ``L_d = L_dd``, ``L_q = L_qq`` of the map's incremental inductance at ``i_dq (2,)`` A:
    what an injection estimator's design rule (carrier voltage, error-signal scale) should see at the
    operating point it serves. A map's linear model at the rated current may have ``L_q < L_d`` (the q
    path saturated) and be refused by the saliency check though the machine is salient at light load."""
    _, L = grid.at(*np.asarray(i_dq, dtype=float))
    # patched, not rebuilt: the design rule reads the map's values as the Python floats they are (the
    # constructor would convert them to arrays of the default precision) and the rest of the motor as is
    return eqx.tree_at(lambda m: (m.L_d, m.L_q), motor, (float(L[0, 0]), float(L[1, 1])))


class CrossSaturationState(eqx.Module):
    injection: object  # the wrapped estimator's state
    i_dq: Array  # (2,) A, low-passed fundamental current in the corrected frame
    angle_error: Array  # rad, the last theta_err taken out


class CrossSaturationCompensated(AbstractEstimator):
    """An HF-injection estimator whose angle is corrected by the flux map's cross-saturation angle (module
    docstring).

    **Arguments:**

    - `injection`: [`HFIRotating`][pmsmjax.estimators.hfi_rotating.HFIRotating] or
      [`HFIPulsating`][pmsmjax.estimators.hfi_pulsating.HFIPulsating].
    - `flux_map`: the machine's [`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap].
    - `current_cutoff`: low-pass cut-off of the current the correction reads, rad/s.
    """

    injects_voltage: ClassVar[bool] = True

    injection: AbstractEstimator
    flux_map: FluxMap
    current_cutoff: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("CrossSaturationCompensated.current_cutoff", self.current_cutoff, "rad/s")

    def check_period(self, Ts: float) -> None:
        self.injection.check_period(Ts)

    def init(self, sample: Sample) -> CrossSaturationState:
        dtype = sample.i_ab.dtype
        return CrossSaturationState(self.injection.init(sample), jnp.zeros(2, dtype), jnp.zeros((), dtype))

    def pull(self, state: CrossSaturationState, estimate: Estimate, theta_e, omega_m, strength):
        """The injection's PLL pulled by the corrected estimate's distance to the target (the correction is
        a shift of the same estimate, so the distance is the same inside; the hybrid's pull)."""
        injection = self.injection.pull(state.injection, estimate, theta_e, omega_m, strength)
        return dataclasses.replace(state, injection=injection)

    def step(
        self, state: CrossSaturationState, sample: Sample, Ts: float
    ) -> tuple[CrossSaturationState, Estimate]:
        injection, estimate = self.injection.step(state.injection, sample, Ts)
        i_ab = sample.i_ab if estimate.i_ab_fundamental is None else estimate.i_ab_fundamental
        i_now = park(i_ab, estimate.theta_e - state.angle_error)
        i_dq = state.i_dq + hs.lowpass_gain(self.current_cutoff, Ts) * (i_now - state.i_dq)
        angle_error = saliency_angle(self.flux_map(i_dq)[1])
        theta = wrap_angle(estimate.theta_e - angle_error)
        corrected = dataclasses.replace(estimate, theta_e=theta)
        return CrossSaturationState(injection, i_dq, angle_error), corrected


def cross_saturation_compensated(
    injection: AbstractEstimator, flux_map: FluxMap, current_cutoff: float | None = None
) -> CrossSaturationCompensated:
    """``injection`` with the cross-saturation correction of ``flux_map``; the current low-pass defaults to
    the injection PLL's bandwidth (``kp / 2`` rad/s of its double-pole design): the correction moves no
    faster than the estimate it corrects."""
    if not isinstance(injection, (HFIRotating, HFIPulsating)):
        raise ParameterError(
            "the cross-saturation correction applies to HF injection (hfi-rotating, hfi-pulsating), got "
            f"{type(injection).__name__}: use the map-scheduled model (map_scheduled) for a back-EMF "
            "observer."
        )
    cutoff = 0.5 * injection.pll.kp if current_cutoff is None else current_cutoff
    return CrossSaturationCompensated(injection, flux_map, cutoff)
