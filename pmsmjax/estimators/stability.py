"""Refusing unstable observer gains before anything runs (the ODrive pattern: its sensorless estimator
refuses ``Ts kp >= 1``, ``Firmware/MotorControl/sensorless_estimator.cpp``).

Every observer's ``check_period(Ts)`` builds the characteristic polynomial of its linearised loop *in
discrete time* (the sampled loop, not the continuous one its design rule starts from) and hands it to
:func:`check_poles`, which raises :class:`~pmsmjax.validation.ParameterError` naming the gain and the fix
when a pole lies on or outside the unit circle. Batched (vmapped) gains are checked element by element;
traced gains are skipped (checks are for the values a user passes in).
"""

from collections.abc import Callable

import jax
import numpy as np

from ..validation import ParameterError, is_concrete


def concrete_values(*xs) -> list[np.ndarray] | None:
    """The arguments as float64 NumPy arrays broadcast together, or ``None`` if any is traced."""
    if not all(is_concrete(x) for x in xs):
        return None
    return list(np.broadcast_arrays(*[np.asarray(jax.device_get(x), dtype=float) for x in xs]))


def largest_pole(poly: Callable[..., list], *values: np.ndarray) -> tuple[float, tuple]:
    """Largest pole magnitude of ``poly(*scalars)`` (coefficients, highest power first) over every element
    of the broadcast ``values``; returns ``(magnitude, the scalars where it occurs)``."""
    worst, where = -1.0, ()
    for idx in np.ndindex(values[0].shape):
        scalars = tuple(float(v[idx]) for v in values)
        mag = float(np.max(np.abs(np.roots(poly(*scalars)))))
        if not np.isfinite(mag):
            mag = np.inf
        if mag > worst:
            worst, where = mag, scalars
    return worst, where


def check_poles(what: str, poly: Callable[..., list], values: list[np.ndarray] | None, fix: str) -> None:
    """Raise if the sampled loop ``what`` has a pole with ``|z| >= 1`` for any element of ``values``.

    `poly` maps the scalars of one element to the characteristic polynomial's coefficients; `fix` says
    what to change (it is completed with the pole found).
    """
    if values is None:
        return
    mag, _ = largest_pole(poly, *values)
    if not mag < 1.0:
        raise ParameterError(
            f"{what} is unstable at this sample time (a pole at |z| = {mag:.4g} >= 1): {fix}."
        )


def tracking_loop_poly(a: float, b: float) -> list:
    """Characteristic polynomial of the sampled type-2 tracking loop (PLL) ``th- = th + Ts w``,
    ``th = th- + a e``, ``w += (b / Ts) e`` with ``e = th_true - th-``: ``z^2 - (2 - a - b) z + (1 - a)``.
    ``a = Ts kp``, ``b = Ts^2 ki``; stable iff ``0 < a < 2`` and ``0 < b < 4 - 2a``."""
    return [1.0, -(2.0 - a - b), 1.0 - a]
