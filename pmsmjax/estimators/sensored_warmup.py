"""Sensored warm-up: the drive runs on its position sensor for a fixed time while the observer converges in
the background, then on the observer (used by the observer tuning).

Why: to tune an observer by gradients the loss must be a smooth function of its gains. A start from
standstill with the I/f hand-over ([`startup`][pmsmjax.estimators.startup]) is continuous, but whether a
back-EMF observer locks after it depends on the scenario (measured: smo-pll and adaptive-smo lose the angle
when the I/f start is followed by 100 r/min or by a reversal), and a lost lock is a jump in the loss. Starting
the plant at speed with the observer cold lets the controller act on an unconverged estimate. This wrapper
starts at speed (``simulate(initial_state=drive.init(speed_m, theta_e))``) with the controller on the sensor
for ``warmup_s`` and then hands over in one period. The hand-over time depends on time only, never on a
traced value, so the whole run is differentiable w.r.t. every observer gain; the jump at the hand-over
is the observer's (converged) angle error, a fraction of a degree.

The observer sees the same samples whether or not it is in charge; the estimate's other fields
(back-EMF, ...) are always the observer's.

Measurement noise (``current_noise_a``, ``voltage_noise_v``, default 0): white Gaussian noise of these
standard deviations (per axis, A and V) on the current and the held voltage *the observer* sees (the
controller keeps the clean sample: the drive hands the estimator its own copy). Without it a closed-loop
tuning rewards observer gains that only work noise-free (measured: the smo tuned noise-free, linear-zone
pole -0.97, gave 20 degrees RMS on the 0.5 % noise logs where the design rule gives 0.5). The noise is a
fixed function of the period index and of the initial rotor angle (so each scenario of a batch gets
its own stream), never of a gain: the loss stays a smooth, deterministic function of the gains.

An injecting estimator (chapter 6) keeps injecting through the wrapper (``injects_voltage`` is the
wrapped one's), and its carrier-free current for the controller is taken from the clean sample.

The path of the wrapped observer is ``estimator.observer``, as in
[`startup.StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator], so gains tuned on a warm-up drive
(``estimator.observer.k``) apply unchanged to a drive with the I/f start.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.machines.motor import as_float
from pmsmjax.signals import Sample
from pmsmjax.spec.validation import ParameterError, check_positive


class SensoredWarmupState(eqx.Module):
    observer: object  # the wrapped observer's state
    t: Array  # s, time since the start (start of the current period)
    key: Array  # PRNG key of the measurement noise (raw uint32 key data)


class SensoredWarmup(AbstractEstimator):
    """Position sensor for ``warmup_s``, then ``observer`` (see the module docstring).

    **Arguments:**

    - `observer`: the observer that takes over (any
      [`AbstractEstimator`][pmsmjax.estimators.base.AbstractEstimator]).
    - `warmup_s`: time on the sensor, s (the observer is in charge from the first period starting at or
      after it).
    - `current_noise_a`, `voltage_noise_v`: standard deviation of the noise on the observer's current (A)
      and held voltage (V) samples, per axis (0: none).
    - `seed`: seed of the noise (static).
    """

    observer: AbstractEstimator
    warmup_s: Array = eqx.field(converter=as_float)
    current_noise_a: Array = eqx.field(converter=as_float, default=0.0)
    voltage_noise_v: Array = eqx.field(converter=as_float, default=0.0)
    seed: int = eqx.field(static=True, default=0)

    def __check_init__(self):
        check_positive("SensoredWarmup.warmup_s (time on the sensor)", self.warmup_s, "s")
        for name, value, unit in (
            ("current_noise_a", self.current_noise_a, "A"),
            ("voltage_noise_v", self.voltage_noise_v, "V"),
        ):
            if jnp.any(jnp.asarray(value) < 0):
                raise ParameterError(f"SensoredWarmup.{name} must be >= 0 {unit} (0: no noise), got {value}.")

    @property
    def injects_voltage(self) -> bool:  # the wrapped estimator's carrier (HF injection) passes through
        return self.observer.injects_voltage

    def check_period(self, Ts: float) -> None:
        self.observer.check_period(Ts)

    def init(self, sample: Sample) -> SensoredWarmupState:
        # the initial angle's bits pick the stream: scenarios started at other angles get other noise
        angle_bits = jax.lax.bitcast_convert_type(jnp.asarray(sample.sensor_theta_e, jnp.float32), jnp.uint32)
        key = jax.random.key_data(jax.random.fold_in(jax.random.PRNGKey(self.seed), angle_bits))
        return SensoredWarmupState(self.observer.init(sample), jnp.zeros((), sample.i_ab.dtype), key)

    def step(self, state: SensoredWarmupState, sample: Sample, Ts: float):
        key, k_i, k_u = jax.random.split(jax.random.wrap_key_data(state.key), 3)
        dtype = sample.i_ab.dtype
        noisy = dataclasses.replace(
            sample,
            i_ab=sample.i_ab + self.current_noise_a * jax.random.normal(k_i, (2,), dtype),
            u_ab_last=sample.u_ab_last + self.voltage_noise_v * jax.random.normal(k_u, (2,), dtype),
        )
        obs_state, obs = self.observer.step(state.observer, noisy, Ts)
        # a comparison of time with a constant: the same branch for every value of the observer's gains
        on_observer = state.t >= self.warmup_s - 0.5 * Ts
        estimate = dataclasses.replace(
            obs,
            theta_e=jnp.where(on_observer, obs.theta_e, sample.sensor_theta_e),
            omega_m=jnp.where(on_observer, obs.omega_m, sample.sensor_omega_m),
        )
        if obs.i_ab_fundamental is not None:
            # the carrier-free current for the controller (HF injection): from the clean sample, as the
            # controller keeps the clean sample (the observer filtered the noisy one)
            fundamental = obs.i_ab_fundamental - (noisy.i_ab - sample.i_ab)
            estimate = dataclasses.replace(estimate, i_ab_fundamental=fundamental)
        return SensoredWarmupState(obs_state, state.t + Ts, jax.random.key_data(key)), estimate
