"""Switching functions of the sliding-mode observers (the book, ch. 5): ``z = k F(i_hat - i)``.

- ``"sign"``: ``F(x) = sign(x)``, the book's ideal sliding mode. Sampled at 10 kHz it chatters: each
  period the observer current jumps by ``k Ts / L`` (13 A for the design-rule ``k`` on the book motor),
  and the low-pass filter must remove a square wave of amplitude ``k`` from the back-EMF estimate.
- ``"saturation"``: ``F(x) = clip(x / width, -1, 1)``, the boundary-layer function (Slotine & Li,
  *Applied Nonlinear Control*, 1991, sec. 7.3); linear with slope ``1/width`` inside ``|x| < width``.
- ``"sigmoid"`` (default): ``F(x) = tanh(x / width)`` (the sigmoid ``2/(1 + exp(-a x)) - 1`` with
  ``a = 2/width``, as in Chi, Zhang, Xu, IEEE TIA 45(2), 2009, doi:10.1109/TIA.2009.2013545): smooth, so
  gradients exist everywhere.

Inside the linear zone the smoothed observers are linear with gain ``G = k / width`` (V/A): the
quantity their design rules and stability checks use
([`linear_gain`][pmsmjax.estimators.switching.linear_gain]). ``sign`` has no linear zone; it is the exact
element, and ``sigmoid`` is both the default and its smooth surrogate.
"""

from typing import Literal

import jax.numpy as jnp

Switching = Literal["sign", "saturation", "sigmoid"]
SWITCHING = ("sign", "saturation", "sigmoid")


def switching_function(x, width, kind: Switching):
    """``F(x)`` elementwise; ``x`` and ``width`` in A (``width`` unused by ``"sign"``)."""
    if kind == "sign":
        return jnp.sign(x)
    if kind == "saturation":
        return jnp.clip(x / width, -1.0, 1.0)
    return jnp.tanh(x / width)


def linear_gain(k, width, kind: Switching):
    """Slope of ``k F`` at zero, V/A; ``None`` for ``"sign"`` (no linear zone)."""
    return None if kind == "sign" else k / width
