"""Sensorless over the whole speed range: HF injection at low speed, a chapter 5 observer above a crossover
band (the book, ch. 6 with chapter 5; the weighted hand-over of e.g. Silva, Asher, Sumner, "Hybrid
rotor position observer for wide speed-range sensorless PM motor drives including zero speed", IEEE
Trans. Ind. Electron. 53(2), 2006, doi:10.1109/TIE.2006.870875).

Both estimators run every period on the same sample. With ``|w|`` the hybrid's own speed estimate (last
period's, through a first-order filter of bandwidth ``speed_filter`` so that noise does not chatter the
hand-over), the observer's weight is

    ``w = s((|w| - w_low) / (w_high - w_low))``,   ``s(x) = 3x^2 - 2x^3`` on [0, 1] (smoothstep: C^1),

0 below ``w_low`` (injection alone), 1 above ``w_high`` (observer alone). The angle is blended along the
shorter arc, ``th = th_inj + w wrap(th_obs - th_inj)`` (no jump of 2 pi), the speed linearly. The injection
voltage is scaled by ``a = clip((w_off - |w|) / (w_off - w_high), 0, 1)``: full up to ``w_high``, faded
out at ``w_off`` (the carrier costs losses, noise and voltage at speed, where it is not needed).

Polarity. The injection knows the d axis modulo pi. From standstill the polarity is found by
[`polarity.PolarityDetector`][pmsmjax.estimators.polarity.PolarityDetector] wrapped around the injection
estimator (pass it as ``injection``). Back from high speed (e.g. a reversal through zero), the injection
estimator re-locks to either pole while the carrier fades in; while the observer is trusted (``w >= 1/2``) the
hybrid therefore keeps a correction ``c`` in {0, pi} that puts the injection's angle on the observer's side:
``c = pi`` iff ``|wrap(th_obs - th_inj)| > pi/2``, held below ``w = 1/2``. This is a comparator (exact; its
derivative is zero almost everywhere): it only selects one of two branches of the same estimate.

Hand-over by current. On a saturated machine the injection loses the d axis beyond a load
([`injection_region`][pmsmjax.estimators.injection_region]: the q path saturates, the saliency fades and
turns), whatever the speed. With ``handover_current`` set (``I_1``, A, and ``I_0`` where it starts) the
observer's weight is the larger of the speed one and

    ``w_i = s((|i| - I_0) / (I_1 - I_0))``,

``|i|`` the carrier-free current's magnitude (frame-free: an angle going wrong cannot hide the current that
makes it go wrong) through a first-order filter of bandwidth ``current_filter``. The current limit is read
as a magnitude because along the MTPA locus ``|i|`` and ``|i_q|`` rise together; at speed the speed weight
is 1 anyway. [`with_current_handover`][pmsmjax.estimators.hybrid.with_current_handover] sets ``I_1`` (the
current at the end of a map's injection region) and ``I_0`` = 80 % of it. Below the speed band the observer
then runs on its own at low speed, where a back-EMF observer sees little: at standstill under a load
beyond the region the EKF holds the angle worse than the fading injection (docs, chapter 6, on
saturated-ipm), so the drives built on a map file leave it off.

The band ``(w_low, w_high, w_off)`` and the filter are parameters (tunable; differentiable: the weight
and the fade are smooth in them). Defaults ([`hybrid_design`][pmsmjax.estimators.hybrid.hybrid_design]): 5 %
to 15 % of the book drive's 1000 r/min (50 to 150 r/min), the carrier gone at 25 %; measured on the book
scenario and a -1000 -> 1000 r/min reversal (benchmarks/hybrid_table.py): 30/100/200 and 80/200/300 r/min hold
as well (peak errors 6.4 and 10.5 degrees after the 60 ms start-up, against 7.9 for the default; README.md).

Slaving. A fundamental-model observer sees no back-EMF at standstill and runs wherever its equations take
it; left alone it would have to converge while the drive accelerates through the band (a few ms at the
book drive's current limit). So below the band the hybrid pulls the observer's angle and speed to its own
estimate: after each step the observer's angle and speed states move so that its estimate goes
``(1 - w)`` of its difference to the hybrid's (the observer's
[`pull`][pmsmjax.estimators.base.AbstractEstimator.pull]: fully slaved at ``w = 0``, free at ``w = 1``).
[`smo.SlidingModeObserver`][pmsmjax.estimators.smo.SlidingModeObserver] with a PLL (the PLL tracks the
back-EMF angle: rotor angle, plus pi below zero speed) and [`ekf.EKF`][pmsmjax.estimators.ekf.EKF]
(``x = [i_a, i_b, w_e, th_e]``) implement it; other observers run free. Likewise above the band the injection
estimator's PLL is pulled so that its estimate goes ``w`` of the way to the hybrid's (less the polarity
correction; [`pll.pull_pll`][pmsmjax.estimators.pll.pull_pll], through a
[`polarity.PolarityDetector`][pmsmjax.estimators.polarity.PolarityDetector]), so that when the carrier fades
back in (a reversal) it is already locked on the right pole at the right speed instead of re-acquiring during
the deceleration. Both pulls shift the states by the *estimate's* distance to the target: an estimator's
output can be its state plus a compensation (the rotating injection adds half its filters' lag to its PLL
angle, 13 degrees at 335 r/min), and setting the state to the target instead biased the blend inside the band
(README.md).

Start-up fields (``startup_weight``, ``startup_i_dq``) and the carrier-free current
(``i_ab_fundamental``) come from the injection estimate (the polarity pulses, the carrier filter).
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.catalogue import INJECTION_OBSERVERS, OBSERVERS, build
from pmsmjax.estimators.polarity import polarity_detector
from pmsmjax.estimators.stability import concrete_values
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Sample
from pmsmjax.spec.validation import ParameterError, check_positive
from pmsmjax.units import rpm_to_rad_s


class HybridState(eqx.Module):
    injection: object  # the injection estimator's state
    observer: object  # the observer's state
    speed: Array  # rad/s mechanical, filtered |speed| that schedules the hand-over
    correction: Array  # rad, 0 or pi added to the injection's angle (polarity from the observer)
    # A, filtered fundamental current magnitude that schedules the hand-over by current
    current: Array = eqx.field(default_factory=lambda: jnp.zeros(()))


def smoothstep(x):
    """``3x^2 - 2x^3`` on [0, 1], 0 below, 1 above: C^1, monotone."""
    x = jnp.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


class HybridEstimator(AbstractEstimator):
    """Injection at low speed, an observer above a crossover band (see the module docstring).

    **Arguments:**

    - `injection`: the low-speed estimator (HF injection, optionally inside a polarity detector).
    - `observer`: the high-speed estimator (a chapter 5 observer).
    - `low_speed`: ``w_low``, mechanical rad/s: below it the injection alone.
    - `high_speed`: ``w_high``, mechanical rad/s: above it the observer alone.
    - `injection_off_speed`: ``w_off``, mechanical rad/s: the carrier is faded out from ``w_high`` to here.
    - `speed_filter`: bandwidth of the scheduling speed's first-order filter, rad/s.
    - `handover_current`: ``(I_0, I_1)``, A: the observer's weight rises from 0 at current magnitude ``I_0``
      to 1 at ``I_1`` whatever the speed (module docstring); None: by speed alone.
    - `current_filter`: bandwidth of the scheduling current's first-order filter, rad/s.
    """

    injection: AbstractEstimator
    observer: AbstractEstimator
    low_speed: Array = eqx.field(converter=as_float)
    high_speed: Array = eqx.field(converter=as_float)
    injection_off_speed: Array = eqx.field(converter=as_float)
    speed_filter: Array = eqx.field(converter=as_float)
    handover_current: tuple[Array, Array] | None = None
    current_filter: Array = eqx.field(converter=as_float, default=2000.0)

    def __check_init__(self):
        check_positive("HybridEstimator.low_speed (w_low)", self.low_speed, "rad/s (mechanical)")
        check_positive("HybridEstimator.speed_filter", self.speed_filter, "rad/s")
        values = concrete_values(self.low_speed, self.high_speed, self.injection_off_speed)
        if values is not None:
            lo, hi, off = values
            if not (lo < hi).all() or not (hi < off).all():
                raise ParameterError(
                    f"HybridEstimator needs low_speed < high_speed < injection_off_speed (mechanical rad/s), "
                    f"got {lo}, {hi}, {off}: the band needs a width and the carrier fade must end above it."
                )
        check_positive("HybridEstimator.current_filter", self.current_filter, "rad/s")
        if self.handover_current is not None:
            values = concrete_values(*self.handover_current)
            if values is not None and not (0 <= values[0] < values[1]).all():
                raise ParameterError(
                    f"HybridEstimator.handover_current (I_0, I_1) needs 0 <= I_0 < I_1 (A), got "
                    f"{values[0]}, {values[1]}: the hand-over by current needs a width."
                )

    @property
    def injects_voltage(self) -> bool:
        return True

    def check_period(self, Ts: float) -> None:
        self.injection.check_period(Ts)
        self.observer.check_period(Ts)

    def init(self, sample: Sample) -> HybridState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        return HybridState(self.injection.init(sample), self.observer.init(sample), zero, zero, zero)

    def observer_weight(self, speed) -> Array:
        """Observer weight in [0, 1] at scheduling speed ``speed`` (mechanical rad/s, >= 0)."""
        return smoothstep((speed - self.low_speed) / (self.high_speed - self.low_speed))

    def current_weight(self, current) -> Array:
        """Observer weight in [0, 1] at scheduling current magnitude ``current`` (A, >= 0); 0 without a
        hand-over by current."""
        if self.handover_current is None:
            return jnp.zeros_like(current)
        start, end = self.handover_current
        return smoothstep((current - start) / (end - start))

    def injection_scale(self, speed) -> Array:
        """Carrier amplitude factor in [0, 1] at scheduling speed ``speed`` (mechanical rad/s, >= 0)."""
        return jnp.clip(
            (self.injection_off_speed - speed) / (self.injection_off_speed - self.high_speed), 0, 1
        )

    def step(self, state: HybridState, sample: Sample, Ts: float):
        inj_state, inj = self.injection.step(state.injection, sample, Ts)
        obs_state, obs = self.observer.step(state.observer, sample, Ts)
        w = jnp.maximum(self.observer_weight(state.speed), self.current_weight(state.current))
        # polarity of the injection's angle from the observer while the observer is trusted
        flipped = jnp.abs(wrap_angle(obs.theta_e - inj.theta_e)) > 0.5 * jnp.pi
        correction = jnp.where(w >= 0.5, jnp.where(flipped, jnp.pi, 0.0), state.correction)
        theta_inj = wrap_angle(inj.theta_e + correction)
        theta = wrap_angle(theta_inj + w * wrap_angle(obs.theta_e - theta_inj))
        omega = (1.0 - w) * inj.omega_m + w * obs.omega_m
        # exact discretisation of the first-order filter of |omega|
        g = 1.0 - jnp.exp(-self.speed_filter * Ts)
        speed = state.speed + g * (jnp.abs(omega) - state.speed)
        current = state.current
        if self.handover_current is not None:
            i_ab = sample.i_ab if inj.i_ab_fundamental is None else inj.i_ab_fundamental
            # |i| smoothed at 1 mA so that its derivative exists at zero current (gradients through a start)
            magnitude = jnp.sqrt(jnp.sum(i_ab * i_ab) + 1e-6)
            current = current + (1.0 - jnp.exp(-self.current_filter * Ts)) * (magnitude - current)
        u_inj = self.injection_scale(state.speed) * inj.u_injection_ab
        obs_state = self.observer.pull(obs_state, obs, theta, omega, 1.0 - w)
        inj_state = self.injection.pull(inj_state, inj, wrap_angle(theta - correction), omega, w)
        estimate = dataclasses.replace(inj, theta_e=theta, omega_m=omega, u_injection_ab=u_inj)
        return HybridState(inj_state, obs_state, speed, correction, current), estimate


#: Crossover band of [`hybrid_design`][pmsmjax.estimators.hybrid.hybrid_design], r/min: observer weight from 0
#: at ``low`` to 1 at ``high``, carrier faded out at ``off``.
HYBRID_BAND_RPM = dict(low=50.0, high=150.0, off=250.0)


def hybrid_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    injection: str = "hfi-rotating",
    observer: str = "ekf",
    low_rpm: float = HYBRID_BAND_RPM["low"],
    high_rpm: float = HYBRID_BAND_RPM["high"],
    off_rpm: float = HYBRID_BAND_RPM["off"],
    speed_filter: float = 200.0,
    polarity: bool = True,
    delay_periods: float = 1.5,
    injection_options: dict | None = None,
    observer_options: dict | None = None,
    polarity_options: dict | None = None,
    injection_motor: PMSMParameters | None = None,
) -> HybridEstimator:
    """The hybrid for ``motor`` at period ``Ts`` (s): injection ``injection`` (a name of
    [`catalogue.INJECTION_OBSERVERS`][pmsmjax.estimators.catalogue.INJECTION_OBSERVERS]), inside a
    [`polarity.PolarityDetector`][pmsmjax.estimators.polarity.PolarityDetector] if ``polarity``, and the
    observer ``observer`` (a name of [`catalogue.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]),
    crossover band in r/min, scheduling-speed filter in rad/s (200 rad/s: well below the injection's error
    filter, above the speed loop's 50 rad/s). ``delay_periods``: the drive's command delay for the injection's
    carrier phase (1.5 periods with a computational delay, 0.5 without). ``injection_motor``: the model the
    injection is designed on (default ``motor``; on a flux map the incremental inductances at no load,
    [`injection_model`][pmsmjax.estimators.hfi_cross_saturation.injection_model]).

    The default observer is the EKF: with the smo-pll the book scenario lost lock at every band tried
    (50-150, 100-200, 150-250 r/min; the SMO is not reliable below about 150 r/min and the injection lags
    by 20 degrees and more at the current limit's acceleration above that; README.md).
    Since the pulls move the estimates (README.md) the smo-pll with a 150/250/350 r/min
    band holds the book scenario (8 of 8 starts, 32 degrees peak) but still not the reversal."""
    low, high, off = (rpm_to_rad_s(x) for x in (low_rpm, high_rpm, off_rpm))
    inj_opts = {"delay_periods": delay_periods, **(injection_options or {})}
    inj_motor = motor if injection_motor is None else injection_motor
    inj = build(INJECTION_OBSERVERS, injection, inj_motor, Ts, "injection estimator", **inj_opts)
    if polarity:
        inj = polarity_detector(inj, motor.R, **(polarity_options or {}))
    obs = build(OBSERVERS, observer, motor, Ts, **(observer_options or {}))
    return HybridEstimator(inj, obs, low, high, off, speed_filter)


#: Where the hand-over by current starts, as a share of the current at which the observer takes over
#: ([`with_current_handover`][pmsmjax.estimators.hybrid.with_current_handover]).
HANDOVER_CURRENT_START = 0.8


def with_current_handover(
    hybrid: HybridEstimator, current_a: float, start_share: float = HANDOVER_CURRENT_START
) -> HybridEstimator:
    """``hybrid`` handing over to its observer by current as well (module docstring): the observer's weight
    rises from 0 at ``start_share * current_a`` to 1 at ``current_a`` (A, the current magnitude at the end of
    the injection region,
    [`InjectionRegion.max_current_a`][pmsmjax.estimators.injection_region.InjectionRegion])."""
    check_positive("hand-over current", current_a, "A")
    if not 0.0 <= start_share < 1.0:
        raise ParameterError(f"start_share must lie in [0, 1), got {start_share}.")
    end = as_float(current_a)
    return dataclasses.replace(hybrid, handover_current=(start_share * end, end))
