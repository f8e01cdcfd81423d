"""Checks of user input made before anything is compiled.

Every failure raises :class:`ParameterError` (a ``ValueError``) naming the offending field and the fix.
Checks are skipped for traced values (inside ``jit``/``vmap``/``grad``): they are meant for the concrete
values a user passes in, and tracing code must stay free of Python branching on array values.
"""

import jax
import numpy as np


class ParameterError(ValueError):
    """A parameter or input is non-physical, inconsistent or malformed."""


def is_concrete(x) -> bool:
    """True when ``x`` holds concrete values (not a JAX tracer)."""
    return not isinstance(x, jax.core.Tracer)


def _values(x):
    return np.asarray(jax.device_get(x), dtype=float)


def check_finite(name: str, x, unit: str = "") -> None:
    if not is_concrete(x):
        return
    v = _values(x)
    if not np.all(np.isfinite(v)):
        raise ParameterError(f"{name} must be finite, got {v}{' ' + unit if unit else ''}: replace NaN/inf.")


def check_positive(name: str, x, unit: str = "", hint: str = "") -> None:
    """Raise unless every element of ``x`` is finite and > 0."""
    if not is_concrete(x):
        return
    check_finite(name, x, unit)
    v = _values(x)
    if np.any(v <= 0):
        fix = hint or f"give a strictly positive value in {unit or 'SI units'}"
        raise ParameterError(f"{name} must be > 0, got {v.min():g}{' ' + unit if unit else ''}: {fix}.")


def check_nonnegative(name: str, x, unit: str = "", hint: str = "") -> None:
    """Raise unless every element of ``x`` is finite and >= 0."""
    if not is_concrete(x):
        return
    check_finite(name, x, unit)
    v = _values(x)
    if np.any(v < 0):
        fix = hint or f"give a value >= 0 in {unit or 'SI units'}"
        raise ParameterError(f"{name} must be >= 0, got {v.min():g}{' ' + unit if unit else ''}: {fix}.")
