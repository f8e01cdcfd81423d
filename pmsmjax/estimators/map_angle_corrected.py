"""A back-EMF observer with its constant model kept, and its steady angle error on a saturated machine
taken out by the flux map: the map-aware observer for the closed loop.

**Why not schedule the model.** [`map_scheduled`][pmsmjax.estimators.map_scheduled] gives the observer, each
sample, the map's ``L_q`` at the operating current. In the closed loop from standstill on the saturated-ipm
drive file that oscillates (``python -m pmsmjax demo --motor saturated-ipm --control pi --estimator
smo --observer-model map --load-nm 5``: 33-41 A against the 25 A limit, a +-7 degree limit cycle under load):
the observer's current equation ``L di/dt = u - R i - e`` with a time-varying ``L`` misses ``i dL/dt``, which
it reads as back-EMF; a current ripple then moves ``L`` (the secant ``L_q`` goes from 12 mH at no load to 6.4
mH at 10 A), hence the angle, hence the current. Keeping the flux ``L i`` across each change of ``L``
(the missing term restored) halved the ripple but left +-3 degrees; a slower schedule (30-300 rad/s) did
not remove it.

**What is done instead.** The observer keeps one constant inductance ``L`` (its model's ``L_q``). For
*any* flux map ``psi(i)`` the stationary-frame voltage equation gives, exactly and with no derivative of
the model, ``u - R i - L di/dt = d/dt (psi_s - L i_s)``: the observer sees the back-EMF of the vector
``psi - L i``, which in the rotor frame points ``eps(i) = atan2(psi_q(i) - L i_q, psi_d(i) - L i_d)``
ahead of the d axis (the "active flux" with a chosen inductance: Boldea, Paicu, Andreescu, "Active flux
concept for motion-sensorless unified AC drives", IEEE TPEL 23(5), 2008, doi:10.1109/TPEL.2008.2002394).
Its angle is therefore ``theta + eps(i)`` in steady state, and ``eps`` is known from the map: the
estimate handed on is ``theta_obs - eps(i_dq)``, ``i_dq`` the measured current in the last *corrected*
frame (the rotor frame when the correction is right: a consistent fixed point), low-passed
(``current_cutoff``) so the correction does not follow the PWM ripple. The observer's dynamics are those
of its constant model, untouched; only a static, smooth function of the current is subtracted. Near
the rated point ``L`` is the map's incremental ``L_q``, so ``d eps / d i_q`` is small there and a
current error barely moves the correction.

This is exact for the observers whose angle is the direction of ``psi - L_q i`` (``smo``, ``smo-pll``,
``adaptive-smo``, ``mras``). The EKF and ``dq-smo`` carry a ``L_d``/``L_q`` model and take part of the
flux mismatch as a speed error; with the same correction the EKF is left 1.2 degrees off under the 5 N m
load of the demo above (``--estimator ekf``), against 20 degrees with its constant model alone.
"""

import dataclasses

import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.map_scheduled import (
    DEFAULT_CURRENT_CUTOFF,
    AbstractMapAwareObserver,
    MapAwareState,
    check_fundamental_observer,
)
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.pmsm_flux_map import FluxMap
from pmsmjax.signals import Estimate, Sample

__all__ = ["MapAngleCorrected", "MapAngleCorrectedState", "map_angle_corrected", "model_flux_angle"]


def model_flux_angle(flux_map: FluxMap, L, i_dq: Array) -> Array:
    """``eps = atan2(psi_q - L i_q, psi_d - L i_d)`` (rad): the angle of the map's flux less ``L`` (H)
    times the rotor-frame current ``i_dq (2,)`` A, ahead of the d axis; the steady angle error of a
    back-EMF observer with inductance ``L`` (module docstring)."""
    psi, _ = flux_map(i_dq)
    return jnp.arctan2(psi[1] - L * i_dq[1], psi[0] - L * i_dq[0])


#: The state of [`MapAngleCorrected`][pmsmjax.estimators.map_angle_corrected.MapAngleCorrected] (its
#: ``i_dq`` and ``theta`` in the corrected frame).
MapAngleCorrectedState = MapAwareState


class MapAngleCorrected(AbstractMapAwareObserver):
    """A constant-model observer whose angle is corrected by the flux map (module docstring): its ``L_q`` is
    the inductance corrected for. Its fields are those of
    [`AbstractMapAwareObserver`][pmsmjax.estimators.map_scheduled.AbstractMapAwareObserver].
    """

    def step(
        self, state: MapAngleCorrectedState, sample: Sample, Ts: float
    ) -> tuple[MapAngleCorrectedState, Estimate]:
        inner, estimate = self.observer.step(state.observer, sample, Ts)
        i_dq = self.operating_current(state, sample, Ts)
        eps = model_flux_angle(self.flux_map, self.observer.model.L_q, i_dq)
        theta = wrap_angle(estimate.theta_e - eps)
        return MapAngleCorrectedState(inner, i_dq, theta), dataclasses.replace(estimate, theta_e=theta)


def map_angle_corrected(
    observer: AbstractEstimator, flux_map: FluxMap, current_cutoff: float = DEFAULT_CURRENT_CUTOFF
) -> MapAngleCorrected:
    """``observer`` with its angle corrected by ``flux_map`` (module docstring)."""
    check_fundamental_observer(observer, "the map's angle correction")
    return MapAngleCorrected(observer, flux_map, current_cutoff)
