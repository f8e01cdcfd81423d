"""Shaft position sensors as estimators: the ideal sensor and an incremental encoder.

[`ExactSensor`][pmsmjax.estimators.position_sensors.ExactSensor] passes the true electrical angle and speed
through (what chapters 1-3 assume).

[`Encoder`][pmsmjax.estimators.position_sensors.Encoder] models an incremental quadrature encoder with
``lines`` lines per revolution (``4 lines`` counts per mechanical revolution, so an electrical-angle quantum
of ``2 pi p_n / (4 lines)``), read ``delay_s`` late (a transport delay: the count latched ``delay_s`` before
the sampling instant, taken as ``theta_e - omega_e delay_s``), mounted ``offset_rad`` off the rotor's d
axis (the count reads ``theta_e + offset_rad``: firmware calibrates the zero by locking the rotor with
a d-axis current and resetting the count there, TI application report SPRABZ0 on sensored FOC of
PMSMs and ST's UM1052 FOC SDK manual on encoder alignment; what that leaves is this offset), and a speed
from a type-2 tracking loop on the counted angle (ODrive's encoder estimator,
``Firmware/MotorControl/encoder.cpp``):
``e = wrap(theta_count - theta^)``, ``theta^ += Ts (omega^ + kp e)``, ``omega^ += Ts ki e`` with
``kp = 2 bw``, ``ki = bw^2`` (both poles at ``-bw``). Differencing the count over one period instead would
give a speed quantum of ``2 pi / (4 lines Ts)``: 6.3 rad/s (60 r/min) for 2500 lines at 10 kHz. The controller
gets the counted angle (advanced by the tracked speed times the delay, as firmware does) and the tracked
speed.
"""

import math

import equinox as eqx
import jax.numpy as jnp

from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_nonnegative, check_positive, is_concrete


def _optional_float(x):
    return None if x is None else as_float(x)


class ExactSensor(AbstractEstimator):
    """The plant's own angle and speed, exactly, at the sampling instant."""

    def init(self, sample: Sample):
        return None

    def step(self, state, sample: Sample, Ts: float):
        return state, Estimate(sample.sensor_theta_e, sample.sensor_omega_m)


class EncoderState(eqx.Module):
    theta_e: object  # rad, tracking-loop angle (continuous, wrapped)
    omega_e: object  # rad/s, tracking-loop electrical speed


class Encoder(AbstractEstimator):
    """Incremental encoder (see the module docstring).

    **Arguments:**

    - `lines`: lines per mechanical revolution (static int; 4 x lines counts).
    - `pole_pairs`: the machine's pole pairs (static int), to turn counts into electrical angle.
    - `delay_s`: latency of the count at the sampling instant, s (>= 0).
    - `speed_bandwidth`: bandwidth of the speed tracking loop, rad/s (both poles there).
    - `offset_rad`: mounting offset of the count's zero, electrical rad (the count reads the true angle
      plus it); None: none (nothing added to the program).
    """

    lines: int = eqx.field(static=True)
    pole_pairs: int = eqx.field(static=True)
    delay_s: object = eqx.field(converter=as_float, default=0.0)
    speed_bandwidth: object = eqx.field(converter=as_float, default=1000.0)
    offset_rad: object = eqx.field(converter=_optional_float, default=None)

    def __check_init__(self):
        for name, value in (("Encoder.lines", self.lines), ("Encoder.pole_pairs", self.pole_pairs)):
            if not isinstance(value, int) or value < 1:
                raise ParameterError(f"{name} must be a positive int, got {value!r}.")
        check_nonnegative("Encoder.delay_s", self.delay_s, "s")
        check_positive("Encoder.speed_bandwidth", self.speed_bandwidth, "rad/s")

    @property
    def quantum_rad(self) -> float:
        """Electrical angle of one count, rad."""
        return 2.0 * math.pi * self.pole_pairs / (4 * self.lines)

    def check_period(self, Ts: float) -> None:
        """Refuse a tracking loop too fast for the period (forward Euler needs ``Ts kp < 1``)."""
        if is_concrete(self.speed_bandwidth):
            kp_ts = 2.0 * float(jnp.max(self.speed_bandwidth)) * Ts
            if kp_ts >= 1.0:
                raise ParameterError(
                    f"Encoder.speed_bandwidth = {float(jnp.max(self.speed_bandwidth)):g} rad/s is too fast "
                    f"for Ts = {Ts:g} s (2 bw Ts = {kp_ts:.2f} >= 1): choose bw < {0.5 / Ts:g} rad/s."
                )

    def count(self, sample: Sample):
        """The electrical angle the counter holds at the sampling instant, rad."""
        omega_e = self.pole_pairs * sample.sensor_omega_m
        latched = sample.sensor_theta_e - omega_e * self.delay_s
        if self.offset_rad is not None:
            latched = latched + self.offset_rad
        q = self.quantum_rad
        return wrap_angle(jnp.floor(latched / q) * q)

    def init(self, sample: Sample):
        theta = self.count(sample)
        return EncoderState(theta, jnp.zeros_like(theta))

    def step(self, state: EncoderState, sample: Sample, Ts: float):
        bw = self.speed_bandwidth
        counted = self.count(sample)
        error = wrap_angle(counted - state.theta_e)
        omega_e = state.omega_e + Ts * bw * bw * error
        theta = wrap_angle(state.theta_e + Ts * (state.omega_e + 2.0 * bw * error))
        # The count is delay_s old: advance it by the tracked speed, as firmware does.
        estimate = Estimate(wrap_angle(counted + omega_e * self.delay_s), omega_e / self.pole_pairs)
        return EncoderState(theta, omega_e), estimate
