"""Derivatives of a scalar closed-loop objective with respect to a chosen set of array leaves.

Forward mode (``jax.jvp``, one pass per parameter) costs about one extra forward simulation per
parameter and stores nothing; reverse mode (``jax.grad``) costs a few forward simulations whatever the
number of parameters, recomputing each period from the per-period checkpoints. ``mode="auto"`` picks
forward mode up to [`FORWARD_MODE_MAX_PARAMS`][pmsmjax.analysis.gradients.FORWARD_MODE_MAX_PARAMS] parameters,
the crossover measured by ``pmsmjax bench`` ([`pmsmjax.jobs.bench`][pmsmjax.jobs.bench]) on the book drive.
"""

from collections.abc import Callable
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

#: Up to this many scalar parameters forward mode is used by ``mode="auto"`` (see module docstring).
FORWARD_MODE_MAX_PARAMS = 4

GradientMode = Literal["auto", "forward", "reverse"]


def value_and_grad(
    fn: Callable, params, *args, mode: GradientMode = "auto", **kwargs
) -> tuple[jax.Array, object]:
    """``fn(params, *args, **kwargs)`` and its gradient with respect to the array leaves of ``params``.

    Args:
        fn: Returns a scalar.
        params: A pytree (e.g. a Drive, or a dict of arrays); non-array leaves are held fixed.
        *args: Further positional arguments of ``fn``.
        mode: ``"forward"``, ``"reverse"`` or ``"auto"`` (by the number of scalar parameters).
        **kwargs: Further keyword arguments of ``fn``.

    Returns:
        ``(value, grads)`` with ``grads`` shaped like ``params`` (None at non-array leaves).
    """
    dynamic, static = eqx.partition(params, eqx.is_inexact_array)
    f = lambda p: fn(eqx.combine(p, static), *args, **kwargs)
    n_params = sum(x.size for x in jax.tree.leaves(dynamic))
    if mode == "auto":
        mode = "forward" if n_params <= FORWARD_MODE_MAX_PARAMS else "reverse"
    if mode == "reverse":
        return jax.value_and_grad(f)(dynamic)
    if mode != "forward":
        raise ValueError(f"mode must be 'auto', 'forward' or 'reverse', got {mode!r}.")
    flat, unravel = ravel_pytree(dynamic)
    g = lambda x: f(unravel(x))
    value = g(flat)
    basis = jnp.eye(flat.size, dtype=flat.dtype)
    tangents = jax.vmap(lambda v: jax.jvp(g, (flat,), (v,))[1])(basis)
    return value, unravel(tangents)
