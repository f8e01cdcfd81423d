"""Magnet polarity detection at start-up by two current pulses along the estimated +-d axis (the book,
ch. 6, "magnet polarity needs a saturation effect"; the secant-inductance form of the pulse method of
Jeong, Lorenz, Jahns, Sul, IEEE Trans. Ind. Appl. 41(1), 2005, doi:10.1109/TIA.2004.840978, and
Noguchi, Yamada, Kondo, Takahashi, "Initial rotor position estimation method of sensorless PM synchronous
motor with no sensitivity to armature resistance", IEEE Trans. Ind. Electron. 45(1), 1998).

A saliency-based (HF injection) estimator locks onto the d axis modulo pi: its error signal goes with
``sin 2 dtheta``. With the d-axis iron biased by the magnet
([`pmsmjax.machines.saturation`][pmsmjax.machines.saturation]), current along +d saturates the iron and
current along -d does not, so the flux needed per ampere (the secant inductance ``L = dpsi_d / di_d``) is
smaller along the true +d axis. This wrapper, at standstill:

1. lets the wrapped estimator converge for ``settle_time`` with zero current;
2. holds ``i_d* = +I_p`` along the estimated d axis for ``pulse_time``, then zero for ``rest_time``; then
   ``-I_p`` and zero again (current controlled, through ``Estimate.startup_weight/startup_i_dq`` as the
   I/f start does, [`startup`][pmsmjax.estimators.startup]), so the pulses are equal whatever the inductance;
3. over each pulse window measures the flux change from the sampled voltage and current,
   ``dpsi = sum (u_d - R i_d) Ts`` (``u_d``: last period's applied voltage in the estimated frame;
   trapezoidal ``i_d``), and the current change ``di``; at standstill ``u_d - R i_d = dpsi_d/dt`` exactly,
   whatever the current controller does, so ``L = dpsi / di`` is the secant inductance of the flux map;
4. decides: if ``L(+) > L(-)`` the estimated +d is the magnet's -d: the angle is flipped by pi from then
   on; then the start-up weight ramps from 1 to 0 over ``release_time`` (the speed loop takes over).
   While the weight is above 0 the reported speed is the wrapped estimator's times ``1 - weight``: the
   rotor is held at standstill, and the pulse transients in an injection estimator's speed would otherwise
   wind up the speed loop (24 starts with rotating injection: up to 14 rad/s of wander before, 2.4 after).

The resistance enters both pulses alike (same current, same duration), so an error in ``R`` shifts both
inductances by about the same amount and does not change the decision. The wrapped estimator's injection
voltage passes through; a window lasting whole carrier periods sees the carrier ripple at the same phase
at both ends.

The decision is a comparator: exact by default (its derivative is zero almost everywhere, which is
right); ``decision="sigmoid"`` replaces the flip by ``pi sigmoid((L(+) - L(-)) / decision_scale)``, a
smooth surrogate for gradient studies.
"""

import dataclasses
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.frames.three_phase import park, wrap_angle
from pmsmjax.machines.motor import as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import check_choice, check_nonnegative, check_positive

Decision = Literal["exact", "sigmoid"]


class PolarityState(eqx.Module):
    observer: object  # the wrapped estimator's state
    t: Array  # s, time since start
    i_d_prev: Array  # A, last sample's current along the estimated d axis
    flux: Array  # (2,) Wb, flux change over the + and - pulse windows
    current: Array  # (2,) A, current change over the + and - pulse windows


