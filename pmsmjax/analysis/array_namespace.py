"""The array library of a figure of merit's inputs."""

import jax
import jax.numpy as jnp
import numpy as np


def namespace(*args):
    """``jax.numpy`` if any argument is a JAX array (or tracer), else ``numpy``: a figure of a recorded run
    is plain NumPy post-processing, with no program to compile, while the same function stays traceable
    and differentiable inside tuning objectives and scans."""
    return jnp if any(isinstance(a, jax.Array) for a in args) else np
