"""Test configuration: float64 everywhere (accuracy is compared against scipy references)."""

import jax

jax.config.update("jax_enable_x64", True)
