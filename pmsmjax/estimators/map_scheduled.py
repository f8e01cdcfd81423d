"""The chapter 5 back-EMF observers and the EKF on a saturated machine: their constant motor model
replaced, each sample, by the flux map's model at the operating point.

**Which constants.** Every fundamental-model observer here (``smo``, ``smo-pll``, ``adaptive-smo``,
``dq-smo``, ``mras``, ``ekf``) writes the machine with one inductance ``L`` (``L_q``; ``dq-smo``: ``L_d``
for the dynamics, ``L_q`` for the coupling) and the active flux ``psi_a = psi_f + (L_d - L_q) i_d`` along
the d axis, the extended-EMF form (Chen et al., IEEE TIE 50(2), 2003, doi:10.1109/TIE.2003.809391; Boldea,
Paicu, Andreescu, "Active flux concept for motion-sensorless unified AC drives", IEEE TPEL 23(5), 2008,
doi:10.1109/TPEL.2008.2002394): the stator flux is ``psi = L_q i + psi_a [1, 0]`` in the rotor frame. The
back-EMF's direction, hence the angle, is right in steady state when this flux is the machine's. On a
flux map ``psi(i)`` that holds at the operating current ``i`` with

    L_q = psi_q(i) / i_q          (secant: the q flux is exact),
    L_d = dpsi_d/di_d (i)          (incremental, the d dynamics),
    psi_f = psi_d(i) - L_d i_d     (so psi_f + L_d i_d = psi_d(i): the active flux is exact),

and ``L_q`` falls back to the incremental ``dpsi_q/di_q`` for ``|i_q|`` under
[`SECANT_FLOOR_A`][pmsmjax.estimators.map_scheduled.SECANT_FLOOR_A] (the secant's limit there when
``psi_q(i_d, 0) = 0``, a q-symmetric rotor). A constant model taken from the map at one current (the drive
file's rated point) misreads ``L_q`` everywhere else: the saturated-ipm map's secant ``L_q`` is 12 mH at no
load and 6.4 mH at the rated 10 A against its 2.8 mH incremental value there.

**Where the current comes from.** The operating current is the measured one in the observer's last
estimated frame, low-passed (``current_cutoff``) so the model does not follow the PWM ripple or the
observer's own transients; the observer then runs its step with that model. Its gains stay those its
design rule gave for the constant model. That suits the sliding-mode observers and the EKF. The MRAS,
scheduled with the default filter, oscillated from 5 A and lost the angle at the rated current on the
saturated-ipm map (``python -m benchmarks.flux_map_observers``), while with the same map model held
fixed at that current it is steady (0.19 degree): the per-sample change of its model excites it
(rescaling its adaptation gains with the scheduled ``(L / psi_f)^2`` does not damp it). A 30 rad/s
``current_cutoff`` damps it to 0.3-0.4 degree peak-to-peak at 10-25 A, at the price of a model that
follows a load change in tens of milliseconds.

**In the closed loop** the scheduled model oscillates (current-limit overshoot, a limit cycle under
load; its current equation misses ``i dL/dt``): the drive's map-aware observer is
[`map_angle_corrected`][pmsmjax.estimators.map_angle_corrected], the constant model with the map's steady
angle error taken out.

**What a constant model costs**
([`constant_model_angle_error`][pmsmjax.estimators.map_scheduled.constant_model_angle_error]). In steady state
the rotor-frame voltage is ``u = R i + w J psi(i)``; an observer with inductance ``L`` extracts the EMF
``w J (psi(i) - L i)`` and takes its flux ``psi(i) - L i`` for the d axis, so the estimate leads the rotor by
``atan2(psi_q - L i_q, psi_d - L i_d)``. The controller holds its reference in the estimated frame, so the
machine carries that reference turned by the error: a fixed point, as for HF injection
([`hfi_cross_saturation`][pmsmjax.estimators.hfi_cross_saturation]).
"""

import dataclasses
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.estimators import hfi_signal as hs
from pmsmjax.estimators.base import AbstractEstimator, AbstractModelObserver
from pmsmjax.frames.three_phase import park
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.machines.pmsm_flux_map import FluxMap
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_positive

__all__ = [
    "AbstractMapAwareObserver",
    "MapAwareState",
    "MapScheduled",
    "MapScheduledState",
    "map_model",
    "map_scheduled",
    "constant_model_angle_error",
    "SECANT_FLOOR_A",
    "DEFAULT_CURRENT_CUTOFF",
    "check_fundamental_observer",
]

#: Below this |i_q| (A) the q inductance is the incremental one, not the secant ``psi_q / i_q``.
SECANT_FLOOR_A = 0.5
#: Default low-pass cut-off of the operating current, rad/s (160 Hz: a tenth of the book's current loop is
#: 175 Hz; slow against the observers' 10 kHz sample, fast against a load step's settling).
DEFAULT_CURRENT_CUTOFF = 1000.0


def map_model(flux_map: FluxMap, model: PMSMParameters, i_dq: Array) -> PMSMParameters:
    """``model`` with ``L_d``, ``L_q``, ``psi_f`` of the flux map at ``i_dq (2,)`` A (module docstring);
    ``R``, ``J``, ``B``, ``pole_pairs`` kept."""
    psi, L = flux_map(i_dq)
    L_d = L[0, 0]
    secant = jnp.abs(i_dq[1]) >= SECANT_FLOOR_A
    L_q = jnp.where(secant, psi[1] / jnp.where(secant, i_dq[1], 1.0), L[1, 1])
    psi_f = psi[0] - L_d * i_dq[0]
    # patched, not rebuilt: the constructor's converter would recast the traced leaves to the default
    # float precision (a float32 drive under x64) and its checks cannot read traced values anyway
    return eqx.tree_at(lambda m: (m.L_d, m.L_q, m.psi_f), model, (L_d, L_q, psi_f))


