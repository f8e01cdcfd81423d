"""The estimator interface: sampled measurements -> rotor angle and speed (the
second block of the sampled-data step of [`pmsmjax.drive`][pmsmjax.drive]).

An estimator is the block between sampling and control. The exact sensor, an encoder and every observer of
the later chapters (sliding-mode, MRAS, EKF, HF injection) implement it, so a sensorless drive is the same
[`pmsmjax.drive.Drive`][pmsmjax.drive.Drive] with another ``estimator``.

- ``init(sample)`` gives the estimator's state from the first sample (an observer that does not know the
  initial angle ignores the sensor fields).
- ``step(state, sample, Ts)`` -> ``(state, Estimate)`` once per control period; the estimate is used by
  the controller in the same period.
- ``injects_voltage`` (class constant): the estimate carries a voltage to add to the controller's command
  (HF injection); the drive adds it only for such estimators, so others cost nothing.
- ``pull(state, estimate, theta_e, omega_m, strength)``: the state moved towards another estimate (how the
  hybrid slaves the estimator it is not listening to); by default the estimator runs free.
- [`AbstractModelObserver`][pmsmjax.estimators.base.AbstractModelObserver]: the fundamental-model observers,
  whose equations use a motor ``model`` (what the flux-map wrappers reschedule).
"""

import abc
from typing import ClassVar

import equinox as eqx

from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.signals import Estimate, Sample


class AbstractEstimator(eqx.Module):
    """Base of every estimator (see the module docstring)."""

    injects_voltage: ClassVar[bool] = False

    @abc.abstractmethod
    def init(self, sample: Sample):
        """The estimator's state from the first period's `sample` (measurements at the start of the run).

        An encoder starts from its count of the sensor's angle (the exact sensor keeps no state:
        ``None``); an observer, which cannot know the rotor's angle, typically starts from the measured
        currents with angle and speed zero. Returns a pytree (the concrete estimator's state type).
        """

    @abc.abstractmethod
    def step(self, state, sample: Sample, Ts: float) -> tuple[object, Estimate]:
        """One control period: update the estimate from this period's `sample`.

        `state`: as returned by [`init`][pmsmjax.estimators.base.AbstractEstimator.init] or the last step;
        `sample`: the period-start measurements (currents A, DC voltage V, last commanded voltage V, sensor
        angle rad); `Ts`: control period, s (static). Returns the new state and the
        [`Estimate`][pmsmjax.signals.Estimate] (electrical angle rad, mechanical speed rad/s, and the optional
        fields the estimator provides) used by the controller in the same period.
        """

    def check_period(self, Ts: float) -> None:
        """Raise [`pmsmjax.ParameterError`][pmsmjax.spec.validation.ParameterError] if the estimator's gains
        are unstable at period ``Ts``, s.

        Called by the drive before compiling; nothing to check here.
        """

    def pull(self, state, estimate: Estimate, theta_e, omega_m, strength):
        """``state`` moved so that the estimate goes ``strength`` (in [0, 1]) of the way to ``theta_e`` (rad)
        and ``omega_m`` (mechanical rad/s); `estimate` is this step's output, from ``state``.

        How [`HybridEstimator`][pmsmjax.estimators.hybrid.HybridEstimator] slaves the estimator it is not
        listening to. The state moves by the *estimate's* distance to the target, not onto the target: an
        estimate may be its state plus a compensation (a filter lag). Here the state is returned unchanged
        (the estimator runs free); the estimators with an angle-and-speed state override it.
        """
        return state


class AbstractModelObserver(AbstractEstimator):
    """A fundamental-model observer: its equations use the motor model ``model`` (the chapter 5 observers,
    the EKF, the stator flux observer), which may differ from the plant's and which the flux-map wrappers
    reschedule ([`pmsmjax.estimators.map_scheduled`][pmsmjax.estimators.map_scheduled],
    [`pmsmjax.estimators.map_angle_corrected`][pmsmjax.estimators.map_angle_corrected])."""

    model: eqx.AbstractVar[PMSMParameters]
