"""Refusing unstable observer gains before anything runs (the ODrive pattern: its sensorless estimator
refuses ``Ts kp >= 1``, ``Firmware/MotorControl/sensorless_estimator.cpp``).

Every observer's ``check_period(Ts)`` writes the small-signal model of its loop *as sampled* (one
period of the implementation, linearised about a rotor tracked at constant speed) as a matrix and hands
it to [`check_loop`][pmsmjax.estimators.stability.check_loop], which raises
[`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the gains and the fix when an eigenvalue
lies on or outside the unit circle. Batched (vmapped) gains are checked element by element; traced gains are
skipped (checks are for the values a user passes in). tests/estimators/test_observers.py runs each observer
just inside and just outside the boundary found here.
"""

from collections.abc import Callable

import jax
import numpy as np

from pmsmjax.spec.validation import ParameterError, is_concrete


def concrete_values(*xs) -> list[np.ndarray] | None:
    """The arguments as float64 NumPy arrays broadcast together, or ``None`` if any is traced."""
    if not all(is_concrete(x) for x in xs):
        return None
    return list(np.broadcast_arrays(*[np.asarray(jax.device_get(x), dtype=float) for x in xs]))


def spectral_radius(matrix: Callable[..., np.ndarray], *values: np.ndarray) -> float:
    """Largest eigenvalue magnitude of ``matrix(*scalars)`` over every element of the broadcast ``values``."""
    worst = -1.0
    for idx in np.ndindex(values[0].shape):
        m = np.asarray(matrix(*(float(v[idx]) for v in values)), dtype=float)
        rho = float(np.max(np.abs(np.linalg.eigvals(m)))) if np.all(np.isfinite(m)) else np.inf
        worst = max(worst, rho)
    return worst


def check_loop(
    what: str, matrix: Callable[..., np.ndarray], values: list[np.ndarray] | None, fix: str
) -> None:
    """Raise if the sampled loop ``what`` (one period: ``x_k = matrix x_{k-1}``) is unstable for any element
    of ``values``; `fix` says what to change."""
    if values is None:
        return
    rho = spectral_radius(matrix, *values)
    if not rho < 1.0:
        raise ParameterError(
            f"{what} is unstable at this sample time (an eigenvalue of the sampled loop at |z| = {rho:.4g} "
            f">= 1): {fix}."
        )


def tracking_loop_matrix(a: float, b: float, c: float = 0.0) -> np.ndarray:
    """One period of a sampled type-2 tracking loop (PLL) about lock, state ``[angle error, Ts x speed
    error]``: ``th- = th + Ts w``, ``e = (measured - th-)``, ``th = th- + a e``, ``w += (b/Ts) e``.
    ``a = Ts kp``, ``b = Ts^2 ki``; ``c``: the measured angle moves by ``c Ts w`` with last period's speed
    estimate (a lag compensation inside the loop, ``c = d(lag)/d(omega) / Ts``; the observers here keep it
    outside, ``c = 0``). Characteristic polynomial ``z^2 - (2 - a - b + b c) z + (1 - a + b c)``; for
    ``c = 0``: stable iff ``0 < a < 2``, ``0 < b < 4 - 2 a``."""
    return np.array([[1.0 - a, 1.0 - a + a * c], [-b, 1.0 - b + b * c]])