def constant_model_angle_error(
    grid: FluxMapGrid, L: float, i_dq_ref, iterations: int = 50
) -> tuple[float, np.ndarray]:
    """Steady angle error ``th^ - th`` (rad) of a back-EMF observer whose model inductance is ``L`` (H)
    on the machine of ``grid`` when the controller holds ``i_dq_ref (2,)`` (A) in the estimated frame, and
    the machine's current ``(2,)`` A then (module docstring; NumPy, fixed-point iteration)."""
    i_ref = np.asarray(i_dq_ref, dtype=float)
    error = 0.0
    for _ in range(iterations):
        c, s = math.cos(error), math.sin(error)
        i = np.array([c * i_ref[0] - s * i_ref[1], s * i_ref[0] + c * i_ref[1]])
        psi, _ = grid.at(*i)
        error = math.atan2(psi[1] - L * i[1], psi[0] - L * i[0])
    return error, i


class MapAwareState(eqx.Module):
    observer: object  # the wrapped observer's state
    i_dq: Array  # (2,) A, low-passed current in the observer's (estimated or corrected) frame
    theta: Array  # rad, the last estimate (the frame of the next sample's current)


#: The state of [`MapScheduled`][pmsmjax.estimators.map_scheduled.MapScheduled].
MapScheduledState = MapAwareState


class AbstractMapAwareObserver(AbstractEstimator):
    """A fundamental-model observer made aware of the machine's flux map from the low-passed operating
    current: [`MapScheduled`][pmsmjax.estimators.map_scheduled.MapScheduled] reschedules its model,
    [`MapAngleCorrected`][pmsmjax.estimators.map_angle_corrected.MapAngleCorrected] corrects its angle.

    Args:
        observer: A fundamental-model observer
            ([`AbstractModelObserver`][pmsmjax.estimators.base.AbstractModelObserver]: the chapter 5
            observers, the EKF).
        flux_map: The machine's map.
        current_cutoff: Operating-current low-pass, rad/s.
    """

    observer: AbstractModelObserver
    flux_map: FluxMap
    current_cutoff: Array = eqx.field(converter=as_float, default=DEFAULT_CURRENT_CUTOFF)

    def __check_init__(self):
        check_positive(f"{type(self).__name__}.current_cutoff", self.current_cutoff, "rad/s")

    def check_period(self, Ts: float) -> None:
        self.observer.check_period(Ts)

    def init(self, sample: Sample) -> MapAwareState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        return MapAwareState(self.observer.init(sample), jnp.zeros(2, sample.i_ab.dtype), zero)

    def pull(self, state: MapAwareState, estimate: Estimate, theta_e, omega_m, strength) -> MapAwareState:
        """The wrapped observer pulled by the estimate's distance to the target (the wrapper's angle
        correction moves with it, so the distance is the same inside)."""
        inner = self.observer.pull(state.observer, estimate, theta_e, omega_m, strength)
        return dataclasses.replace(state, observer=inner)

    def operating_current(self, state: MapAwareState, sample: Sample, Ts: float) -> Array:
        """``(2,)`` A: the low-passed current in the frame of the last estimate."""
        i_now = park(sample.i_ab, state.theta)
        return state.i_dq + hs.lowpass_gain(self.current_cutoff, Ts) * (i_now - state.i_dq)


class MapScheduled(AbstractMapAwareObserver):
    """A fundamental-model observer whose motor model follows the flux map (module docstring). Its fields
    are those of [`AbstractMapAwareObserver`][pmsmjax.estimators.map_scheduled.AbstractMapAwareObserver]."""

    def step(self, state: MapScheduledState, sample: Sample, Ts: float) -> tuple[MapScheduledState, Estimate]:
        i_dq = self.operating_current(state, sample, Ts)
        # the same observer on this period's model (patched, as map_model: its gains keep their dtype)
        observer = eqx.tree_at(
            lambda o: o.model, self.observer, map_model(self.flux_map, self.observer.model, i_dq)
        )
        inner, estimate = observer.step(state.observer, sample, Ts)
        return MapScheduledState(inner, i_dq, estimate.theta_e), estimate


def map_scheduled(
    observer: AbstractEstimator, flux_map: FluxMap, current_cutoff: float = DEFAULT_CURRENT_CUTOFF
) -> MapScheduled:
    """``observer`` with its model scheduled on ``flux_map`` (module docstring)."""
    check_fundamental_observer(observer, "the map-scheduled model")
    return MapScheduled(observer, flux_map, current_cutoff)


def check_fundamental_observer(observer: AbstractEstimator, what: str) -> None:
    """Refuse, in one line naming ``what``, an estimator without a motor model (HF injection)."""
    if not isinstance(observer, AbstractModelObserver):
        raise ParameterError(
            f"{what} applies to the fundamental-model observers (smo, smo-pll, adaptive-smo, dq-smo, mras, "
            f"ekf), got {type(observer).__name__}: HF injection takes the cross-saturation correction "
            "(cross_saturation_compensated)."
        )
