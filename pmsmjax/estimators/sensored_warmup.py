"""Sensored warm-up: the drive runs on its position sensor for a fixed time while the observer converges in
the background, then on the observer (issue 14, observer tuning).

Why: to tune an observer by gradients the loss must be a smooth function of its gains. A start from
standstill with the I/f hand-over (:mod:`.startup`) is continuous, but whether a back-EMF observer locks
after it depends on the scenario (measured: smo-pll and adaptive-smo lose the angle when the I/f start is
followed by 100 r/min or by a reversal), and a lost lock is a jump in the loss. Starting the plant at speed
with the observer cold lets the controller act on an unconverged estimate. This wrapper starts at speed
(``simulate(initial_state=drive.init(speed_m, theta_e))``) with the controller on the sensor for
``warmup_s`` and then hands over in one period. The hand-over time depends on time only, never on a
traced value, so the whole run is differentiable w.r.t. every observer gain; the jump at the hand-over
is the observer's (converged) angle error, a fraction of a degree.

The observer sees the same samples whether or not it is in charge; the estimate's other fields
(back-EMF, ...) are always the observer's. The path of the wrapped observer is ``estimator.observer``,
as in :class:`.startup.StartupEstimator`, so gains tuned on a warm-up drive (``estimator.observer.k``)
apply unchanged to a drive with the I/f start.
"""

import equinox as eqx
import jax.numpy as jnp

from .._types import Array
from ..machines.motor import as_float
from ..signals import Sample
from ..validation import check_positive
from .base import AbstractEstimator


class SensoredWarmupState(eqx.Module):
    observer: object  # the wrapped observer's state
    t: Array  # s, time since the start (start of the current period)


class SensoredWarmup(AbstractEstimator):
    """Position sensor for ``warmup_s``, then ``observer`` (see the module docstring).

    **Arguments:**

    - `observer`: the observer that takes over (any :class:`AbstractEstimator`).
    - `warmup_s`: time on the sensor, s (the observer is in charge from the first period starting at or
      after it).
    """

    observer: AbstractEstimator
    warmup_s: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("SensoredWarmup.warmup_s (time on the sensor)", self.warmup_s, "s")

    def check_period(self, Ts: float) -> None:
        self.observer.check_period(Ts)

    def init(self, sample: Sample) -> SensoredWarmupState:
        return SensoredWarmupState(self.observer.init(sample), jnp.zeros((), sample.i_ab.dtype))

    def step(self, state: SensoredWarmupState, sample: Sample, Ts: float):
        obs_state, obs = self.observer.step(state.observer, sample, Ts)
        # a comparison of time with a constant: the same branch for every value of the observer's gains
        on_observer = state.t >= self.warmup_s - 0.5 * Ts
        estimate = eqx.tree_at(
            lambda e: (e.theta_e, e.omega_m),
            obs,
            (
                jnp.where(on_observer, obs.theta_e, sample.sensor_theta_e),
                jnp.where(on_observer, obs.omega_m, sample.sensor_omega_m),
            ),
        )
        return SensoredWarmupState(obs_state, state.t + Ts), estimate
