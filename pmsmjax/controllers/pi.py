"""Discrete PI controller with output limit and back-calculation anti-windup.

Forward-Euler integral, evaluated once per controller period ``Ts``::

    v = kp e + x + ff               (unsaturated output)
    u = sat(v)                      (limited output)
    x <- x + Ts ki e + g (u - v)    (the integral absorbs the fraction g of what the limiter cut off)

``g`` is the tracking gain per period, ``Ts/T_t`` for a tracking time constant ``T_t`` (Astrom and
Hagglund, *Advanced PID Control*, 2006, sec. 3.5). When the output is not limited ``u = v`` and the term
vanishes, so ``g`` never changes the small-signal (linear) design.

- ``g = 1`` (the default, used by the current loop): the integral is reset each period so that
  ``kp e + x + ff`` sits exactly on the limit. The loop leaves saturation as soon as the unsaturated
  output moves back inside the limit by one period's change of ``kp e + ff``.
- ``g = Ts ki/kp`` ([`realisable_reference_tracking`][pmsmjax.controllers.pi.realisable_reference_tracking],
  used by the speed loop): ``T_t = kp/ki``. Then ``x <- x + Ts (ki/kp)(u - x - ff)``: the integral is driven
  by the error to the *realisable reference*, the reference that would have produced the limited output (Hanus
  et al., "Conditioning technique, a general anti-windup and bumpless transfer method", Automatica 23(6),
  1987; the 2DOF PI of Harnefors et al., *Control of Variable-Speed Drives*, and motulator's ``PIController``,
  which updates ``u_i += Ts (k_i/k_t)(u - v)``). The integral does not jump with the proportional and
  feed-forward terms, so a limited speed loop holds its limit until the speed nears the reference.

The limiter is exact (non-smoothed): its gradient is zero beyond the limit, which tuning objectives
penalise separately.
"""

import jax.numpy as jnp

from pmsmjax._types import Array


def pi_update(
    kp, ki, integral, error, Ts, limited_output, feedforward=0.0, tracking=1.0
) -> tuple[Array, Array]:
    """One PI update.

    **Arguments:**

    - `kp`, `ki`: proportional gain and integral gain (per second), broadcast with `error`.
    - `integral`: integral state (output units), same shape as `error`.
    - `error`: reference minus measurement.
    - `Ts`: controller period, s.
    - `limited_output`: function ``v -> u`` applying the output limit (scalar clip, circular limit, ...).
    - `feedforward`: added to the output before limiting (not integrated).
    - `tracking`: anti-windup tracking gain per period ``g = Ts/T_t`` in (0, 1]; 1 resets the integral to
      the limit each period.

    **Returns:** ``(integral_next, u)``.
    """
    v = kp * error + integral + feedforward
    u = limited_output(v)
    return integral + Ts * ki * error + tracking * (u - v), u


def realisable_reference_tracking(kp, ki, Ts) -> Array:
    """Tracking gain ``g = Ts ki/kp`` (``T_t = kp/ki``) of the realisable-reference anti-windup.

    Clipped to ``(0, 1]``: ``g > 1`` would over-correct the integral (1 is the per-period reset). A
    non-positive ``kp`` (reachable while tuning) falls back to 1; the division is guarded with the
    double-where pattern so its gradient stays finite there.
    """
    positive = kp > 0
    g = Ts * ki / jnp.where(positive, kp, 1.0)
    return jnp.where(positive, jnp.clip(g, 0.0, 1.0), 1.0)


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
