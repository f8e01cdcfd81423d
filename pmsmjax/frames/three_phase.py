"""Reference-frame transforms for three-phase quantities.

Conventions (docs/book_reference.md, whole project):

- Clarke, amplitude-invariant (default, factor 2/3)::

      alpha = 2/3 (a - b/2 - c/2),  beta = (b - c)/sqrt(3),  zero = (a + b + c)/3

  Power-invariant scaling (``power_invariant=True``) multiplies alpha/beta by sqrt(3/2) and the zero
  sequence by sqrt(3); the inverse undoes exactly what the forward transform did, so
  ``inverse(forward(x)) == x`` holds for every vector, zero sequence included.
- Park rotates alpha-beta into the rotor frame whose d axis is at electrical angle ``theta_e`` from the
  A (alpha) axis; the magnet flux lies on d::

      d =  alpha cos(th) + beta sin(th),   q = -alpha sin(th) + beta cos(th)

All functions act on the last axis, so they broadcast over leading batch/time axes.
"""

import jax.numpy as jnp

from pmsmjax._types import Array, ArrayLike

SQRT3 = 3.0**0.5

__all__ = [
    "abc_to_alpha_beta",
    "abc_to_alpha_beta_zero",
    "wrap_angle",
    "alpha_beta_to_abc",
    "abc_to_dq",
    "dq_to_abc",
    "park",
    "inverse_park",
    "rotation",
]


def abc_to_alpha_beta(x_abc: ArrayLike, power_invariant: bool = False) -> Array:
    """Clarke transform. ``x_abc: (..., 3)`` -> ``(..., 2)`` alpha-beta (zero sequence dropped).

    Use [`abc_to_alpha_beta_zero`][pmsmjax.frames.three_phase.abc_to_alpha_beta_zero] when the zero sequence
    is wanted.
    """
    return abc_to_alpha_beta_zero(x_abc, power_invariant)[..., :2]


def abc_to_alpha_beta_zero(x_abc: ArrayLike, power_invariant: bool = False) -> Array:
    """Clarke transform with zero sequence. ``x_abc: (..., 3)`` -> ``(..., 3)`` [alpha, beta, zero]."""
    x = jnp.asarray(x_abc)
    a, b, c = x[..., 0], x[..., 1], x[..., 2]
    alpha = (2.0 * a - b - c) / 3.0
    beta = (b - c) / SQRT3
    zero = (a + b + c) / 3.0
    if power_invariant:
        alpha, beta, zero = alpha * (1.5**0.5), beta * (1.5**0.5), zero * SQRT3
    return jnp.stack([alpha, beta, zero], axis=-1)


def alpha_beta_to_abc(x_ab: ArrayLike, power_invariant: bool = False) -> Array:
    """Inverse Clarke. ``x_ab: (..., 2)`` or ``(..., 3)`` with zero sequence -> ``(..., 3)`` abc."""
    x = jnp.asarray(x_ab)
    alpha, beta = x[..., 0], x[..., 1]
    zero = x[..., 2] if x.shape[-1] == 3 else jnp.zeros_like(alpha)
    if power_invariant:
        alpha, beta, zero = alpha / (1.5**0.5), beta / (1.5**0.5), zero / SQRT3
    a = alpha + zero
    b = -0.5 * alpha + 0.5 * SQRT3 * beta + zero
    c = -0.5 * alpha - 0.5 * SQRT3 * beta + zero
    return jnp.stack([a, b, c], axis=-1)


def rotation(theta: ArrayLike) -> Array:
    """2x2 matrix rotating a vector by +theta (rad): ``(...,) -> (..., 2, 2)``."""
    c, s = jnp.cos(theta), jnp.sin(theta)
    return jnp.stack([jnp.stack([c, -s], -1), jnp.stack([s, c], -1)], -2)


def park(x_ab: ArrayLike, theta_e: ArrayLike) -> Array:
    """Stationary -> rotor frame. ``x_ab: (..., 2)``, ``theta_e: (...)`` rad -> ``(..., 2)`` dq."""
    x = jnp.asarray(x_ab)
    c, s = jnp.cos(theta_e), jnp.sin(theta_e)
    return jnp.stack([x[..., 0] * c + x[..., 1] * s, -x[..., 0] * s + x[..., 1] * c], axis=-1)


def inverse_park(x_dq: ArrayLike, theta_e: ArrayLike) -> Array:
    """Rotor -> stationary frame. ``x_dq: (..., 2)``, ``theta_e: (...)`` rad -> ``(..., 2)`` alpha-beta."""
    x = jnp.asarray(x_dq)
    c, s = jnp.cos(theta_e), jnp.sin(theta_e)
    return jnp.stack([x[..., 0] * c - x[..., 1] * s, x[..., 0] * s + x[..., 1] * c], axis=-1)


def abc_to_dq(x_abc: ArrayLike, theta_e: ArrayLike, power_invariant: bool = False) -> Array:
    """abc -> dq (Clarke then Park). ``(..., 3)`` -> ``(..., 2)``."""
    return park(abc_to_alpha_beta(x_abc, power_invariant), theta_e)


def dq_to_abc(x_dq: ArrayLike, theta_e: ArrayLike, power_invariant: bool = False) -> Array:
    """dq -> abc (inverse Park then inverse Clarke, zero sequence 0). ``(..., 2)`` -> ``(..., 3)``."""
    return alpha_beta_to_abc(inverse_park(x_dq, theta_e), power_invariant)


def wrap_angle(theta: ArrayLike) -> ArrayLike:
    """Wrap an angle (rad) to [-pi, pi). Gradient 1 everywhere (the jump is a constant 2 pi).

    Written with operators only, so it keeps its input's kind: JAX in, JAX out (traceable); NumPy in,
    NumPy out in the input's precision (figures of merit score float32 runs in float64,
    [`pmsmjax.analysis.observer_errors`][pmsmjax.analysis.observer_errors]). Both give the same bits for the
    same float64 input.
    """
    return (theta + jnp.pi) % (2.0 * jnp.pi) - jnp.pi
