"""Phase-locked loop: angle and speed from a phase error (the book, ch. 5: "a PLL on
``-e_a cos th^ - e_b sin th^`` (PI -> w^, integrate -> th^)").

Sampled form (ODrive, ``Firmware/MotorControl/sensorless_estimator.cpp``): each period

    th-  = th + Ts w            (prediction to the sampling instant)
    e    = phase error at th-   (the caller's phase detector, ~ sin(th_true - th-))
    th   = th- + Ts kp e,       w = w + Ts ki e.

Design rule (ODrive; Harnefors & Nee, "A general algorithm for speed and position estimation of AC
motors", IEEE TIE 47(1), 2000, doi:10.1109/41.824128): for a bandwidth ``bw`` (rad/s) the continuous
loop ``s^2 + kp s + ki`` gets a double pole at ``-bw``: ``kp = 2 bw``, ``ki = bw^2``. The loop tracks a
constant speed with zero angle error (type 2). The sampled loop's characteristic polynomial is
``z^2 - (2 - a - b) z + (1 - a)`` with ``a = Ts kp``, ``b = Ts^2 ki``
([`pmsmjax.estimators.stability.tracking_loop_matrix`][pmsmjax.estimators.stability.tracking_loop_matrix]):
stable iff ``0 < a < 2``, ``0 < b < 4 - 2a`` (ODrive refuses the stricter ``a >= 1``). A lag compensation
computed from the PLL's own speed belongs on its output, not on the angle it locks to: there it would feed the
speed back into the phase error and shrink the stable gains several-fold.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.stability import check_loop, concrete_values, tracking_loop_matrix
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import as_float
from pmsmjax.signals import Estimate
from pmsmjax.spec.validation import check_positive


class PLLState(eqx.Module):
    """A PLL's angle and speed."""

    theta: Array  # rad, electrical angle (wrapped)
    omega: Array  # rad/s, electrical speed


class PLL(eqx.Module):
    """Type-2 tracking loop (see the module docstring).

    **Arguments:**

    - `kp`: proportional gain, 1/s (rad/s of correction per rad of phase error).
    - `ki`: integral gain, 1/s^2.
    """

    kp: Array = eqx.field(converter=as_float)
    ki: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("PLL.kp", self.kp, "1/s", "give kp = 2 bw for a bandwidth bw in rad/s")
        check_positive("PLL.ki", self.ki, "1/s^2", "give ki = bw^2 for a bandwidth bw in rad/s")

    def check_period(self, Ts: float, owner: str = "PLL") -> None:
        """Refuse gains whose sampled loop is unstable at period ``Ts`` (s)."""
        values = concrete_values(self.kp, self.ki)
        if values is None:
            return
        kp, ki = values
        check_loop(
            f"{owner} (kp = {kp.max():g} 1/s, ki = {ki.max():g} 1/s^2)",
            lambda p, i: tracking_loop_matrix(Ts * p, Ts * Ts * i),
            [kp, ki],
            f"lower the gains: kp Ts must stay below 2 and ki Ts^2 below 4 - 2 kp Ts; the rule kp = 2 bw, "
            f"ki = bw^2 is stable for bw < {(8**0.5 - 2) / Ts:.4g} rad/s (ODrive keeps kp Ts < 1)",
        )

    @staticmethod
    def init(theta, omega) -> PLLState:
        return PLLState(jnp.asarray(theta), jnp.asarray(omega))

    @staticmethod
    def predict(state: PLLState, Ts: float) -> Array:
        """The angle at the next sampling instant, rad (not wrapped: the caller's detector uses sin/cos)."""
        return state.theta + Ts * state.omega

    def correct(self, state: PLLState, theta_pred, error, Ts: float) -> PLLState:
        """The state after the phase error ``error`` (rad, ~ sin of the angle error) measured at
        ``theta_pred``."""
        return PLLState(wrap_angle(theta_pred + Ts * self.kp * error), state.omega + Ts * self.ki * error)


def pull_pll(pll: PLLState, pole_pairs, estimate: Estimate, theta_e, omega_m, strength) -> PLLState:
    """``pll`` moved so that the estimate read from it (`estimate`) goes ``strength`` (in [0, 1]) of the way
    to ``theta_e`` (rad) and ``omega_m`` (mechanical rad/s; ``pole_pairs`` turns it electrical): the
    [`pull`][pmsmjax.estimators.base.AbstractEstimator.pull] of the estimators whose angle and speed are a
    PLL's (the HF-injection estimators).

    Shifted by the estimate's distance to the target, not set to it: the rotating injection's output is
    its PLL angle plus half its filters' lag of the ``2 th`` image (``~ 2 w_e / B``: 13 electrical degrees
    at 335 r/min on the book drive). Setting the PLL to the target left the output off by that lag, and
    inside the hybrid's crossover band, where the blend feeds back into both estimators, the two pulls
    settled on an estimate off by up to twice it; that lost the hand-down under load (README.md)."""
    theta = wrap_angle(pll.theta + strength * wrap_angle(theta_e - estimate.theta_e))
    omega = pll.omega + strength * pole_pairs * (omega_m - estimate.omega_m)
    return PLLState(theta, omega)


class AbstractPLLEstimator(AbstractEstimator):
    """An estimator whose angle and speed are a PLL's: its state has a ``pll`` field
    ([`PLLState`][pmsmjax.estimators.pll.PLLState]); the HF-injection estimators."""

    pole_pairs: eqx.AbstractVar[int]

    def pull(self, state, estimate: Estimate, theta_e, omega_m, strength):
        """The PLL moved by the estimate's distance to the target
        ([`pull_pll`][pmsmjax.estimators.pll.pull_pll])."""
        pll = pull_pll(state.pll, self.pole_pairs, estimate, theta_e, omega_m, strength)
        return dataclasses.replace(state, pll=pll)


def pll_design(bandwidth_rad_s=300.0) -> PLL:
    """The PLL with a double pole at ``-bandwidth`` (rad/s): ``kp = 2 bw``, ``ki = bw^2``."""
    check_positive("PLL bandwidth", bandwidth_rad_s, "rad/s")
    bw = as_float(bandwidth_rad_s)
    return PLL(2.0 * bw, bw * bw)