class PolarityDetector(AbstractEstimator):
    """Two-pulse polarity detection around a modulo-pi estimator (see the module docstring).

    **Arguments:**

    - `observer`: the wrapped estimator (HF injection: angle known modulo pi).
    - `R`: stator resistance of the model, ohm (for ``u_d - R i_d``).
    - `pulse_current`: ``I_p``, A: the pulse amplitude; a few times the flux map's current scale gives
      the largest contrast, and it must stay inside the drive's current limit.
    - `settle_time`: s, zero current while the wrapped estimator converges.
    - `pulse_time`: s, each pulse (choose several current-loop time constants, whole carrier periods).
    - `rest_time`: s, zero current after each pulse.
    - `release_time`: s, ramp of the start-up weight from 1 to 0 after the decision.
    - `decision`: ``"exact"`` comparator or its ``"sigmoid"`` surrogate (static).
    - `decision_scale`: H, inductance difference for the sigmoid's unit slope (sigmoid only).
    """

    observer: AbstractEstimator
    R: Array = eqx.field(converter=as_float)
    pulse_current: Array = eqx.field(converter=as_float)
    settle_time: Array = eqx.field(converter=as_float)
    pulse_time: Array = eqx.field(converter=as_float)
    rest_time: Array = eqx.field(converter=as_float)
    release_time: Array = eqx.field(converter=as_float)
    decision: Decision = eqx.field(static=True, default="exact")
    decision_scale: Array = eqx.field(converter=as_float, default=1e-4)

    def __check_init__(self):
        check_nonnegative("PolarityDetector.R (model resistance)", self.R, "ohm")
        check_positive("PolarityDetector.pulse_current (I_p)", self.pulse_current, "A")
        check_nonnegative("PolarityDetector.settle_time", self.settle_time, "s")
        check_positive("PolarityDetector.pulse_time", self.pulse_time, "s")
        check_nonnegative("PolarityDetector.rest_time", self.rest_time, "s")
        check_positive("PolarityDetector.release_time", self.release_time, "s")
        check_positive("PolarityDetector.decision_scale", self.decision_scale, "H")
        check_choice("decision", self.decision, ("exact", "sigmoid"))

    @property
    def injects_voltage(self) -> bool:  # the wrapped estimator's carrier passes through
        return self.observer.injects_voltage

    def check_period(self, Ts: float) -> None:
        self.observer.check_period(Ts)

    @property
    def decision_time(self) -> Array:
        """s, end of the second rest: the polarity is known from here on."""
        return self.settle_time + 2.0 * (self.pulse_time + self.rest_time)

    def init(self, sample: Sample) -> PolarityState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        return PolarityState(
            self.observer.init(sample), zero, zero, jnp.zeros(2, zero.dtype), jnp.zeros(2, zero.dtype)
        )

    def secant_inductances(self, state: PolarityState) -> Array:
        """``(2,)`` measured secant d inductances ``[L(+), L(-)]`` along the estimated +d and -d, H."""
        di = state.current
        safe = jnp.where(jnp.abs(di) > 0, di, 1.0)
        return jnp.where(jnp.abs(di) > 0, state.flux / safe, 0.0)

    def flip(self, state: PolarityState, t) -> Array:
        """Angle correction at sample time ``t`` (s), rad: pi where the estimated +d is the magnet's -d
        (from the decision time on), else 0."""
        L = self.secant_inductances(state)
        if self.decision == "exact":
            wrong = (L[0] > L[1]).astype(L.dtype)
        else:
            wrong = jax.nn.sigmoid((L[0] - L[1]) / self.decision_scale)
        return jnp.where(t >= self.decision_time, jnp.pi * wrong, 0.0)

    def step(self, state: PolarityState, sample: Sample, Ts: float):
        obs_state, obs = self.observer.step(state.observer, sample, Ts)
        t = state.t
        theta_obs = obs.theta_e
        # measurement in the frame of the angle the pulses were commanded in (the wrapped estimate, unflipped)
        i_d = park(sample.i_ab, theta_obs)[0]
        u_d = park(sample.u_ab_last, theta_obs)[0]
        dflux = (u_d - self.R * 0.5 * (i_d + state.i_d_prev)) * Ts
        dcur = i_d - state.i_d_prev
        # the sample at time t closes the period [t - Ts, t]: it belongs to a window if that period does
        t_plus = self.settle_time
        t_minus = self.settle_time + self.pulse_time + self.rest_time
        in_plus = (t > t_plus) & (t <= t_plus + self.pulse_time + 0.5 * Ts)
        in_minus = (t > t_minus) & (t <= t_minus + self.pulse_time + 0.5 * Ts)
        gate = jnp.stack([in_plus, in_minus]).astype(dflux.dtype)
        flux = state.flux + gate * dflux
        current = state.current + gate * dcur

        # current pulses for the period starting now, in the wrapped estimate's frame
        p_on = (t >= t_plus) & (t < t_plus + self.pulse_time)
        m_on = (t >= t_minus) & (t < t_minus + self.pulse_time)
        i_d_ref = self.pulse_current * (p_on.astype(i_d.dtype) - m_on.astype(i_d.dtype))
        new_state = PolarityState(obs_state, t + Ts, i_d, flux, current)
        correction = self.flip(new_state, t)
        theta = wrap_angle(theta_obs + correction)
        # the pulses end before the decision, so they are in the unflipped frame the controller then uses
        i_dq_start = jnp.stack([i_d_ref, jnp.zeros_like(i_d_ref)])
        weight = jnp.clip(1.0 - (t - self.decision_time) / self.release_time, 0.0, 1.0)
        # the rotor is held at standstill while the start-up block is in charge: report zero speed then, so
        # that the wrapped estimator's pulse transients do not wind up the speed loop (as the I/f start
        # reports its ramp speed)
        omega = (1.0 - weight) * obs.omega_m
        estimate = dataclasses.replace(
            obs, theta_e=theta, omega_m=omega, startup_weight=weight, startup_i_dq=i_dq_start
        )
        return new_state, estimate

    def pull(self, state: PolarityState, estimate: Estimate, theta_e, omega_m, strength) -> PolarityState:
        """The wrapped estimator pulled (the flip is in both ``theta_e`` and ``estimate``, so it cancels)."""
        observer = self.observer.pull(state.observer, estimate, theta_e, omega_m, strength)
        return dataclasses.replace(state, observer=observer)


def polarity_detector(
    observer: AbstractEstimator,
    R,
    *,
    pulse_current: float = 8.0,
    settle_time: float = 0.02,
    pulse_time: float = 4e-3,
    rest_time: float = 4e-3,
    release_time: float = 0.01,
    decision: Decision = "exact",
) -> PolarityDetector:
    """[`PolarityDetector`][pmsmjax.estimators.polarity.PolarityDetector] with defaults for the book drive
    (current loop 1100 rad/s: a 4 ms pulse is 4.4 time constants; 8 A is the default flux map's current scale,
    inside the 15 A limit)."""
    return PolarityDetector(
        observer, R, pulse_current, settle_time, pulse_time, rest_time, release_time, decision=decision
    )
