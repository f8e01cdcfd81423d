"""Discrete PI controller with output limit and back-calculation anti-windup.

Forward-Euler integral, evaluated once per controller period ``Ts``::

    v = kp e + x + ff          (unsaturated output)
    u = sat(v)                 (limited output)
    x <- x + Ts ki e + (u - v) (the integral absorbs what the limiter cut off)

The back-calculation term keeps ``kp e + x`` at the limit while saturated, so the integral never winds
up and the loop leaves saturation as soon as the error changes sign. It is the exact (non-smoothed)
limiter: its gradient is zero beyond the limit, which tuning objectives penalise separately.
"""

import jax.numpy as jnp

from .._types import Array


def pi_update(kp, ki, integral, error, Ts, limited_output, feedforward=0.0) -> tuple[Array, Array]:
    """One PI update.

    **Arguments:**

    - `kp`, `ki`: proportional gain and integral gain (per second), broadcast with `error`.
    - `integral`: integral state (output units), same shape as `error`.
    - `error`: reference minus measurement.
    - `Ts`: controller period, s.
    - `limited_output`: function ``v -> u`` applying the output limit (scalar clip, circular limit, ...).
    - `feedforward`: added to the output before limiting (not integrated).

    **Returns:** ``(integral_next, u)``.
    """
    v = kp * error + integral + feedforward
    u = limited_output(v)
    return integral + Ts * ki * error + (u - v), u


def clip_symmetric(limit):
    """Limiter ``v -> clip(v, -limit, limit)``."""
    return lambda v: jnp.clip(v, -limit, limit)


def clip_magnitude(limit):
    """Limiter scaling a vector ``v`` to magnitude <= ``limit``, keeping its direction.

    The norm is guarded with the double-where pattern so the gradient stays finite at ``v = 0``.
    """

    def limiter(v):
        sq = jnp.sum(v * v, axis=-1, keepdims=True)
        positive = sq > 0
        norm = jnp.sqrt(jnp.where(positive, sq, 1.0))
        scale = jnp.where(positive & (norm > limit), limit / norm, 1.0)
        return v * scale

    return limiter
