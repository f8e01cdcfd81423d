"""Checks of user input made before anything is compiled.

Every failure raises [`ParameterError`][pmsmjax.spec.validation.ParameterError] (a ``ValueError``) naming
the offending field and the fix. Checks are skipped for traced values (inside ``jit``/``vmap``/``grad``): they
are meant for the concrete values a user passes in, and tracing code must stay free of Python branching on
array values.

This module does not import JAX (a value can only be a tracer once JAX is loaded), so the command line
can raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] for bad flags before JAX starts.
"""

import sys

import numpy as np


class ParameterError(ValueError):
    """A parameter or input is non-physical, inconsistent or malformed."""


def is_concrete(x) -> bool:
    """True when ``x`` holds concrete values (not a JAX tracer)."""
    jax = sys.modules.get("jax")
    return jax is None or not isinstance(x, jax.core.Tracer)


def _values(x):
    jax = sys.modules.get("jax")
    return np.asarray(x if jax is None else jax.device_get(x), dtype=float)


def plain(x) -> str:
    """A number (or a short array) as a user reads it: ``0.01``, ``[0, nan]``; never a NumPy repr such as
    ``np.float64(0.01)``."""
    v = np.asarray(x, dtype=float) if not isinstance(x, str) else None
    if v is None:
        return x
    if v.ndim == 0:
        return f"{float(v):g}"
    flat = [f"{float(e):g}" for e in v.reshape(-1)[:6]]
    return "[" + ", ".join(flat) + (", ...]" if v.size > 6 else "]")


def check_finite(name: str, x, unit: str = "") -> None:
    """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming `name` unless every element
    of ``x`` is finite (no NaN or inf).

    `unit` is shown after the values in the message; a traced ``x`` (inside ``jit``) is not checked.
    """
    if not is_concrete(x):
        return
    v = _values(x)
    if not np.all(np.isfinite(v)):
        raise ParameterError(
            f"{name} must be finite, got {plain(v)}{' ' + unit if unit else ''}: replace NaN/inf."
        )


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


def alternatives(choices) -> str:
    """``choices`` as a sentence names them: ``'a' or 'b'``, ``'a', 'b' or 'c'``."""
    quoted = [repr(c) for c in choices]
    return quoted[0] if len(quoted) == 1 else f"{', '.join(quoted[:-1])} or {quoted[-1]}"


def check_choice(name: str, value, choices, hint: str = "") -> None:
    """Raise unless ``value`` is one of ``choices`` (a static option such as a mode or a switching function).

    The message names `name`, the choices and what was given; `hint` (a sentence) follows it."""
    if value not in tuple(choices):
        raise ParameterError(
            f"{name} must be {alternatives(choices)}, got {value!r}{': ' + hint if hint else ''}."
        )


def check_divider(name: str, value, what: str) -> None:
    """Raise unless ``value`` is an ``int`` >= 1: how many `what` (e.g. "control periods") make one
    period of a slower loop."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ParameterError(
            f"{name} must be an int >= 1, got {value!r}: give how many {what} make one speed-loop period."
        )
