"""Space-vector PWM in the book's form (the book, ch. 2).

Sector from the signs of ``U1 = u_b``, ``U2 = (sqrt3 u_a - u_b)/2``, ``U3 = (-sqrt3 u_a - u_b)/2``:
``N = [U1>0] + 2[U2>0] + 4[U3>0]`` (N = 3, 1, 5, 4, 6, 2 are sectors I..VI). Dwell times of the two
adjacent active vectors from X, Y, Z; over-modulation scales them to fit the period (keeping the
direction); switching times ``Ta, Tb, Tc`` of the 7-segment sequence 0-x-y-7-y-x-0 are compared with a
centre-aligned carrier, so the upper-switch duty of each leg is ``1 - 2 Tcm/Ts``.

The output is continuous in the reference (the sector switch changes which formula is used, not the
value), so gradients through it are exact away from over-modulation.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.inverters.base import AbstractModulator

SQRT3 = 3.0**0.5

# Rows indexed by N = 0..7. N = 0 occurs only for a zero reference (then X = Y = Z = 0 and any row
# gives zero dwell times); N = 7 cannot occur (U1 + U2 + U3 = 0). Entries index into (X, Y, Z, -X, -Y, -Z).
_X, _Y, _Z, _mX, _mY, _mZ = range(6)
# NumPy int32 tables: built at import, they must not depend on the JAX precision mode of that moment.
_DWELL_TABLE = np.array(
    [[_X, _Y], [_Z, _Y], [_Y, _mX], [_mZ, _X], [_mX, _Z], [_X, _mY], [_mY, _mZ], [_X, _Y]], dtype=np.int32
)
# Which of (Ta, Tb, Tc) each leg's comparison value takes, by N.
_LEG_TABLE = np.array(
    [[0, 1, 2], [1, 0, 2], [0, 2, 1], [0, 1, 2], [2, 1, 0], [2, 0, 1], [1, 2, 0], [0, 1, 2]]
)
# The same tables as one-hot selection matrices: selecting by a product instead of a gather keeps the
# reverse-mode derivative a product too (the VJP of a gather is a scatter, slow inside a loop on CPU).
_DWELL_ONE_HOT = np.eye(6)[_DWELL_TABLE]  # (8, 2, 6)
_LEG_ONE_HOT = np.eye(3)[_LEG_TABLE]  # (8, 3, 3)


def sector_code(u_ab: Array) -> Array:
    """The book's sector code N of an alpha-beta vector.

    Args:
        u_ab: ``(2,)`` vector.

    Returns:
        N (int, 1..6; 0 for a zero reference).
    """
    u_a, u_b = u_ab[0], u_ab[1]
    U1 = u_b
    U2 = 0.5 * (SQRT3 * u_a - u_b)
    U3 = 0.5 * (-SQRT3 * u_a - u_b)
    return (U1 > 0).astype(jnp.int32) + 2 * (U2 > 0) + 4 * (U3 > 0)


def switching_times(u_ab: Array, u_dc: Array, Ts) -> tuple[Array, Array, Array]:
    """Book SVPWM for one period.

    Args:
        u_ab: ``(2,)`` reference, V.
        u_dc: DC-link voltage, V.
        Ts: PWM period, s.

    Returns:
        ``(T_cm, T1, T2)``: ``(3,)`` comparison times of legs a, b, c (s, a leg is high while the
        centre-aligned carrier is above its T_cm) and the dwell times of the two active vectors (s), after
        over-modulation scaling.
    """
    u_a, u_b = u_ab[0], u_ab[1]
    k = SQRT3 * Ts / u_dc
    X = k * u_b
    Y = k * (0.5 * SQRT3 * u_a + 0.5 * u_b)
    Z = k * (-0.5 * SQRT3 * u_a + 0.5 * u_b)
    candidates = jnp.stack([X, Y, Z, -X, -Y, -Z])
    N = sector_code(u_ab)
    dtype = candidates.dtype
    T1, T2 = jnp.asarray(_DWELL_ONE_HOT, dtype)[N] @ candidates
    total = T1 + T2
    over = total > Ts
    # Double-where: the ratio is only evaluated where it is used, so its gradient stays finite at zero.
    scale = jnp.where(over, Ts / jnp.where(over, total, 1.0), 1.0)
    T1, T2 = T1 * scale, T2 * scale
    Ta = 0.25 * (Ts - T1 - T2)
    Tb = Ta + 0.5 * T1
    Tc = Tb + 0.5 * T2
    T_cm = jnp.asarray(_LEG_ONE_HOT, dtype)[N] @ jnp.stack([Ta, Tb, Tc])
    return T_cm, T1, T2


class SVPWM(AbstractModulator):
    """The book's space-vector PWM; linear up to ``U_dc/sqrt(3)`` (the hexagon's inscribed circle).

    Beyond the hexagon the dwell times are scaled to the period, which keeps the voltage direction and
    clips the magnitude to the hexagon boundary.

    Args:
        name: The modulator's name in tables and figures (static).
    """

    name: str = eqx.field(static=True, default="svpwm")

    def duties(self, u_ab_ref, u_dc):
        T_cm, _, _ = switching_times(u_ab_ref, u_dc, 1.0)
        return 1.0 - 2.0 * T_cm

    def linear_limit(self, u_dc):
        return u_dc / SQRT3
