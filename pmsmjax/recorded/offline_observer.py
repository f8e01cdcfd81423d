"""Run an estimator offline on recorded stator-frame signals (``pmsmjax observe``, tests, tuning).

The estimator sees exactly what it sees inside [`pmsmjax.drive.Drive`][pmsmjax.drive.Drive]: at row ``k`` a
[`Sample`][pmsmjax.signals.Sample] with the current sampled at ``t_k`` and the voltage held over
``[t_{k-1}, t_k)`` (row ``k - 1`` of the log, whose voltage is "applied from row k to row k+1"); the
voltage before the first row is unknown and taken as zero. The sensor fields are zero: an observer never
reads them. Running an observer on the sensored drive's own trace is therefore the drive's "shadow
mode": the observer runs alongside, and its estimate changes nothing.

Pure JAX: [`observe`][pmsmjax.recorded.offline_observer.observe] composes with ``jax.vmap`` (batches of logs
or of observers) and ``jax.grad`` (observer tuning).
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax._types import Array

# The estimate's figures of merit are defined in pmsmjax.analysis.observer_errors; the angle errors are
# re-exported here beside the runner that produces the estimates they score.
from pmsmjax.analysis.observer_errors import angle_error, angle_error_modulo_pi
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.frames.three_phase import alpha_beta_to_abc, wrap_angle
from pmsmjax.signals import Sample

__all__ = ["ObserverOutput", "observe", "angle_error", "angle_error_modulo_pi"]


class ObserverOutput(eqx.Module):
    """One row per log row: `theta_e` ``(N,)`` electrical rad in [-pi, pi), `omega_m` ``(N,)`` mechanical
    rad/s, `back_emf_ab` ``(N, 2)`` V (zeros for estimators without one)."""

    theta_e: Array
    omega_m: Array
    back_emf_ab: Array


@eqx.filter_jit
def observe(estimator: AbstractEstimator, u_ab: Array, i_ab: Array, Ts: float, u_dc=0.0) -> ObserverOutput:
    """Run ``estimator`` over a log. ``u_ab``: ``(N, 2)`` V held from row k to k+1; ``i_ab``: ``(N, 2)`` A
    sampled at row k; ``Ts``: the row spacing, s (static); ``u_dc``: DC-link voltage, V (unused by the
    chapter 5 observers)."""
    u_ab, i_ab = jnp.asarray(u_ab), jnp.asarray(i_ab)
    u_last = jnp.concatenate([jnp.zeros_like(u_ab[:1]), u_ab[:-1]], axis=0)
    zero = jnp.zeros((), i_ab.dtype)
    u_dc = jnp.asarray(u_dc, i_ab.dtype)

    def sample(i, u):
        return Sample(alpha_beta_to_abc(i), i, u_dc, u, zero, zero)

    state = estimator.init(sample(i_ab[0], u_last[0]))

    def body(s, xs):
        s, est = estimator.step(s, sample(*xs), Ts)
        emf = jnp.zeros(2, i_ab.dtype) if est.back_emf_ab is None else est.back_emf_ab
        return s, (wrap_angle(est.theta_e), est.omega_m, emf)

    _, (theta, omega, emf) = jax.lax.scan(body, state, (i_ab, u_last))
    return ObserverOutput(theta, omega, emf)
