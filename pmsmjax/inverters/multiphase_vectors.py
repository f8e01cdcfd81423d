"""The ``2^n`` switching states of an n-leg inverter feeding a multi-phase machine with isolated star points,
projected on the VSD planes, for any :class:`~pmsmjax.frames.multiphase.PhaseLayout` (BOOK.md chapters 8
and 10).

State index ``s = sum_x b_x 2^x`` (``b_x`` the upper switch of leg ``x``, leg order of the layout). Each
state's phase voltages are ``U_dc (b_x - mean of its star)``; their amplitude-invariant VSD gives one
vector per plane. :func:`space_vectors` returns them with the two groups of states that near-four-vector
SVPWM uses (:mod:`.multiphase_svpwm`):

- **large** (L): the states of largest alpha-beta magnitude, one per direction, sorted by angle from
  the first at or after 0 rad; the sectors lie between neighbours (sector ``k`` from L_k to L_k+1);
- **second** (the next group collinear with L): at each L direction, the state of the next-largest
  alpha-beta magnitude. Its vector in the second plane is opposite to the L state's, so a mix of the two
  nulls that plane's average.

Five phases (:data:`~pmsmjax.frames.multiphase.FIVE_PHASE`), per unit of ``U_dc``:

==========  =====  ========================================  ===========  ==================
alpha-beta  count  name                                      x-y          direction
==========  =====  ========================================  ===========  ==================
0           2      zero (00000, 11111)                       0
0.2472      10     small                                     0.6472
0.4000      10     medium (M), collinear with L              0.4000       x-y opposite to L's
0.6472      10     large (L), at 36 k deg                    0.2472
==========  =====  ========================================  ===========  ==================

``|L| = (4/5) cos 36 deg``, ``|M| = 2/5``, ``|small| = (4/5) cos 72 deg``: the golden ratio links them
(``|L|/|M| = |M|/|small| = 1.618``). Six phases: the same construction returns the L and ML vectors of
:mod:`.six_phase_vectors` (tests/test_five_phase_pwm.py checks it).

All tables are NumPy float64 built once per layout (they must not depend on the JAX precision mode).
"""

import functools
import itertools
from typing import NamedTuple

import numpy as np

from pmsmjax.checks.validation import ParameterError
from pmsmjax.frames.multiphase import PhaseLayout, vsd_matrix

__all__ = ["SpaceVectors", "space_vectors"]


class SpaceVectors(NamedTuple):
    """Switching states of a layout (read-only NumPy float64).

    `states` ``(2^n, n)`` leg states; `vectors` ``(2^n, 2 n_planes)`` their VSD voltages per unit of
    ``U_dc``; `large`, `second` ``(K,)`` indices of the L states and of the next group at the same
    directions (``K`` sectors); `bisectors` ``(K, 2)`` unit vectors halfway between L_k and L_k+1;
    `large_magnitude` ``|L|`` per unit.
    """

    states: np.ndarray
    vectors: np.ndarray
    large: np.ndarray
    second: np.ndarray
    bisectors: np.ndarray
    large_magnitude: float


@functools.lru_cache(maxsize=8)
def space_vectors(layout: PhaseLayout) -> SpaceVectors:
    """The switching-state tables of ``layout`` (module docstring)."""
    layout.check()
    n = layout.n
    if n > 12:
        raise ParameterError(f"space_vectors enumerates 2^n states; n = {n} is too many.")
    states = np.array(list(itertools.product((0, 1), repeat=n)), dtype=float)[:, ::-1]  # leg 0 = bit 0
    phase = states.copy()
    for group in layout.neutrals:
        idx = list(group)
        phase[:, idx] -= phase[:, idx].mean(axis=1, keepdims=True)
    vectors = phase @ vsd_matrix(layout)[: layout.n_active].T
    mag = np.hypot(vectors[:, 0], vectors[:, 1])
    ang = np.mod(np.arctan2(vectors[:, 1], vectors[:, 0]), 2 * np.pi)
    tol = 1e-9
    large_mag = mag.max()
    large = np.nonzero(np.abs(mag - large_mag) < tol)[0]
    # Angles within tol of 2 pi are the direction 0.
    key = np.where(ang[large] > 2 * np.pi - tol, 0.0, ang[large])
    large = large[np.argsort(key)]
    second = []
    for i in large:
        same = (np.abs(np.angle(np.exp(1j * (ang - ang[i])))) < tol) & (mag < large_mag - tol) & (mag > tol)
        if not np.any(same):
            raise ParameterError(f"layout {layout.name!r}: no state is collinear with the large vector {i}.")
        m2 = mag[same].max()
        (j,) = np.nonzero(same & (np.abs(mag - m2) < tol))
        if len(j) != 1:
            raise ParameterError(
                f"layout {layout.name!r}: {len(j)} states share the second magnitude at one L direction; "
                "near-four-vector tables need exactly one."
            )
        second.append(int(j[0]))
    unit = vectors[large, :2] / large_mag
    mid = unit + np.roll(unit, -1, axis=0)
    bisectors = mid / np.linalg.norm(mid, axis=1, keepdims=True)
    out = SpaceVectors(states, vectors, large, np.array(second), bisectors, float(large_mag))
    for a in out[:5]:
        a.setflags(write=False)
    return out
